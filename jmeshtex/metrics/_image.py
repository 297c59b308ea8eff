"""Pixel-level image metrics on the host (NumPy): PSNR and DSSIM, optionally restricted to a mask
(e.g. the used texels of a texture atlas)."""

from __future__ import annotations

import numpy as np
from skimage.metrics import structural_similarity

from .._errors import InputError


def _check_pair(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None, name: str):
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    if a.shape != b.shape or a.ndim not in (2, 3):
        raise InputError(
            f"{name}: images must be [H, W] or [H, W, C] of equal shape, got {a.shape} and {b.shape}"
        )
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise InputError(f"{name}: images contain NaN or inf")
    if mask is None:
        mask = np.ones(a.shape[:2], bool)
    mask = np.asarray(mask, bool)
    if mask.shape != a.shape[:2]:
        raise InputError(f"{name}: mask must be [H, W] = {a.shape[:2]}, got {mask.shape}")
    if not mask.any():
        raise InputError(f"{name}: the mask selects no pixel")
    return a, b, mask


def psnr(
    a: np.ndarray, b: np.ndarray, *, mask: np.ndarray | None = None, data_range: float = 1.0
) -> float:
    """Peak signal-to-noise ratio in dB over the masked pixels.

    .. math:: \\mathrm{PSNR} = 10 \\log_{10} \\frac{R^2}{\\operatorname{mean}_{m}(a - b)^2}

    Identical images give ``inf``.

    Args:
      a, b: ``[H, W]`` or ``[H, W, C]`` images with values in ``[0, data_range]``.
      mask: ``[H, W]`` pixels to compare (default all).
      data_range: ``R``, the value range (1 for float images).

    Example:
      >>> round(psnr(np.zeros((4, 4)), np.full((4, 4), 0.1)), 6)
      20.0
    """
    a, b, mask = _check_pair(a, b, mask, "psnr")
    mse = float(np.mean((a[mask] - b[mask]) ** 2))
    return float("inf") if mse == 0 else float(10 * np.log10(data_range**2 / mse))


def dssim(
    a: np.ndarray, b: np.ndarray, *, mask: np.ndarray | None = None, data_range: float = 1.0
) -> float:
    """Structural dissimilarity ``(1 − SSIM) / 2`` averaged over the masked pixels.

    SSIM with the standard Gaussian window (σ = 1.5, Wang et al. 2004), channels averaged; the SSIM
    map is computed on the whole image and averaged where ``mask`` is true, leaving out the 5-pixel
    border whose windows leave the image (as scikit-image does, so without a mask the result is
    exactly ``(1 − structural_similarity) / 2``).

    Args:
      a, b: ``[H, W]`` or ``[H, W, C]`` images, at least 11×11.
      mask: ``[H, W]`` pixels to average over (default all).

    Example:
      >>> x = np.random.default_rng(0).random((16, 16, 3))
      >>> dssim(x, x)
      0.0
    """
    a, b, mask = _check_pair(a, b, mask, "dssim")
    if min(a.shape[:2]) < 11:
        raise InputError(f"dssim: images must be at least 11×11, got {a.shape[:2]}")
    _, ssim_map = structural_similarity(
        a,
        b,
        data_range=data_range,
        channel_axis=-1 if a.ndim == 3 else None,
        gaussian_weights=True,
        sigma=1.5,
        use_sample_covariance=False,
        full=True,
    )
    if ssim_map.ndim == 3:
        ssim_map = ssim_map.mean(-1)
    border = 5  # (win_size - 1) // 2 for the 11-tap Gaussian window at sigma = 1.5
    interior = np.zeros_like(mask)
    interior[border:-border, border:-border] = True
    if not (mask & interior).any():
        raise InputError(
            f"dssim: the mask selects no pixel at least {border} pixels inside the image"
        )
    mask = mask & interior
    return float(max(0.0, (1.0 - ssim_map[mask].mean()) / 2.0))

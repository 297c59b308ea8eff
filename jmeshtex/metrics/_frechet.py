"""The Fréchet distance between two Gaussians fitted to feature samples (host NumPy, float64).

The distance behind FID (Heusel et al. 2017) and SIFID (Shaham et al. 2019, SinGAN): fit a Gaussian
to each set of feature vectors and take the 2-Wasserstein distance between the two in closed form.
"""

from __future__ import annotations

import numpy as np

from .._errors import InputError
from .._types import ArrayLike, Float


def _psd_eigenvalues(lam: np.ndarray) -> np.ndarray:
    """Eigenvalues of a symmetric PSD matrix with rounding noise removed: those below ``C · eps ·
    max |λ|`` (negative ones, and the ≈ 1e-16 ghosts of a singular matrix, whose square roots
    ≈ 1e-8 would otherwise enter the trace) are set to 0."""
    tol = (
        lam.size
        * np.finfo(np.float64).eps
        * max(float(np.abs(lam).max(initial=0.0)), np.finfo(np.float64).tiny)
    )
    return np.where(lam > tol, lam, 0.0)


def _sym_sqrt(cov: np.ndarray) -> np.ndarray:
    """The PSD square root of a symmetric matrix."""
    lam, u = np.linalg.eigh(cov)
    return (u * np.sqrt(_psd_eigenvalues(lam))) @ u.T


def frechet_from_moments(
    mean_a: Float[ArrayLike, " C"],
    cov_a: Float[ArrayLike, "C C"],
    mean_b: Float[ArrayLike, " C"],
    cov_b: Float[ArrayLike, "C C"],
) -> float:
    """Fréchet (2-Wasserstein) distance between the Gaussians ``N(μa, Σa)`` and ``N(μb, Σb)``.

    .. math:: d^2 = \\lVert \\mu_a - \\mu_b \\rVert^2
              + \\operatorname{Tr}\\bigl(\\Sigma_a + \\Sigma_b - 2 (\\Sigma_a \\Sigma_b)^{1/2}\\bigr)

    ``Tr (Σa Σb)^½`` is computed as ``Σ_i √λ_i`` with ``λ`` the eigenvalues of the symmetric PSD
    matrix ``Σa^½ Σb Σa^½`` (similar to ``Σa Σb``), in float64: no complex square roots, no
    ill-conditioned ``sqrtm`` of a non-symmetric product, exact for singular (rank-deficient)
    covariances. Both covariances are symmetrised first; eigenvalues below ``C · eps · max λ``
    (rounding noise, negative or the ghosts of a singular matrix) count as 0, and a negative result
    is clipped to 0 (it is ≥ 0 in exact arithmetic). The square root is not Lipschitz at 0, so
    with singular covariances (fewer samples than channels) identical inputs give ≈ 1e-8 of
    ``Tr Σ`` rather than 0.

    Args:
      mean_a, mean_b: ``[C]`` means.
      cov_a, cov_b: ``[C, C]`` symmetric positive semi-definite covariances.

    Returns:
      ``d²`` (squared distance, as FID reports it), a Python float.

    Raises:
      InputError: mismatched shapes or non-finite values.

    Example:
      >>> frechet_from_moments(np.zeros(2), np.eye(2), np.ones(2), 4 * np.eye(2))  # 2 + 2·(1 + 4 − 2·2)
      4.0
    """
    ma, mb = (np.asarray(m, np.float64) for m in (mean_a, mean_b))
    ca, cb = (np.asarray(c, np.float64) for c in (cov_a, cov_b))
    c = ma.shape[0] if ma.ndim == 1 else -1
    if ma.shape != (c,) or mb.shape != (c,) or ca.shape != (c, c) or cb.shape != (c, c):
        raise InputError(
            f"frechet_from_moments: need means [C] and covariances [C, C] of one C, got "
            f"{ma.shape}, {ca.shape}, {mb.shape}, {cb.shape}"
        )
    if not all(np.isfinite(x).all() for x in (ma, mb, ca, cb)):
        raise InputError("frechet_from_moments: means or covariances contain NaN or inf")
    ca, cb = 0.5 * (ca + ca.T), 0.5 * (cb + cb.T)
    root_a = _sym_sqrt(ca)
    inner = root_a @ cb @ root_a
    lam = np.linalg.eigvalsh(0.5 * (inner + inner.T))
    trace_sqrt = float(np.sqrt(_psd_eigenvalues(lam)).sum())
    d2 = float(np.sum((ma - mb) ** 2)) + float(np.trace(ca) + np.trace(cb)) - 2.0 * trace_sqrt
    return max(d2, 0.0)


def frechet_distance(a: Float[ArrayLike, "N C"], b: Float[ArrayLike, "M C"]) -> float:
    """Fréchet distance between the Gaussians fitted to two sets of feature vectors (FID's formula).

    .. math:: d^2 = \\lVert \\mu_a - \\mu_b \\rVert^2
              + \\operatorname{Tr}\\bigl(\\Sigma_a + \\Sigma_b - 2 (\\Sigma_a \\Sigma_b)^{1/2}\\bigr)

    with ``μ`` the sample means and ``Σ`` the unbiased sample covariances (``np.cov``, as
    pytorch-fid and SinGAN's SIFID code compute them), in float64 on the host; see
    :func:`frechet_from_moments` for the stable square root. ``N`` and ``M`` may differ.

    Args:
      a: ``[N, C]`` samples (rows), ``N ≥ 2``.
      b: ``[M, C]`` samples, ``M ≥ 2``.

    Returns:
      ``d²`` ≥ 0 (0 for identical sample sets, to rounding), a Python float.

    Raises:
      InputError: not two 2-D arrays with the same number of columns, fewer than 2 rows, NaN/inf.

    Example:
      >>> rng = np.random.default_rng(0)
      >>> x = rng.standard_normal((500, 3))
      >>> round(frechet_distance(x, x + np.array([3.0, 0.0, 4.0])), 6)  # a shift: ‖Δμ‖² = 25
      25.0
    """
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if a.ndim != 2 or b.ndim != 2 or a.shape[1] != b.shape[1]:
        raise InputError(
            f"frechet_distance: need [N, C] and [M, C] samples, got {a.shape} and {b.shape}"
        )
    if len(a) < 2 or len(b) < 2:
        raise InputError(
            f"frechet_distance: need at least 2 samples per set, got {len(a)} and {len(b)}"
        )
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise InputError("frechet_distance: samples contain NaN or inf")
    cov = [np.atleast_2d(np.cov(x, rowvar=False)) for x in (a, b)]
    return frechet_from_moments(a.mean(0), cov[0], b.mean(0), cov[1])

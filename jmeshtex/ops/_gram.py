"""Gram matrices of features, the texture statistic of neural texture synthesis (Gatys et al. 2015;
used on mesh textures by Kovács et al. 2024)."""

from __future__ import annotations

import jax.numpy as jnp

from .._errors import InputError
from .._types import Array, ArrayLike, Bool, Float


def gram_matrix(
    x: Float[ArrayLike, "N C"], mask: Bool[ArrayLike, " N"] | None = None
) -> Float[Array, "C C"]:
    """Channel-by-channel second moments of features over the valid entries.

    .. math:: G_{cd} = \\frac{1}{\\sum_n m_n} \\sum_n m_n\\, x_{nc}\\, x_{nd}

    The mask is folded into the features (``m_n ∈ {0, 1}``, so ``m_n² = m_n``) before one GEMM,
    padded rows replaced by 0 first, so they change nothing even when non-finite. With no valid
    entry the result is 0.

    Args:
      x: ``[N, C]`` features (texels, pixels or vertices).
      mask: ``[N]`` True for real entries (default: all).

    Returns:
      ``[C, C]`` symmetric positive semi-definite matrix, dtype of ``x``.

    Example:
      >>> x = jnp.array([[1.0, 2.0], [3.0, 4.0], [100.0, 100.0]])
      >>> gram_matrix(x, jnp.array([True, True, False])).tolist()
      [[5.0, 7.0], [7.0, 10.0]]
    """
    if x.ndim != 2:
        raise InputError(f"gram_matrix: x must be [N, C], got {tuple(x.shape)}")
    if mask is None:
        mask = jnp.ones(x.shape[:1], bool)
    if mask.shape != x.shape[:1]:
        raise InputError(f"gram_matrix: mask must be [N] = [{x.shape[0]}], got {tuple(mask.shape)}")
    m = jnp.asarray(mask).astype(x.dtype)
    xm = jnp.where(m[:, None] != 0, x, 0) * m[:, None]  # a non-finite padded row stays out
    return (xm.T @ xm) / jnp.maximum(jnp.sum(m), 1)

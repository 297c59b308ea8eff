"""Small numerical helpers shared by the operators: safe norms and masked reductions.

Every helper has finite values *and* finite gradients at exactly-zero inputs (DESIGN.md, "Zero
vectors"), uses no Python loop, and keeps the input's dtype.
"""

from __future__ import annotations

import jax.numpy as jnp

from .._types import Array, Bool, Float, Inexact


def safe_norm(x: Inexact[Array, "..."], *, axis: int = -1, keepdims: bool = False) -> Float[Array, "..."]:
    """Euclidean norm along ``axis`` with a zero (not NaN) gradient at ``x = 0``.

    .. math:: \\|x\\| = \\sqrt{\\textstyle\\sum_i |x_i|^2}, \\qquad \\nabla\\|x\\| := 0 \\text{ at } x = 0

    Uses the double-``where`` trick: the square root never sees 0, so no ``inf · 0`` appears in the
    backward pass.

    Args:
      x: real or complex array.
      axis: the axis to reduce.
      keepdims: keep the reduced axis with size 1.

    Returns:
      The real norm, dtype of ``x`` (real part type for complex input).

    Example:
      >>> import jax, jax.numpy as jnp
      >>> float(safe_norm(jnp.array([3.0, 4.0])))
      5.0
      >>> jax.grad(lambda v: safe_norm(v))(jnp.zeros(3)).tolist()
      [0.0, 0.0, 0.0]
    """
    sq = jnp.sum(jnp.real(x * jnp.conj(x)), axis=axis, keepdims=keepdims)
    positive = sq > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, sq, 1)), 0)


def safe_normalize(x: Float[Array, "... D"], *, axis: int = -1) -> Float[Array, "... D"]:
    """``x / |x|`` along ``axis``, with the zero vector mapped to zero (finite value and gradient).

    Example:
      >>> import jax.numpy as jnp
      >>> safe_normalize(jnp.array([[0.0, 2.0], [0.0, 0.0]])).tolist()
      [[0.0, 1.0], [0.0, 0.0]]
    """
    sq = jnp.sum(jnp.real(x * jnp.conj(x)), axis=axis, keepdims=True)
    positive = sq > 0
    inv = jnp.where(positive, 1 / jnp.sqrt(jnp.where(positive, sq, 1)), 0)
    return x * inv


def masked_mean(
    x: Inexact[Array, "N ..."], mask: Bool[Array, " N"] | Float[Array, " N"], *, axis: int = 0
) -> Inexact[Array, "..."]:
    """Mean of ``x`` over ``axis`` counting only entries where ``mask`` is set (0 if none is).

    .. math:: \\bar x = \\frac{\\sum_i m_i x_i}{\\max(\\sum_i m_i, 1)}

    The mask is folded into a weight (no ``where``), so masked entries never reach the result and
    get zero gradient.

    Args:
      x: values; ``mask`` broadcasts along ``axis``.
      mask: ``[N]`` boolean (or 0/1 weights) along ``axis``.
      axis: the reduced axis.

    Example:
      >>> import jax.numpy as jnp
      >>> masked_mean(jnp.array([[1.0], [3.0], [100.0]]), jnp.array([True, True, False])).tolist()
      [2.0]
    """
    axis = axis % x.ndim
    w = jnp.asarray(mask).astype(x.real.dtype)
    w = w.reshape(w.shape + (1,) * (x.ndim - axis - 1))
    count = jnp.maximum(jnp.sum(w), 1)
    return jnp.sum(x * w, axis=axis) / count

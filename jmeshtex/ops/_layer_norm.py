"""Layer norm for complex tangent features: magnitudes rescaled, never shifted or rotated."""

import jax
import jax.numpy as jnp

from .._errors import InputError
from .._types import Array, ArrayLike, Complex, Float
from ._numerics import abs2, check_complex, check_delta, real_dtype


def complex_layer_norm(
    x: Complex[ArrayLike, "... C"], scale: Float[ArrayLike, " C"], *, delta: float = 1e-6
) -> Complex[Array, "... C"]:
    """Layer norm for tangent features: rescale magnitudes only, never shift or rotate.

    .. math:: y_c = \\frac{\\gamma_c}{\\sqrt{\\frac1C \\sum_{c'} |x_{c'}|^2 + \\delta}}\\, x_c

    The mean over channels of ``|x|²`` is rotation-invariant, so a common rotation of all channels of
    an element commutes with the layer. Nothing is subtracted (centering complex features would mix
    frames); ``δ > 0`` keeps ``x = 0`` finite (``y = 0``).

    Args:
      x: ``[..., C]`` complex (normalised over the last axis, independently per leading index).
      scale: ``[C]`` real gain ``γ``.
      delta: ``δ > 0``.

    Returns:
      ``[..., C]`` complex, same frames and dtype as ``x``.

    Example:
      >>> y = complex_layer_norm(jnp.array([[3 + 4j, 0j]]), jnp.ones(2), delta=1e-12)
      >>> jnp.abs(y).round(4).tolist()  # mean |x|² = 12.5
      [[1.4142, 0.0]]
    """
    check_complex(x, "complex_layer_norm")
    delta = check_delta(delta, "complex_layer_norm")
    if jnp.shape(scale) != (x.shape[-1],):
        raise InputError(
            f"complex_layer_norm: scale must have shape [C] = ({x.shape[-1]},), got {jnp.shape(scale)}"
        )
    rdt = real_dtype(x.dtype)
    factor = jnp.asarray(scale).astype(rdt) * jax.lax.rsqrt(
        jnp.mean(abs2(x), axis=-1, keepdims=True) + jnp.asarray(delta, rdt)
    )
    return jax.lax.complex(x.real * factor, x.imag * factor)

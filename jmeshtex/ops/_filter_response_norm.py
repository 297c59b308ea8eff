"""Filter response normalisation of tangent features over a mesh (CVPR 2024 supplement eq. 20).

A real, rotation-invariant rescale per channel: no bias and no mean subtraction, so each vertex's
features keep their frame.
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp

from .._config import is_finite_number
from .._errors import InputError
from .._types import Array, ArrayLike, Bool, Complex, Float
from ._numerics import abs2, check_complex, check_delta, check_size, real_dtype


class FRNParams(NamedTuple):
    """Parameters of :func:`filter_response_norm`.

    Attributes:
      scale: ``[C]`` real gain ``γ``.
      eps: ``[C]`` real learned stabiliser; ``|ε|`` is added under the square root.
    """

    scale: Float[ArrayLike, " C"]
    eps: Float[ArrayLike, " C"]


def init_frn(features: int, *, dtype=jnp.float32, eps: float = 1e-3) -> FRNParams:
    """:class:`FRNParams` with ``γ = 1`` and ``ε = eps`` (deterministic, no key needed).

    Example:
      >>> init_frn(3).scale.tolist()
      [1.0, 1.0, 1.0]
    """
    check_size(features, "features", "init_frn")
    if not is_finite_number(eps):
        raise InputError(f"init_frn: eps must be a finite number (|eps| is used), got {eps!r}")
    dtype = real_dtype(dtype)
    return FRNParams(scale=jnp.ones((features,), dtype), eps=jnp.full((features,), eps, dtype))


def filter_response_norm(
    x: Complex[ArrayLike, "V C"],
    params: FRNParams,
    *,
    area: Float[ArrayLike, " V"],
    vertex_mask: Bool[ArrayLike, " V"] | None = None,
    delta: float = 1e-6,
) -> Complex[Array, "V C"]:
    """Filter response normalisation of tangent features over a mesh (2024 supplement eq. 20).

    Per channel, the area-weighted mean squared modulus over the valid vertices, then a real rescale:

    .. math:: \\nu_c^2 = \\frac{\\sum_p m_p a_p |x_{pc}|^2}{\\sum_p m_p a_p}, \\qquad
       y_{pc} = \\frac{\\gamma_c}{\\sqrt{\\nu_c^2 + \\delta + |\\epsilon_c|}}\\, x_{pc}

    with ``a_p`` the vertex area and ``m_p`` the vertex mask. There is no bias (a complex bias would
    break gauge equivariance) and no mean subtraction (the mean of tangent vectors in different frames
    means nothing); the factor is real and rotation-invariant, so each vertex's features keep their
    frame. Padded vertices (``m_p = 0``) do not enter the statistics; their outputs are rescaled too
    but are never read by anything that respects the mask.

    Args:
      x: ``[V, C]`` complex tangent features.
      params: :class:`FRNParams` (cast to the real dtype of ``x``).
      area: ``[V]`` vertex areas (``VertexNeighborhood.area``).
      vertex_mask: ``[V]`` True for real vertices (``VertexNeighborhood.vertex_mask``); None = all.
      delta: fixed ``δ > 0`` under the square root.

    Returns:
      ``[V, C]`` complex, same frames and dtype as ``x``.

    Example:
      >>> x = jnp.array([[1 + 0j], [0 + 3j], [100 + 0j]])
      >>> y = filter_response_norm(x, FRNParams(jnp.ones(1), jnp.zeros(1)), area=jnp.ones(3),
      ...                          vertex_mask=jnp.array([True, True, False]), delta=1e-12)
      >>> jnp.abs(y[:2, 0]).round(4).tolist()  # ν² = (1 + 9) / 2 = 5
      [0.4472, 1.3416]
    """
    check_complex(x, "filter_response_norm", ndim_min=2)
    delta = check_delta(delta, "filter_response_norm")
    if x.ndim != 2:
        raise InputError(
            f"filter_response_norm: x must be [V, C] (vmap for batches), got shape {x.shape}"
        )
    v, c = x.shape
    if jnp.shape(area) != (v,):
        raise InputError(
            f"filter_response_norm: area must have shape [V] = ({v},), got {jnp.shape(area)}"
        )
    if params.scale.shape != (c,) or params.eps.shape != (c,):
        raise InputError(
            f"filter_response_norm: scale and eps must have shape [C] = ({c},), got "
            f"{params.scale.shape} and {params.eps.shape}"
        )
    rdt = real_dtype(x.dtype)
    w = jnp.asarray(area).astype(rdt)
    if vertex_mask is not None:
        if jnp.shape(vertex_mask) != (v,):
            raise InputError(
                f"filter_response_norm: vertex_mask must have shape ({v},), got {jnp.shape(vertex_mask)}"
            )
        w = w * jnp.asarray(vertex_mask).astype(rdt)
    total = jnp.maximum(jnp.sum(w), jnp.finfo(rdt).tiny)
    nu2 = (w @ abs2(x)) / total
    eps = jnp.abs(params.eps.astype(rdt))
    factor = params.scale.astype(rdt) * jax.lax.rsqrt(nu2 + jnp.asarray(delta, rdt) + eps)
    return jax.lax.complex(x.real * factor, x.imag * factor)

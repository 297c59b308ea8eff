"""The stages of :func:`~jmeshtex.ops.field_conv`, as separate pure functions (for profiling and reading).

:func:`~jmeshtex.ops.field_conv` evaluates, per vertex block and in one loop,

1. :func:`field_conv_terms`: gather the neighbours' features, transport them into each vertex's
   frame and weight them, ``z_{pqc} = ŵ_{pq} ρ_{q→p} x_{qc}``, and form the gauge-invariant filter
   arguments ``a_{pqc} = log_p(q) · conj(û_{pqc})``;
2. :func:`field_conv_filter_sums`: ``S_{phc} = Σ_q z_{pqc} φ_h(a_{pqc}, e_p)`` (responses from
   :func:`field_conv_responses`, never stored);
3. :func:`field_conv_mix`: the complex dense layer ``y_{pd} = Σ_{c,h} S_{phc} M_{chd}``.

These functions run the same numerics over the whole mesh at once, so each stage can be timed on its
own (``docs/performance.md``); composed, they give ``field_conv``'s output to rounding.
"""

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp

from .._errors import ConfigError, InputError
from .._neighborhoods import VertexNeighborhood
from .._types import Array, ArrayLike, Complex, Float
from ._field_conv_params import FieldConvParams
from ._field_conv_terms import (
    ACTIVATIONS,
    as_complex,
    filtered_sums_fused,
    filtered_sums_plain,
    gather_terms,
    mix_halves,
    responses,
    slot_geometry,
)
from ._numerics import check_complex, check_delta, complex_dtype, real_dtype


class FieldConvTerms(NamedTuple):
    """Per-slot terms of a field convolution (:func:`field_conv_terms`), real ``[V, K, C]`` each.

    Attributes:
      z_real, z_imag: ``ŵ_{pq} ρ_{q→p} x_{qc}``, the weighted features transported into p's frame.
      arg_real, arg_imag: the filter argument ``a_{pqc} = log_p(q) · conj(û_{pqc})``.
    """

    z_real: Float[ArrayLike, "V K C"]
    z_imag: Float[ArrayLike, "V K C"]
    arg_real: Float[ArrayLike, "V K C"]
    arg_imag: Float[ArrayLike, "V K C"]


def field_conv_terms(
    x: Complex[ArrayLike, "V C"], nbhd: VertexNeighborhood, *, delta: float = 1e-4
) -> FieldConvTerms:
    """Stage 1 of :func:`~jmeshtex.ops.field_conv`: transported, weighted features and filter arguments.

    .. math:: z_{pqc} = \\hat w_{pq}\\, \\rho_{q\\to p} x_{qc}, \\qquad
       a_{pqc} = \\log_p(q)\\, \\overline{u_{pqc}} / \\sqrt{|u_{pqc}|^2 + \\delta^2},
       \\qquad u_{pqc} = \\rho_{q\\to p} x_{qc}

    Args:
      x: ``[V, C]`` complex tangent features, each in its own vertex's frame.
      nbhd: padded :class:`~jmeshtex.VertexNeighborhood` with ``K`` slots.
      delta: ``δ > 0`` of the smoothed direction, as in ``field_conv``.

    Returns:
      :class:`FieldConvTerms`, real ``[V, K, C]`` arrays of ``x``'s real dtype (0 on padded slots'
      ``z``).

    Example:
      >>> import jax
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.geometry import one_ring_neighborhood
      >>> from jmeshtex.ops import field_conv, init_field_conv
      >>> nbhd = one_ring_neighborhood(*icosphere(1))
      >>> x = jax.random.normal(jax.random.key(0), (42, 3), jnp.complex128)
      >>> params = init_field_conv(jax.random.key(1), 3, 5, hdim=4, dtype=jnp.complex128)
      >>> terms = field_conv_terms(x, nbhd)
      >>> terms.z_real.shape
      (42, 6, 3)
      >>> y = field_conv_mix(field_conv_filter_sums(terms, params), params)
      >>> bool(jnp.allclose(y, field_conv(x, nbhd, params), rtol=1e-12, atol=1e-12))
      True
    """
    check_complex(x, "field_conv_terms", ndim_min=2)
    delta = check_delta(delta, "field_conv_terms")
    if x.ndim != 2 or jnp.shape(nbhd.index)[:1] != x.shape[:1]:
        raise InputError(
            f"field_conv_terms: x must be [V, C] with V = nbhd.index.shape[0], got {x.shape} and "
            f"{jnp.shape(nbhd.index)}"
        )
    index, slots = slot_geometry(nbhd, real_dtype(x.dtype))
    return FieldConvTerms(*gather_terms(x.real, x.imag, index, slots, delta, blocked=False))


def _filter_inputs(params: FieldConvParams, v: int, rdt, embedding):
    """Filter weights ``[2, H]`` for ``(Re a, Im a)`` and the per-vertex pre-activation bias ``[V, H]``."""
    a_w = params.filter_weight.astype(rdt)
    n_emb = a_w.shape[0] - 2
    bias = jnp.broadcast_to(params.filter_bias.astype(rdt), (v, a_w.shape[1]))
    if (embedding is None) != (n_emb == 0) or (
        embedding is not None and jnp.shape(embedding) != (v, n_emb)
    ):
        raise InputError(
            f"field_conv stages: filter_weight {params.filter_weight.shape} expects an embedding "
            f"[V, {n_emb}] (V = {v}), got {None if embedding is None else jnp.shape(embedding)}"
        )
    if n_emb:
        bias = bias + jnp.asarray(embedding).astype(rdt) @ a_w[2:]
    return a_w[:2], bias


def _check_activation(activation: str, name: str) -> None:
    if activation not in ACTIVATIONS:
        raise ConfigError(f"{name}: activation must be one of {ACTIVATIONS}, got {activation!r}")


def field_conv_responses(
    arg_real: Float[ArrayLike, "V K C"],
    arg_imag: Float[ArrayLike, "V K C"],
    params: FieldConvParams,
    *,
    embedding: Float[ArrayLike, "V E"] | None = None,
    activation: str = "silu",
) -> Float[Array, "V K H C"]:
    """The filter responses ``φ_h(a, e)`` of every slot and channel, materialised: ``[V, K, H, C]``.

    .. math:: \\varphi_h(a, e) = \\mathrm{act}\\big(A_{0h} \\mathrm{Re}\\,a + A_{1h} \\mathrm{Im}\\,a
       + \\textstyle\\sum_j A_{2+j,h}\\, e_j + b_h\\big)

    The very function ``field_conv`` evaluates inside its filter sums (where the responses are never
    written to memory); materialised like this it serves to measure the activation's throughput.

    Args:
      arg_real, arg_imag: ``[V, K, C]`` filter arguments (:class:`FieldConvTerms`).
      params: :class:`~jmeshtex.ops.FieldConvParams` (its ``mix`` is not used).
      embedding: ``[V, E]`` per-vertex scalars, as in ``field_conv``.
      activation: ``"silu"`` or ``"relu"``.

    Returns:
      ``[V, K, H, C]`` real.

    Example:
      >>> from jmeshtex.ops import FieldConvParams
      >>> p = FieldConvParams(filter_weight=jnp.array([[1.0], [0.0]]), filter_bias=jnp.zeros(1),
      ...                     mix=jnp.ones((1, 1, 1), jnp.complex64))
      >>> a = jnp.array([-1.0, 0.0, 2.0]).reshape(1, 3, 1)
      >>> field_conv_responses(a, jnp.zeros_like(a), p, activation="relu")[0, :, 0, 0].tolist()
      [0.0, 0.0, 2.0]
    """
    _check_activation(activation, "field_conv_responses")
    a_w, bias = _filter_inputs(params, arg_real.shape[0], arg_real.dtype, embedding)
    return responses(arg_real, arg_imag, a_w, bias, activation)


def field_conv_filter_sums(
    terms: FieldConvTerms,
    params: FieldConvParams,
    *,
    embedding: Float[ArrayLike, "V E"] | None = None,
    activation: str = "silu",
) -> tuple[Float[Array, "V H C"], Float[Array, "V H C"]]:
    """Stage 2 of :func:`~jmeshtex.ops.field_conv`: the filtered sums over each neighbourhood.

    .. math:: S_{phc} = \\sum_{q} z_{pqc}\\, \\varphi_h(a_{pqc}, e_p)

    One fused reduction that evaluates every response once and never stores it; its derivatives
    (every mode and order, through a ``custom_jvp``) are those of the plain formula, which
    materialises the ``[V, K, H, C]`` responses (``field_conv`` itself differentiates block by
    block instead; the two agree to rounding).

    Args:
      terms: :class:`FieldConvTerms` from :func:`field_conv_terms`.
      params: :class:`~jmeshtex.ops.FieldConvParams` (its ``mix`` is not used).
      embedding: ``[V, E]`` per-vertex scalars, as in ``field_conv``.
      activation: ``"silu"`` or ``"relu"``.

    Returns:
      ``(S_real, S_imag)``, each real ``[V, H, C]``.

    Example:
      >>> import jax
      >>> from jmeshtex.ops import init_field_conv
      >>> terms = FieldConvTerms(*jnp.ones((4, 10, 6, 3)))  # V = 10, K = 6, C = 3
      >>> p = jax.eval_shape(lambda key: init_field_conv(key, 3, 5, hdim=4), jax.random.key(0))
      >>> [s.shape for s in jax.eval_shape(field_conv_filter_sums, terms, p)]
      [(10, 4, 3), (10, 4, 3)]
    """
    _check_activation(activation, "field_conv_filter_sums")
    zr, zi, ar, ai = terms
    a_w, bias = _filter_inputs(params, zr.shape[0], zr.dtype, embedding)
    return _filtered_sums(zr, zi, ar, ai, a_w, bias, activation)


def field_conv_mix(
    sums: tuple[Float[ArrayLike, "V H C"], Float[ArrayLike, "V H C"]], params: FieldConvParams
) -> Complex[Array, "V D"]:
    """Stage 3 of :func:`~jmeshtex.ops.field_conv`: the complex dense layer over the filtered sums.

    .. math:: y_{pd} = \\sum_{c,h} (S^{re}_{phc} + i\\, S^{im}_{phc})\\, M_{chd}

    computed as one real GEMM per part, ``S_re [M_re, M_im] + S_im [-M_im, M_re]``.

    Args:
      sums: ``(S_real, S_imag)`` from :func:`field_conv_filter_sums`, each ``[V, H, C]``.
      params: :class:`~jmeshtex.ops.FieldConvParams` (``mix [C, H, D]``, cast to the sums' dtype).

    Returns:
      ``[V, D]`` complex features in each vertex's frame.

    Example:
      >>> from jmeshtex.ops import FieldConvParams
      >>> p = FieldConvParams(filter_weight=jnp.zeros((2, 1)), filter_bias=jnp.zeros(1),
      ...                     mix=jnp.array([[[1j]]], jnp.complex64))  # C = H = D = 1
      >>> field_conv_mix((jnp.full((1, 1, 1), 2.0), jnp.zeros((1, 1, 1))), p).tolist()
      [[2j]]
    """
    s_r, s_i = sums
    v = s_r.shape[0]
    if s_r.shape[1:] != params.mix.shape[1::-1]:
        raise InputError(
            f"field_conv_mix: sums {s_r.shape} do not match mix [C, H, D] = {params.mix.shape}"
        )
    m_r, m_i = mix_halves(params.mix.astype(complex_dtype(s_r.dtype)))
    return as_complex(s_r.reshape(v, -1) @ m_r + s_i.reshape(v, -1) @ m_i)


@functools.partial(jax.custom_jvp, nondiff_argnums=(6,))
def _filtered_sums(zr, zi, ar, ai, a_w, bias, activation):
    """:func:`~._field_conv_terms.filtered_sums_fused`, differentiated as the plain formula."""
    return filtered_sums_fused(zr, zi, ar, ai, a_w, bias, activation)


def _filtered_sums_jvp(activation, primals, tangents):
    out = _filtered_sums(*primals, activation)  # higher orders re-enter this rule

    def plain(*args):
        return filtered_sums_plain(*args, activation)

    return out, jax.jvp(plain, primals, tangents)[1]


_filtered_sums.defjvp(_filtered_sums_jvp)

"""Field convolutions of tangent-vector features (Mitchel et al., ICCV 2021; CVPR 2024 eq. 34–35).

A field convolution gathers, at every vertex ``p``, the features ``x_q`` of its neighbours, brings
them into ``p``'s frame with the parallel transport ``ρ_{q→p}``, and weights each by a filter
evaluated at the neighbour's position *relative to the feature's own direction*. Because that
relative position is invariant to the frames at both ends, the result is equivariant to gauge
changes (and hence intrinsic: unchanged by isometries that preserve the log maps and transports).

Filter argument ("gathering" form). With ``u_{pqc} = ρ_{q→p} x_{qc}`` (the feature of
channel ``c`` at ``q``, in ``p``'s frame) and ``û = u / sqrt(|u|² + δ²)`` its smoothed direction,

.. math:: a_{pqc} = \\log_p(q)\\, \\overline{\\hat u_{pqc}}

i.e. the neighbour's position in a frame aligned with the transported feature. Under a gauge change
``α`` at every vertex, ``log_p(q) → log_p(q) e^{-iα_p}`` and ``u_{pqc} → u_{pqc} e^{-iα_p}``, so
``a`` is unchanged. The seed paper's eq. 34 as printed pairs ``log_p(q)`` (p's frame) with ``x̂_q``
in q's own frame; that argument moves by ``e^{i(α_q − α_p)}`` and is *not* gauge-invariant (the test
suite keeps it as a negative control).

At ``x_q = 0`` the direction is undefined; ``û`` then goes to 0 smoothly, so the filter is evaluated
at the rotation-invariant centre ``a = 0`` of its domain, and its value is multiplied by
``x_q = 0`` anyway: the output, and every gradient, is finite and continuous there.

Filters ("PointConv trick", Wu et al. 2019): a small real MLP maps ``(Re a, Im a)`` -- plus an
optional per-vertex scalar embedding ``e_p`` such as a diffusion timestep or labels (eq. 35) -- to
``H`` real responses; the transported, weighted features are summed against them over the
neighbourhood, and one complex dense layer mixes the ``C·H`` sums to ``D`` outputs. That dense
layer is the MLP's (complex) output layer, so the effective filter from channel ``c`` to ``d`` is
``f_{cd}(a) = Σ_h M_{chd} φ_h(a)``, a one-hidden-layer MLP of the invariant argument.
"""

from __future__ import annotations

import jax.numpy as jnp

from .._errors import ConfigError, InputError
from .._neighborhoods import VertexNeighborhood, check_log_scale
from .._types import Array, ArrayLike, Complex, Float
from ._field_conv_fast import conv_fast
from ._field_conv_general import conv_general
from ._field_conv_params import FieldConvParams
from ._field_conv_terms import ACTIVATIONS, ARGUMENTS, slot_geometry
from ._numerics import check_complex, check_delta, complex_dtype, real_dtype


def field_conv(
    x: Complex[ArrayLike, "V C"],
    nbhd: VertexNeighborhood,
    params: FieldConvParams,
    *,
    embedding: Float[ArrayLike, "V E"] | None = None,
    channel_embedding: Float[ArrayLike, "V C"] | None = None,
    delta: float = 1e-4,
    activation: str = "silu",
    argument: str = "transported",
) -> Complex[Array, "V D"]:
    """Field convolution of tangent features with MLP filters (Mitchel et al. 2021; 2024 eq. 34–35).

    .. math:: y_{pd} = \\sum_{c,h} M_{chd} \\sum_{q \\in N(p)} \\hat w_{pq}\\, \\rho_{q\\to p}\\,
       x_{qc}\\; \\varphi_h\\big(\\log_p(q)\\,\\overline{\\hat u_{pqc}},\\, e_p\\big)

    with ``u_{pqc} = ρ_{q→p} x_{qc}``, ``û = u / sqrt(|u|² + δ²)`` (see the module docstring),
    ``ŵ_{pq} = w_{pq} / Σ_{q'} w_{pq'}`` the slot weights (``nbhd.weight``, mask folded in)
    normalised per vertex, and the filter responses

    .. math:: \\varphi_h(a, e) = \\mathrm{SiLU}\\big(A_{0h} \\mathrm{Re}\\,a + A_{1h} \\mathrm{Im}\\,a
       + \\textstyle\\sum_j A_{2+j,h}\\, e_j + b_h\\big)

    Everything inside the filter is gauge-invariant and the rest is complex-linear in features that
    all live in ``p``'s frame, so a gauge change ``x_p → x_p e^{-iα_p}`` (with the matching log maps
    and transports) gives ``y_p → y_p e^{-iα_p}`` exactly. The filter argument scales with the log
    map, so neighbourhoods should come with log maps of about unit scale: build them with
    ``scale="mean_edge"`` (the builders' default) or call :func:`jmeshtex.scale_log_maps` (a
    recorded ``log_unit`` must be positive and finite); a concrete neighbourhood without a
    recorded unit whose typical edge (:func:`jmeshtex.check_log_scale`) is outside ``[0.2, 5]``
    warns once (:class:`jmeshtex.LogScaleWarning`).

    Args:
      x: ``[V, C]`` complex tangent features, each in its own vertex's frame.
      nbhd: padded :class:`~jmeshtex.VertexNeighborhood` (one-ring or k-NN; a k-NN self
        slot has ``log = 0`` and contributes ``x_p φ(0)``). Padded slots and vertices contribute
        nothing; a vertex with no valid slot gets 0.
      params: :class:`FieldConvParams` (cast to ``x``'s dtype).
      embedding: optional ``[V, E]`` real per-vertex scalars appended to the filter input
        (timestep or label embedding, eq. 35); broadcast a global one to ``[V, E]``.
      channel_embedding: optional ``[V, C]`` real per-vertex, per-*channel* scalars: channel ``c``'s
        filter sees ``e_{pc}`` as a third input, ``φ_h(a, e_p, e_{pc})`` with the first layer's row
        ``params.channel_weight`` (the reference's ``FieldConvEmb``, which conditions each channel's
        filter on its own timestep/label embedding value). Requires ``channel_weight``.
      delta: ``δ > 0`` of the smoothed direction ``û``.
      activation: the filter nonlinearity, ``"silu"`` (default, as the reference code) or
        ``"relu"`` (piecewise-linear filters, cheaper to evaluate).
      argument: ``"transported"`` (default): the gauge-invariant ``log_p(q) · conj(û_{pqc})``
        above. ``"untransported"``: ``log_p(q) · conj(x̂_q)`` with ``x̂_q`` in *q's* frame, the
        form of the seed paper's eq. 34 and of the reference code's ``get_rel_pos``; it moves by
        ``e^{i(α_q − α_p)}`` under a gauge change, so the output is **not** equivariant (kept for
        the equivariance harness's negative control).

    Returns:
      ``[V, D]`` complex features in each vertex's frame, dtype of ``x``.

    Transformations: ``field_conv`` is a pure function of arrays and composes with every JAX
    transformation in any order (``jit``, ``vmap``, ``grad``, ``vjp``, ``jvp``, ``linearize``,
    ``jacfwd``, ``jacrev``, ``hessian``, ``checkpoint``, and each under the others, e.g.
    ``jax.jvp(jax.jit(f))``); derivatives with respect to the neighbourhood's geometry work too.
    Two implementations give the same values to rounding, chosen from the arguments alone (never
    from how the call is traced): the transported argument (one or two hidden filter layers) runs
    a fused blocked forward with a ``custom_jvp`` whose tangent is plain JAX (reverse mode
    recomputes the filter responses block by block instead of storing them); the untransported
    argument runs a blocked plain-JAX formula under ``jax.checkpoint``. Timings and memory:
    docs/design_notes.md, "Field convolution".

    Example:
      >>> import jax
      >>> import numpy as np
      >>> nb = VertexNeighborhood(index=np.array([[0, 1], [1, 0]]), mask=np.ones((2, 2), bool),
      ...     log=np.array([[0, 1], [0, -1]], complex), transport=np.ones((2, 2), complex),
      ...     weight=np.ones((2, 2)), area=np.ones(2), vertex_mask=np.ones(2, bool))
      >>> p = FieldConvParams(filter_weight=jnp.array([[1.0, 0.0], [0.0, 1.0]]), filter_bias=jnp.zeros(2),
      ...                     mix=jnp.ones((3, 2, 5), jnp.complex64))  # C = 3, H = 2, D = 5
      >>> x = jnp.array([[1 + 1j, 2, -1j], [0.5j, 1, 1]], jnp.complex64)
      >>> conv = jax.jit(field_conv)
      >>> y = conv(x, nb, p)
      >>> turned = nb._replace(log=nb.log * 1j)  # every frame turned by -90°: x, log, y get a factor i
      >>> y.shape, bool(jnp.allclose(conv(x * 1j, turned, p), y * 1j, atol=1e-5))
      ((2, 5), True)
    """
    check_complex(x, "field_conv", ndim_min=2)
    delta = check_delta(delta, "field_conv")
    if activation not in ACTIVATIONS:
        raise ConfigError(
            f"field_conv: activation must be one of {ACTIVATIONS}, got {activation!r}"
        )
    if argument not in ARGUMENTS:
        raise ConfigError(f"field_conv: argument must be one of {ARGUMENTS}, got {argument!r}")
    v, c, h, d, n_emb = _check_shapes(x, nbhd, params, embedding)
    _check_extra(params, channel_embedding, v, c, h)
    check_log_scale(nbhd, "field_conv", once=True)
    rdt = real_dtype(x.dtype)
    a_w = params.filter_weight.astype(rdt)
    bias = jnp.broadcast_to(params.filter_bias.astype(rdt), (v, h))
    if n_emb:
        bias = bias + jnp.asarray(embedding).astype(rdt) @ a_w[2:]
    index, slots = slot_geometry(nbhd, rdt)
    mix = params.mix.astype(complex_dtype(x.dtype))
    channel = None
    if channel_embedding is not None:
        channel = (jnp.asarray(channel_embedding).astype(rdt), params.channel_weight.astype(rdt))
    hidden = None
    if params.hidden_weight is not None:
        hidden = (params.hidden_weight.astype(rdt), params.hidden_bias.astype(rdt))
    if argument == "transported":
        fast_bias = bias
        if channel is not None:  # per-channel pre-activation offsets [V, H, C]
            fast_bias = bias[:, :, None] + channel[1][None, :, None] * channel[0][:, None, :]
        return conv_fast(x, index, slots, a_w[:2], fast_bias, mix, delta, activation, hidden)
    return conv_general(
        x,
        index,
        slots,
        a_w[:2],
        bias,
        mix,
        channel,
        hidden,
        delta=delta,
        activation=activation,
        transported=argument == "transported",
    )


def _check_extra(params: FieldConvParams, channel_embedding, v: int, c: int, h: int) -> None:
    if (params.hidden_weight is None) != (params.hidden_bias is None):
        raise InputError("field_conv: hidden_weight and hidden_bias must be given together")
    if params.hidden_weight is not None and (
        jnp.shape(params.hidden_weight) != (h, h) or jnp.shape(params.hidden_bias) != (h,)
    ):
        raise InputError(
            f"field_conv: hidden_weight must be [H, H] = ({h}, {h}) and hidden_bias [H], got "
            f"{jnp.shape(params.hidden_weight)} and {jnp.shape(params.hidden_bias)}"
        )
    if channel_embedding is None:
        if params.channel_weight is not None:
            raise InputError(
                "field_conv: params has a channel_weight but channel_embedding=None; pass [V, C]"
            )
        return
    if params.channel_weight is None or jnp.shape(params.channel_weight) != (h,):
        raise InputError(
            f"field_conv: channel_embedding needs params.channel_weight of shape [H] = ({h},) "
            "(init_field_conv(..., channel_embedding=True))"
        )
    if jnp.shape(channel_embedding) != (v, c):
        raise InputError(
            f"field_conv: channel_embedding must be [V, C] = ({v}, {c}), got {jnp.shape(channel_embedding)}"
        )
    if not jnp.issubdtype(jnp.result_type(channel_embedding), jnp.floating):
        raise InputError(
            f"field_conv: channel_embedding must be real, got {jnp.result_type(channel_embedding)}"
        )


def _check_shapes(x, nbhd: VertexNeighborhood, params: FieldConvParams, embedding):
    v, c = x.shape if x.ndim == 2 else (None, None)
    if x.ndim != 2:
        raise InputError(f"field_conv: x must be [V, C] (vmap for batches), got shape {x.shape}")
    shape = jnp.shape(nbhd.index)
    if len(shape) != 2 or shape[0] != v or shape[1] < 1:
        raise InputError(
            f"field_conv: x has {v} vertices but nbhd.index has shape {shape}; pad x to the "
            "neighbourhood's V (jmeshtex.geometry.pad_to pads the neighbourhood)"
        )
    for field in ("mask", "log", "transport", "weight"):
        if jnp.shape(getattr(nbhd, field)) != shape:
            raise InputError(
                f"field_conv: nbhd.{field} has shape {jnp.shape(getattr(nbhd, field))}, expected {shape}"
            )
    if jnp.ndim(params.filter_weight) != 2 or params.filter_weight.shape[0] < 2:
        raise InputError(
            f"field_conv: filter_weight must be [2 + E, H], got {jnp.shape(params.filter_weight)}"
        )
    n_in, h = params.filter_weight.shape
    if jnp.shape(params.filter_bias) != (h,):
        raise InputError(
            f"field_conv: filter_bias must be [H] = ({h},), got {jnp.shape(params.filter_bias)}"
        )
    if jnp.ndim(params.mix) != 3 or params.mix.shape[:2] != (c, h):
        raise InputError(
            f"field_conv: mix must be [C, H, D] = [{c}, {h}, D], got {jnp.shape(params.mix)}"
        )
    n_emb = n_in - 2
    if embedding is None:
        if n_emb:
            raise InputError(
                f"field_conv: the filter expects an embedding of width {n_emb} (filter_weight has "
                f"{n_in} rows) but embedding=None; pass embedding=[V, {n_emb}]"
            )
    elif jnp.shape(embedding) != (v, n_emb):
        raise InputError(
            f"field_conv: embedding must have shape [V, E] = ({v}, {n_emb}) to match filter_weight "
            f"{params.filter_weight.shape}, got {jnp.shape(embedding)}"
        )
    elif not jnp.issubdtype(jnp.result_type(embedding), jnp.floating):
        raise InputError(
            f"field_conv: embedding must be real floating point, got {jnp.result_type(embedding)}"
        )
    return v, c, h, params.mix.shape[2], n_emb

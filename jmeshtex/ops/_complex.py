"""Complex tangent-feature layers (Mitchel, Esteves, Makadia, CVPR 2024, supplement §9).

A tangent feature is one complex number per vertex and channel, expressed in that vertex's frame
(DESIGN.md). A change of gauge at a vertex rotates all of its channels together, ``x → x e^{-iα}``;
every layer here commutes with such a common rotation:

- :func:`complex_linear` mixes channels with complex weights and **no bias** (a bias would not
  rotate with the frame);
- :func:`vn_nonlinearity` (eq. 19) is a vector-neuron nonlinearity: it only looks at rotation
  invariants (``Re(q k̄)``, ``|k|²``) to decide how much of a learned direction to remove;
- :func:`filter_response_norm` (eq. 20) and :func:`complex_layer_norm` rescale magnitudes only;
- :func:`complex_attention` takes logits from ``Re(q·k̄)`` (rotation-invariant) and averages complex
  values, and :func:`vn_transformer_block` stacks it with a vector-neuron MLP and residuals.

All ops are pure functions of plain NamedTuple parameters, follow the input's dtype (complex64 /
complex128; parameters are cast to it), and have finite values and gradients at ``x = 0`` thanks to
their ``δ > 0`` terms. ``init_*`` functions draw parameters; the complex initialisation is a
circular Gaussian with ``E|w|² = 1/fan_in`` (complex LeCun normal), so a layer maps unit-variance
inputs to unit-variance outputs.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp

from .._errors import ConfigError, InputError
from .._types import Array, Bool, Complex, Float, PRNGKey
from ._numerics import abs2, check_complex, check_delta, complex_dtype, complex_matmul, real_dtype

# ----------------------------------------------------------------------------------------- init


def complex_lecun_normal(key: PRNGKey, shape: tuple[int, ...], *, fan_in: int, dtype=jnp.complex64) -> Array:
    """Circular complex Gaussian weights with ``E|w|² = 1/fan_in`` (complex LeCun normal).

    .. math:: w = \\frac{a + i b}{\\sqrt{2\\,\\mathrm{fan\\_in}}}, \\qquad a, b \\sim \\mathcal N(0, 1)

    The phase is uniform and independent of the modulus (Rayleigh distributed), so the distribution
    is invariant to rotations ``w → w e^{iα}``; a linear layer with these weights maps inputs with
    ``E|x_c|² = 1`` to outputs with ``E|y_d|² = 1``.

    Args:
      key: PRNG key.
      shape: weight shape.
      fan_in: number of inputs summed into each output.
      dtype: ``complex64`` or ``complex128``.

    Example:
      >>> w = complex_lecun_normal(jax.random.key(0), (256, 512), fan_in=256)
      >>> round(float(jnp.mean(jnp.abs(w) ** 2) * 256), 1)
      1.0
    """
    return complex_lecun_blocks(key, [(tuple(shape), fan_in)], dtype=dtype)[0]


def normal_blocks(key: PRNGKey, shapes, dtype) -> list[Array]:
    """Standard normal arrays of the given shapes, cut from **one** draw.

    Every ``jax.random`` call adds its own generator to the compiled program (~0.5 s of XLA:CPU
    compile time each), so the ``init_*`` functions draw all their numbers at once.
    """
    sizes = [math.prod(s) for s in shapes]
    flat = jax.random.normal(key, (sum(sizes),), dtype)
    out, start = [], 0
    for shape, n in zip(shapes, sizes, strict=False):
        out.append(flat[start : start + n].reshape(shape))
        start += n
    return out


def complex_lecun_blocks(key: PRNGKey, specs, *, dtype=jnp.complex64, extra_real=()) -> list[Array]:
    """Complex LeCun-normal arrays for ``specs = [(shape, fan_in), ...]`` (then standard normal real
    arrays of the shapes in ``extra_real``), all from one draw."""
    dtype = complex_dtype(dtype)
    rdt = real_dtype(dtype)
    blocks = normal_blocks(key, [(2, *shape) for shape, _ in specs] + list(extra_real), rdt)
    out = [
        jax.lax.complex(b[0], b[1]) * jnp.asarray(1.0 / math.sqrt(2.0 * fan_in), rdt).astype(dtype)
        for b, (_, fan_in) in zip(blocks, specs, strict=False)
    ]
    return out + blocks[len(specs) :]


def init_complex_linear(key: PRNGKey, in_features: int, out_features: int, *, dtype=jnp.complex64) -> Complex[Array, "C D"]:
    """Weights ``[in_features, out_features]`` for :func:`complex_linear` (:func:`complex_lecun_normal`).

    Example:
      >>> jax.eval_shape(lambda key: init_complex_linear(key, 3, 5), jax.random.key(0)).shape
      (3, 5)
    """
    return complex_lecun_normal(key, (in_features, out_features), fan_in=in_features, dtype=dtype)


# --------------------------------------------------------------------------------- linear layer


def complex_linear(x: Complex[Array, "... C"], w: Complex[Array, "C D"]) -> Complex[Array, "... D"]:
    """Complex linear layer without bias: ``y = x W``.

    .. math:: y_d = \\sum_c x_c\\, W_{cd}

    There is deliberately no bias: ``(x e^{-iα}) W = (x W) e^{-iα}``, whereas a bias ``b`` would stay
    put when the frame rotates and break gauge equivariance.

    Args:
      x: ``[..., C]`` complex tangent features (any leading axes), each in its vertex's frame.
      w: ``[C, D]`` complex weights (cast to ``x``'s dtype).

    Returns:
      ``[..., D]`` complex, same frames and dtype as ``x``.

    Example:
      >>> x = jnp.array([[1j, 1.0]], jnp.complex64)
      >>> complex_linear(x, jnp.array([[1.0], [1j]], jnp.complex64)).tolist()
      [[2j]]
    """
    check_complex(x, "complex_linear")
    if jnp.ndim(w) != 2 or w.shape[0] != x.shape[-1]:
        raise InputError(
            f"complex_linear: x has {x.shape[-1]} channels but w has shape {jnp.shape(w)}; "
            "w must be [C, D] with C = x.shape[-1]"
        )
    return complex_matmul(x, w)


# --------------------------------------------------------------------- vector-neuron nonlinearity


class VNParams(NamedTuple):
    """Parameters of :func:`vn_nonlinearity`.

    Attributes:
      weight: ``[C, D]`` complex map to the features ``q = x W``; ``None`` means ``q = x`` (then
        ``D = C``).
      direction: ``[C, D]`` complex map to the learned directions ``k = x U``.
    """

    weight: Complex[Array, "C D"] | None
    direction: Complex[Array, "C D"]


def init_vn(key: PRNGKey, in_features: int, out_features: int | None = None, *, dtype=jnp.complex64) -> VNParams:
    """Random :class:`VNParams` (complex LeCun normal).

    Args:
      key: PRNG key.
      in_features: ``C``.
      out_features: ``D``; ``None`` gives the residual form ``q = x`` (``weight=None``, ``D = C``).
      dtype: complex dtype of the weights.

    Example:
      >>> p = jax.eval_shape(lambda key: init_vn(key, 4, 6), jax.random.key(0))
      >>> p.weight.shape, p.direction.shape, init_vn(jax.random.key(0), 4).weight is None
      ((4, 6), (4, 6), True)
    """
    out = in_features if out_features is None else out_features
    spec = ((in_features, out), in_features)
    if out_features is None:
        return VNParams(weight=None, direction=complex_lecun_blocks(key, [spec], dtype=dtype)[0])
    weight, direction = complex_lecun_blocks(key, [spec, spec], dtype=dtype)
    return VNParams(weight=weight, direction=direction)


def vn_nonlinearity(x: Complex[Array, "... C"], params: VNParams, *, delta: float = 1e-6) -> Complex[Array, "... D"]:
    """Vector-neuron nonlinearity for tangent features (2024 supplement eq. 19; Deng et al. 2021).

    With ``q = x W`` (or ``q = x``) and ``k = x U``, per output channel:

    .. math:: y = q + \\frac{\\mathrm{SiLU}\\big(-\\langle q, k\\rangle\\big)}{|k|^2 + \\delta}\\, k,
       \\qquad \\langle q, k\\rangle = \\mathrm{Re}(q\\,\\bar k)

    For ``⟨q, k⟩ ≫ 0`` this is ``y ≈ q``; for ``⟨q, k⟩ ≪ 0`` it is ``y ≈ q − ⟨q,k⟩ k/|k|²``, the
    projection of ``q`` onto the half-plane ``⟨y, k⟩ ≥ 0`` (the vector-neuron ReLU), with SiLU as a
    smooth switch between the two. ``⟨q, k⟩`` and ``|k|²`` are invariant to a common rotation of the
    channels, so ``x → x e^{iα}`` gives ``y → y e^{iα}``. ``δ > 0`` keeps the value and gradient finite
    at ``k = 0`` (where ``y = q``), in particular at ``x = 0`` (where ``y = 0``).

    Args:
      x: ``[..., C]`` complex tangent features.
      params: :class:`VNParams` (cast to ``x``'s dtype).
      delta: ``δ > 0`` in the denominator.

    Returns:
      ``[..., D]`` complex, in the same frames as ``x``.

    Example:
      >>> p = VNParams(weight=None, direction=jnp.eye(1, dtype=jnp.complex64))  # k = q = x
      >>> y = vn_nonlinearity(jnp.array([[2 + 0j], [-2 + 0j]], jnp.complex64), p)
      >>> y.real.round(4).tolist()  # coefficient SiLU(-4)/4 = -sigmoid(-4): x shrinks by 1.8 %
      [[1.964], [-1.964]]
    """
    check_complex(x, "vn_nonlinearity")
    delta = check_delta(delta, "vn_nonlinearity")
    c = x.shape[-1]
    if params.weight is None:
        q = x
        if params.direction.shape[-1] != c:
            raise InputError(
                f"vn_nonlinearity: with weight=None the output has C = {c} channels, but direction has "
                f"shape {params.direction.shape}; pass a weight [C, D] or a direction [C, C]"
            )
    else:
        if params.weight.shape[-1] != params.direction.shape[-1]:
            raise InputError(
                f"vn_nonlinearity: weight {params.weight.shape} and direction {params.direction.shape} "
                "must have the same output width D"
            )
        q = complex_linear(x, params.weight)
    k = complex_linear(x, params.direction)
    dot = q.real * k.real + q.imag * k.imag
    coef = jax.nn.silu(-dot) / (abs2(k) + jnp.asarray(delta, dot.dtype))
    return jax.lax.complex(q.real + coef * k.real, q.imag + coef * k.imag)


# ------------------------------------------------------------------- filter response normalisation


class FRNParams(NamedTuple):
    """Parameters of :func:`filter_response_norm`.

    Attributes:
      scale: ``[C]`` real gain ``γ``.
      eps: ``[C]`` real learned stabiliser; ``|ε|`` is added under the square root.
    """

    scale: Float[Array, " C"]
    eps: Float[Array, " C"]


def init_frn(features: int, *, dtype=jnp.float32, eps: float = 1e-3) -> FRNParams:
    """:class:`FRNParams` with ``γ = 1`` and ``ε = eps`` (deterministic, no key needed).

    Example:
      >>> init_frn(3).scale.tolist()
      [1.0, 1.0, 1.0]
    """
    dtype = real_dtype(dtype)
    return FRNParams(scale=jnp.ones((features,), dtype), eps=jnp.full((features,), eps, dtype))


def filter_response_norm(
    x: Complex[Array, "V C"],
    params: FRNParams,
    *,
    area: Float[Array, " V"],
    vertex_mask: Bool[Array, " V"] | None = None,
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
        raise InputError(f"filter_response_norm: x must be [V, C] (vmap for batches), got shape {x.shape}")
    v, c = x.shape
    if jnp.shape(area) != (v,):
        raise InputError(f"filter_response_norm: area must have shape [V] = ({v},), got {jnp.shape(area)}")
    if params.scale.shape != (c,) or params.eps.shape != (c,):
        raise InputError(
            f"filter_response_norm: scale and eps must have shape [C] = ({c},), got "
            f"{params.scale.shape} and {params.eps.shape}"
        )
    rdt = real_dtype(x.dtype)
    w = jnp.asarray(area).astype(rdt)
    if vertex_mask is not None:
        if jnp.shape(vertex_mask) != (v,):
            raise InputError(f"filter_response_norm: vertex_mask must have shape ({v},), got {jnp.shape(vertex_mask)}")
        w = w * jnp.asarray(vertex_mask).astype(rdt)
    total = jnp.maximum(jnp.sum(w), jnp.finfo(rdt).tiny)
    nu2 = (w @ abs2(x)) / total
    eps = jnp.abs(params.eps.astype(rdt))
    factor = params.scale.astype(rdt) * jax.lax.rsqrt(nu2 + jnp.asarray(delta, rdt) + eps)
    return jax.lax.complex(x.real * factor, x.imag * factor)


def complex_layer_norm(
    x: Complex[Array, "... C"], scale: Float[Array, " C"], *, delta: float = 1e-6
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
        raise InputError(f"complex_layer_norm: scale must have shape [C] = ({x.shape[-1]},), got {jnp.shape(scale)}")
    rdt = real_dtype(x.dtype)
    factor = jnp.asarray(scale).astype(rdt) * jax.lax.rsqrt(
        jnp.mean(abs2(x), axis=-1, keepdims=True) + jnp.asarray(delta, rdt)
    )
    return jax.lax.complex(x.real * factor, x.imag * factor)


# ------------------------------------------------------------------------------------ attention


class ComplexAttentionParams(NamedTuple):
    """Parameters of :func:`complex_attention` (no biases: they would break equivariance).

    Attributes:
      query: ``[C, H, E]`` complex, input channels → heads × query/key width.
      key: ``[C, H, E]`` complex.
      value: ``[C, H, F]`` complex, input channels → heads × value width.
      out: ``[H, F, D]`` complex output projection.
    """

    query: Complex[Array, "C H E"]
    key: Complex[Array, "C H E"]
    value: Complex[Array, "C H F"]
    out: Complex[Array, "H F D"]


def init_complex_attention(
    key: PRNGKey,
    in_features: int,
    *,
    num_heads: int,
    head_features: int | None = None,
    out_features: int | None = None,
    dtype=jnp.complex64,
) -> ComplexAttentionParams:
    """Random :class:`ComplexAttentionParams` (complex LeCun normal).

    Args:
      key: PRNG key.
      in_features: ``C``.
      num_heads: ``H``.
      head_features: ``E = F`` per head; default ``C // H`` (``C`` must then be divisible by ``H``).
      out_features: ``D``; default ``C``.
      dtype: complex dtype.

    Example:
      >>> p = jax.eval_shape(lambda key: init_complex_attention(key, 8, num_heads=2), jax.random.key(0))
      >>> p.query.shape, p.out.shape
      ((8, 2, 4), (2, 4, 8))
    """
    if num_heads < 1:
        raise ConfigError(f"init_complex_attention: num_heads must be >= 1, got {num_heads}")
    if head_features is None:
        if in_features % num_heads:
            raise ConfigError(
                f"init_complex_attention: in_features = {in_features} is not divisible by num_heads = "
                f"{num_heads}; pass head_features explicitly"
            )
        head_features = in_features // num_heads
    out_features = in_features if out_features is None else out_features
    hf = (num_heads, head_features)
    qkv = ((in_features, *hf), in_features)
    return ComplexAttentionParams(
        *complex_lecun_blocks(key, [qkv, qkv, qkv, ((*hf, out_features), num_heads * head_features)], dtype=dtype)
    )


_MASKED_LOGIT = 1e30  # added (negated) to masked logits; exp(-1e30 - max) is exactly 0 in f32 and f64


def complex_attention(
    x: Complex[Array, "... S C"],
    params: ComplexAttentionParams,
    *,
    mask: Bool[Array, "... S"] | None = None,
) -> Complex[Array, "... S D"]:
    """Multi-head self-attention over a set of complex (tangent) features.

    With ``q = x W_q``, ``k = x W_k``, ``v = x W_v`` per head ``h`` (``E`` query/key channels):

    .. math:: a^h_{st} = \\operatorname{softmax}_t\\Big(\\frac{\\mathrm{Re}\\sum_e q^h_{se}\\,
       \\overline{k^h_{te}}}{\\sqrt E}\\Big), \\qquad
       y_s = \\sum_h \\Big(\\sum_t a^h_{st}\\, v^h_t\\Big) W_o^h

    The logits ``Re(q·k̄)`` do not change when every set element is rotated by the same ``e^{iα}``,
    and the output is a complex-linear function of the values, so ``x → x e^{iα}`` gives
    ``y → y e^{iα}``; without positional terms, permuting the set permutes the output. Masked
    elements (``mask`` False) get exactly zero attention weight: they never change valid outputs
    (their own outputs are computed but meaningless; if all elements are masked, the output is 0).

    Args:
      x: ``[..., S, C]`` complex: a set of ``S`` elements per leading index (e.g. per vertex), all
        in one frame.
      params: :class:`ComplexAttentionParams` (cast to ``x``'s dtype).
      mask: ``[..., S]`` True for valid set elements; None = all valid.

    Returns:
      ``[..., S, D]`` complex, in the same frame as ``x``.

    Example:
      >>> one = jnp.ones((1, 1, 1), jnp.complex64)  # one head, one channel: q = k = v = x
      >>> p = ComplexAttentionParams(query=one, key=one, value=one, out=one)
      >>> x = jnp.array([[1 + 0j], [1j]], jnp.complex64)  # a set of two elements
      >>> y = complex_attention(x, p)  # element 0: logits Re(1·1) = 1, Re(1·conj(i)) = 0
      >>> y[0, 0].round(4), bool(jnp.allclose(complex_attention(x * 1j, p), y * 1j))
      (Array(0.7311+0.2689j, dtype=complex64), True)
    """
    check_complex(x, "complex_attention", ndim_min=2)
    s, c = x.shape[-2:]
    if params.query.ndim != 3 or params.query.shape[0] != c or params.key.shape != params.query.shape:
        raise InputError(
            f"complex_attention: query and key must both be [C, H, E] with C = {c}, got "
            f"{params.query.shape} and {params.key.shape}"
        )
    _, h, e = params.query.shape
    if params.value.ndim != 3 or params.value.shape[:2] != (c, h):
        raise InputError(f"complex_attention: value must be [C, H, F] = [{c}, {h}, F], got {params.value.shape}")
    f = params.value.shape[2]
    if params.out.ndim != 3 or params.out.shape[:2] != (h, f):
        raise InputError(f"complex_attention: out must be [H, F, D] = [{h}, {f}, D], got {params.out.shape}")
    rdt = real_dtype(x.dtype)
    lead = x.shape[:-1]

    def heads(w):
        y = complex_matmul(x, w.reshape(c, -1)).reshape(*lead, h, -1)
        return jnp.concatenate([y.real, y.imag], axis=-1)  # [..., S, H, 2·width]

    q, k, v = heads(params.query), heads(params.key), heads(params.value)
    # Re(q k̄) = q_r k_r + q_i k_i: one real contraction over the stacked parts
    logits = jnp.einsum("...she,...the->...hst", q, k) * jnp.asarray(1.0 / math.sqrt(e), rdt)
    if mask is not None:
        if jnp.shape(mask) != lead:
            raise InputError(f"complex_attention: mask must have shape {lead} (x.shape[:-1]), got {jnp.shape(mask)}")
        m = jnp.asarray(mask).astype(rdt)[..., None, None, :]
        logits = logits + (m - 1) * jnp.asarray(_MASKED_LOGIT, rdt)
        attn = jax.nn.softmax(logits, axis=-1) * m
    else:
        attn = jax.nn.softmax(logits, axis=-1)
    o = jnp.einsum("...hst,...thf->...shf", attn, v)  # [..., S, H, 2F]
    o = jax.lax.complex(o[..., :f], o[..., f:]).reshape(*lead, h * f)
    return complex_matmul(o, params.out.reshape(h * f, -1))


# --------------------------------------------------------------------------- VN-Transformer block


class VNTransformerParams(NamedTuple):
    """Parameters of :func:`vn_transformer_block`.

    Attributes:
      attention_norm: ``[C]`` real gain of the layer norm before attention.
      attention: :class:`ComplexAttentionParams` with ``D = C``.
      mlp_norm: ``[C]`` real gain of the layer norm before the MLP.
      mlp_in: :class:`VNParams` ``C → F`` (dense form, ``weight`` set).
      mlp_out: :class:`VNParams` ``F → C`` (dense form).
    """

    attention_norm: Float[Array, " C"]
    attention: ComplexAttentionParams
    mlp_norm: Float[Array, " C"]
    mlp_in: VNParams
    mlp_out: VNParams


def init_vn_transformer_block(
    key: PRNGKey,
    features: int,
    *,
    num_heads: int,
    mlp_features: int | None = None,
    dtype=jnp.complex64,
) -> VNTransformerParams:
    """Random :class:`VNTransformerParams` (unit layer-norm gains, complex LeCun normal weights).

    Args:
      key: PRNG key.
      features: ``C`` (input = output width).
      num_heads: attention heads (``C`` must be divisible by it).
      mlp_features: hidden width ``F`` of the VN MLP; default ``C``.
      dtype: complex dtype of the weights (gains use the matching real dtype).

    Example:
      >>> init = lambda key: init_vn_transformer_block(key, 8, num_heads=2, mlp_features=16)
      >>> p = jax.eval_shape(init, jax.random.key(0))
      >>> p.mlp_in.weight.shape, p.mlp_out.weight.shape
      ((8, 16), (16, 8))
    """
    hidden = features if mlp_features is None else mlp_features
    shapes = jax.eval_shape(lambda k: init_complex_attention(k, features, num_heads=num_heads, dtype=dtype), key)
    c, h, e = shapes.query.shape  # (and the ConfigError checks of init_complex_attention)
    qkv, mlp_in, mlp_out = ((c, h, e), c), ((features, hidden), features), ((hidden, features), hidden)
    w = complex_lecun_blocks(key, [qkv, qkv, qkv, ((h, e, features), h * e), mlp_in, mlp_in, mlp_out, mlp_out], dtype=dtype)
    ones = jnp.ones((features,), real_dtype(dtype))
    return VNTransformerParams(
        attention_norm=ones,
        attention=ComplexAttentionParams(*w[:4]),
        mlp_norm=ones,
        mlp_in=VNParams(*w[4:6]),
        mlp_out=VNParams(*w[6:8]),
    )


def vn_transformer_block(
    x: Complex[Array, "... S C"],
    params: VNTransformerParams,
    *,
    mask: Bool[Array, "... S"] | None = None,
    delta: float = 1e-6,
) -> Complex[Array, "... S C"]:
    """Pre-norm VN-Transformer block: complex attention and a vector-neuron MLP, each with a residual.

    .. math:: u = x + \\mathrm{Attn}(\\mathrm{LN}_1(x)), \\qquad
       y = u + \\mathrm{VN}_{out}(\\mathrm{VN}_{in}(\\mathrm{LN}_2(u)))

    with :func:`complex_layer_norm` (magnitudes only), :func:`complex_attention` and two dense
    :func:`vn_nonlinearity` layers. Every piece commutes with a common rotation of the set and with
    permutations of it, and so does the block.

    Args:
      x: ``[..., S, C]`` complex set elements (one frame per leading index).
      params: :class:`VNTransformerParams`.
      mask: ``[..., S]`` True for valid elements; masked ones never influence valid outputs.
      delta: ``δ > 0`` of the layer norms and VN layers.

    Returns:
      ``[..., S, C]`` complex.

    Example:
      >>> p = jax.eval_shape(lambda key: init_vn_transformer_block(key, 4, num_heads=2), jax.random.key(0))
      >>> x = jnp.zeros((10, 3, 4), jnp.complex64)  # 10 vertices, a set of 3 per vertex, 4 channels
      >>> jax.eval_shape(vn_transformer_block, x, p).shape
      (10, 3, 4)
    """
    check_complex(x, "vn_transformer_block", ndim_min=2)
    u = x + complex_attention(complex_layer_norm(x, params.attention_norm, delta=delta), params.attention, mask=mask)
    hidden = vn_nonlinearity(complex_layer_norm(u, params.mlp_norm, delta=delta), params.mlp_in, delta=delta)
    return u + vn_nonlinearity(hidden, params.mlp_out, delta=delta)

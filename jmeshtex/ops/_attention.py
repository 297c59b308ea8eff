"""Multi-head self-attention over sets of complex tangent features (CVPR 2024 supplement §9).

Logits from ``Re(q·k̄)`` (rotation-invariant) and a complex-linear average of the values, so the
layer commutes with a common rotation of the set; no biases (they would break equivariance).
"""

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp

from .._errors import ConfigError, InputError
from .._types import Array, ArrayLike, Bool, Complex, PRNGKey
from ._complex_init import complex_lecun_blocks
from ._numerics import check_complex, complex_matmul, real_dtype


class ComplexAttentionParams(NamedTuple):
    """Parameters of :func:`complex_attention` (no biases: they would break equivariance).

    Attributes:
      query: ``[C, H, E]`` complex, input channels → heads × query/key width.
      key: ``[C, H, E]`` complex.
      value: ``[C, H, F]`` complex, input channels → heads × value width.
      out: ``[H, F, D]`` complex output projection.
      linear: ``[C, D]`` complex weight of a parallel linear path ``x W`` added to the attention's
        output (the reference's ``complex_mhattn``: ``MHA(x) + Dense(x)``), or None (none).
    """

    query: Complex[ArrayLike, "C H E"]
    key: Complex[ArrayLike, "C H E"]
    value: Complex[ArrayLike, "C H F"]
    out: Complex[ArrayLike, "H F D"]
    linear: Complex[ArrayLike, "C D"] | None = None


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
        *complex_lecun_blocks(
            key, [qkv, qkv, qkv, ((*hf, out_features), num_heads * head_features)], dtype=dtype
        )
    )


_MASKED_LOGIT = (
    1e30  # added (negated) to masked logits; exp(-1e30 - max) is exactly 0 in f32 and f64
)


def complex_attention(
    x: Complex[ArrayLike, "... S C"],
    params: ComplexAttentionParams,
    *,
    mask: Bool[ArrayLike, "... S"] | None = None,
) -> Complex[Array, "... S D"]:
    """Multi-head self-attention over a set of complex (tangent) features.

    With ``q = x W_q``, ``k = x W_k``, ``v = x W_v`` per head ``h`` (``E`` query/key channels):

    .. math:: a^h_{st} = \\operatorname{softmax}_t\\Big(\\frac{\\mathrm{Re}\\sum_e q^h_{se}\\,
       \\overline{k^h_{te}}}{\\sqrt E}\\Big), \\qquad
       y_s = \\sum_h \\Big(\\sum_t a^h_{st}\\, v^h_t\\Big) W_o^h \\; [+\\, x_s W_\\ell]

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
    if (
        params.query.ndim != 3
        or params.query.shape[0] != c
        or params.key.shape != params.query.shape
    ):
        raise InputError(
            f"complex_attention: query and key must both be [C, H, E] with C = {c}, got "
            f"{params.query.shape} and {params.key.shape}"
        )
    _, h, e = params.query.shape
    if params.value.ndim != 3 or params.value.shape[:2] != (c, h):
        raise InputError(
            f"complex_attention: value must be [C, H, F] = [{c}, {h}, F], got {params.value.shape}"
        )
    f = params.value.shape[2]
    if params.out.ndim != 3 or params.out.shape[:2] != (h, f):
        raise InputError(
            f"complex_attention: out must be [H, F, D] = [{h}, {f}, D], got {params.out.shape}"
        )
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
            raise InputError(
                f"complex_attention: mask must have shape {lead} (x.shape[:-1]), got {jnp.shape(mask)}"
            )
        m = jnp.asarray(mask).astype(rdt)[..., None, None, :]
        logits = logits + (m - 1) * jnp.asarray(_MASKED_LOGIT, rdt)
        attn = jax.nn.softmax(logits, axis=-1) * m
    else:
        attn = jax.nn.softmax(logits, axis=-1)
    o = jnp.einsum("...hst,...thf->...shf", attn, v)  # [..., S, H, 2F]
    o = jax.lax.complex(o[..., :f], o[..., f:]).reshape(*lead, h * f)
    y = complex_matmul(o, params.out.reshape(h * f, -1))
    if params.linear is not None:  # complex-linear per element: commutes with rotations too
        if jnp.shape(params.linear) != (c, y.shape[-1]):
            raise InputError(
                f"complex_attention: linear must be [C, D] = [{c}, {y.shape[-1]}], got "
                f"{jnp.shape(params.linear)}"
            )
        y = y + complex_matmul(x, params.linear)
    return y

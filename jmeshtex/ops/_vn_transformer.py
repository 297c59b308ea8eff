"""Pre-norm VN-Transformer block: complex attention and a vector-neuron MLP with residuals.

Stacks :func:`~jmeshtex.ops.complex_layer_norm`, :func:`~jmeshtex.ops.complex_attention` and two
:func:`~jmeshtex.ops.vn_nonlinearity` layers (CVPR 2024 supplement §9); every piece commutes with a
common rotation of the set and with its permutations.
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp

from .._errors import InputError
from .._types import Array, ArrayLike, Bool, Complex, Float, PRNGKey
from ._attention import ComplexAttentionParams, complex_attention, init_complex_attention
from ._complex_init import complex_lecun_blocks
from ._layer_norm import complex_layer_norm
from ._numerics import abs2, check_complex, real_dtype
from ._vector_neuron import VNParams, vn_nonlinearity


class VNTransformerParams(NamedTuple):
    """Parameters of :func:`vn_transformer_block`.

    Attributes:
      attention_norm: ``[C]`` real gain of the layer norm before attention.
      attention: :class:`ComplexAttentionParams` with ``D = C``.
      mlp_norm: ``[C]`` real gain of the layer norm before the MLP.
      mlp_in: :class:`VNParams` ``C → F`` (dense form, ``weight`` set).
      mlp_out: :class:`VNParams` ``F → C`` (dense form).
    """

    attention_norm: Float[ArrayLike, " C"]
    attention: ComplexAttentionParams
    mlp_norm: Float[ArrayLike, " C"]
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
    shapes = jax.eval_shape(
        lambda k: init_complex_attention(k, features, num_heads=num_heads, dtype=dtype), key
    )
    c, h, e = shapes.query.shape  # (and the ConfigError checks of init_complex_attention)
    qkv, mlp_in, mlp_out = (
        ((c, h, e), c),
        ((features, hidden), features),
        ((hidden, features), hidden),
    )
    w = complex_lecun_blocks(
        key,
        [qkv, qkv, qkv, ((h, e, features), h * e), mlp_in, mlp_in, mlp_out, mlp_out],
        dtype=dtype,
    )
    ones = jnp.ones((features,), real_dtype(dtype))
    return VNTransformerParams(
        attention_norm=ones,
        attention=ComplexAttentionParams(*w[:4]),
        mlp_norm=ones,
        mlp_in=VNParams(*w[4:6]),
        mlp_out=VNParams(*w[6:8]),
    )


def vn_transformer_block(
    x: Complex[ArrayLike, "... S C"],
    params: VNTransformerParams,
    *,
    mask: Bool[ArrayLike, "... S"] | None = None,
    delta: float = 1e-6,
    norm: str = "element",
) -> Complex[Array, "... S C"]:
    """Pre-norm VN-Transformer block: complex attention and a vector-neuron MLP, each with a residual.

    .. math:: u = x + \\mathrm{Attn}(\\mathrm{LN}_1(x)), \\qquad
       y = u + \\mathrm{VN}_{out}(\\mathrm{VN}_{in}(\\mathrm{LN}_2(u)))

    with :func:`complex_layer_norm` (magnitudes only), :func:`complex_attention` and two dense
    :func:`vn_nonlinearity` layers. Every piece commutes with a common rotation of the set and with
    permutations of it, and so does the block.

    ``norm="channel"`` replaces the layer norms by the reference's per-channel normalisation
    (``square_mag_norm_encoder`` in google-research ``mesh_diffusion/latents/ring_vae.py``):
    channel ``c`` is divided by the root mean of ``|x_c|²`` over every valid element of the whole
    batch (all leading indices and the set), ``LN(x)_c = γ_c x_c / sqrt(mean |x_c|² + δ)``. That
    mean is a batch statistic: each output then depends on the other sets of the call (still
    invariant to a rotation of any one set, whose magnitudes do not change).

    Args:
      x: ``[..., S, C]`` complex set elements (one frame per leading index).
      params: :class:`VNTransformerParams`.
      mask: ``[..., S]`` True for valid elements; masked ones never influence valid outputs.
      delta: ``δ > 0`` of the layer norms and VN layers.
      norm: ``"element"`` (each element over its channels; default) or ``"channel"`` (each
        channel over all valid elements of the batch).

    Returns:
      ``[..., S, C]`` complex.

    Example:
      >>> p = jax.eval_shape(lambda key: init_vn_transformer_block(key, 4, num_heads=2), jax.random.key(0))
      >>> x = jnp.zeros((10, 3, 4), jnp.complex64)  # 10 vertices, a set of 3 per vertex, 4 channels
      >>> jax.eval_shape(vn_transformer_block, x, p).shape
      (10, 3, 4)
    """
    check_complex(x, "vn_transformer_block", ndim_min=2)
    if norm not in ("element", "channel"):
        raise InputError(f"vn_transformer_block: norm must be 'element' or 'channel', got {norm!r}")

    def normalise(y, gain):
        if norm == "element":
            return complex_layer_norm(y, gain, delta=delta)
        return _channel_norm(y, gain, mask, delta)

    u = x + complex_attention(normalise(x, params.attention_norm), params.attention, mask=mask)
    hidden = vn_nonlinearity(normalise(u, params.mlp_norm), params.mlp_in, delta=delta)
    return u + vn_nonlinearity(hidden, params.mlp_out, delta=delta)


def _channel_norm(x, gain, mask, delta) -> Array:
    """``γ_c x_c / sqrt(mean |x_c|² + δ)``, the mean over every valid element of the batch."""
    rdt = real_dtype(x.dtype)
    w = (
        jnp.ones(x.shape[:-1], rdt)
        if mask is None
        else jnp.broadcast_to(jnp.asarray(mask), x.shape[:-1]).astype(rdt)
    )
    axes = tuple(range(x.ndim - 1))
    total = jnp.maximum(jnp.sum(w), jnp.asarray(1.0, rdt))
    mean = jnp.sum(abs2(x) * w[..., None], axis=axes) / total  # [C]
    factor = jnp.asarray(gain).astype(rdt) * jax.lax.rsqrt(mean + jnp.asarray(delta, rdt))
    return jax.lax.complex(x.real * factor, x.imag * factor)

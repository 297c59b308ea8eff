"""The parameters of :func:`~jmeshtex.ops.field_conv` and their random initialisation."""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp

from .._errors import ConfigError
from .._types import ArrayLike, Complex, Float, PRNGKey
from ._complex_init import complex_lecun_blocks
from ._numerics import real_dtype


class FieldConvParams(NamedTuple):
    """Parameters of :func:`field_conv`.

    Attributes:
      filter_weight: ``[2 + E, H]`` real; rows 0 and 1 act on ``Re a`` and ``Im a`` (the invariant
        filter argument), rows ``2..`` on the per-vertex embedding (``E = 0`` without one).
      filter_bias: ``[H]`` real.
      mix: ``[C, H, D]`` complex: the dense layer from the ``C·H`` filtered sums to ``D`` outputs.
      channel_weight: ``[H]`` real or None: the first filter layer's row for a *per-channel* scalar
        input ``e_{pc}`` (``channel_embedding`` of :func:`field_conv`; the reference's
        ``FieldConvEmb``, where each channel's filter sees its own embedding value).
      hidden_weight, hidden_bias: ``[H, H]`` and ``[H]`` real or None: a second hidden filter layer
        ``φ ← act(φ W₂ + b₂)`` (the reference's two-hidden-layer filters); None: one hidden layer.
    """

    filter_weight: Float[ArrayLike, "I H"]
    filter_bias: Float[ArrayLike, " H"]
    mix: Complex[ArrayLike, "C H D"]
    channel_weight: Float[ArrayLike, " H"] | None = None
    hidden_weight: Float[ArrayLike, "H H"] | None = None
    hidden_bias: Float[ArrayLike, " H"] | None = None


def init_field_conv(
    key: PRNGKey,
    in_features: int,
    out_features: int,
    *,
    hdim: int = 16,
    embedding_features: int = 0,
    channel_embedding: bool = False,
    hidden_layers: int = 1,
    dtype=jnp.complex64,
) -> FieldConvParams:
    """Random :class:`FieldConvParams`.

    The filter weights are real LeCun normal (``N(0, 1/(2 + E))``), the filter biases ``N(0, 1)``
    (so the ``H`` ridge functions have different offsets, and the self slot ``a = 0`` of a k-NN
    neighbourhood gets a non-zero response), the mix complex LeCun normal with ``fan_in = C·H``
    (:func:`~jmeshtex.ops.complex_lecun_normal`).

    Training: ``mix`` is complex, and for complex leaves ``jax.grad`` returns the conjugate of the
    steepest-ascent direction; put :func:`jmeshtex.optim.complex_steepest` first in the optax chain
    (``optax.chain(complex_steepest(), optax.adam(lr))``), or plain optax moves the imaginary parts
    uphill.

    Args:
      key: PRNG key.
      in_features: ``C``.
      out_features: ``D``.
      hdim: ``H``, filter responses per input channel.
      embedding_features: ``E``, width of the optional per-vertex embedding (0: none).
      channel_embedding: add ``channel_weight`` (``N(0, 1/(3 + E))``; the first layer's fan-in is
        then ``3 + E``) for a per-channel embedding.
      hidden_layers: 1 (default) or 2 hidden filter layers; the second has LeCun-normal
        ``hidden_weight`` (``N(0, 1/H)``) and zero ``hidden_bias``. The extra parameters are drawn
        from ``fold_in(key, 1)``, so the one-layer parameters are the same for every choice.
      dtype: complex dtype of ``mix``; the filter uses the matching real dtype.

    Example:
      >>> init = lambda key: init_field_conv(key, 4, 8, hdim=16, embedding_features=3)
      >>> p = jax.eval_shape(init, jax.random.key(0))
      >>> p.filter_weight.shape, p.filter_bias.shape, p.mix.shape
      ((5, 16), (16,), (4, 16, 8))
      >>> p2 = jax.eval_shape(lambda key: init_field_conv(key, 4, 8, hdim=16, hidden_layers=2,
      ...                     channel_embedding=True), jax.random.key(0))
      >>> p2.channel_weight.shape, p2.hidden_weight.shape
      ((16,), (16, 16))
    """
    if hidden_layers not in (1, 2):
        raise ConfigError(f"init_field_conv: hidden_layers must be 1 or 2, got {hidden_layers!r}")
    rdt = real_dtype(dtype)
    fan = 2 + embedding_features + int(bool(channel_embedding))
    mix, weight, bias = complex_lecun_blocks(
        key,
        [((in_features, hdim, out_features), in_features * hdim)],
        dtype=dtype,
        extra_real=[(2 + embedding_features, hdim), (hdim,)],
    )
    inv = jnp.asarray(1.0 / math.sqrt(fan), rdt)
    extra = {}
    if channel_embedding or hidden_layers == 2:
        draw = jax.random.normal(jax.random.fold_in(key, 1), (hdim * (1 + hdim),), rdt)
        if channel_embedding:
            extra["channel_weight"] = draw[:hdim] * inv
        if hidden_layers == 2:
            extra["hidden_weight"] = draw[hdim:].reshape(hdim, hdim) / jnp.asarray(
                math.sqrt(hdim), rdt
            )
            extra["hidden_bias"] = jnp.zeros((hdim,), rdt)
    return FieldConvParams(filter_weight=weight * inv, filter_bias=bias, mix=mix, **extra)

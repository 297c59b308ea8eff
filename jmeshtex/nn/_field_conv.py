"""Flax modules for field convolutions: thin wrappers around :func:`jmeshtex.ops.field_conv`.

Parameters are the fields of :class:`jmeshtex.ops.FieldConvParams` (``filter_weight``,
``filter_bias``, ``mix``, and the optional ``channel_weight``, ``hidden_weight``, ``hidden_bias``),
drawn by :func:`jmeshtex.ops.init_field_conv`; see
:mod:`jmeshtex.nn._complex` for the complex initialisation and the optax gradient convention.
"""

from __future__ import annotations

from typing import Any

import flax.linen as nn
import jax.numpy as jnp

from ..ops import field_conv, init_field_conv, real_dtype
from ._complex import pytree_params


class FieldConv(nn.Module):
    """Field convolution, :func:`jmeshtex.ops.field_conv` (2021; 2024 eq. 34), as a flax module.

    .. math:: y_{pd} = \\sum_{c,h} M_{chd} \\sum_{q \\in N(p)} \\hat w_{pq}\\, \\rho_{q\\to p}\\,
       x_{qc}\\; \\varphi_h\\big(\\log_p(q)\\,\\overline{\\hat u_{pqc}},\\, e_{pc}\\big)

    The one implementation of the layer: :class:`FieldConvEmb` and the FLDM denoiser's blocks
    (:mod:`jmeshtex.fldm`) all use it or the op it wraps. The filter ``φ`` is an
    MLP with ``filter_layers`` hidden layers of width ``H``; with ``channel_embedding=True`` each
    input channel ``c``'s filter also sees its own real scalar ``e_{pc}`` (the reference's
    ``FieldConvEmb``: the timestep/label embedding processed to one value per channel), passed as
    the call's third argument ``[V, C]``.

    The module's parameters are the non-None fields of :class:`jmeshtex.ops.FieldConvParams`
    under their field names (``filter_weight [2, H]``, ``filter_bias [H]``, ``mix [C, H, D]``, and
    ``channel_weight [H]``, ``hidden_weight [H, H]``, ``hidden_bias [H]`` when used), drawn by
    :func:`jmeshtex.ops.init_field_conv`; ``FieldConvParams(**variables["params"])`` exports them
    for the op.

    Attributes:
      features: output channels ``D``.
      hdim: filter responses per input channel ``H``.
      delta: ``δ`` of the smoothed feature direction.
      activation: filter nonlinearity, ``"silu"`` or ``"relu"``.
      filter_layers: hidden layers of the filter MLP, 1 (default) or 2 (the reference's).
      channel_embedding: the filters take a per-channel embedding ``[V, C]`` (third call argument).
      argument: the filter argument, ``"transported"`` (gauge-invariant, default) or
        ``"untransported"`` (the reference code's form, a negative control).
      param_dtype: complex dtype of the mix (the filter uses the matching real dtype).

    Call: ``(x [V, C] complex, nbhd, channel_embedding [V, C] real or None) -> [V, D]``, every vector
    in its own vertex's frame.

    Example:
      >>> import jax, numpy as np
      >>> from jmeshtex.geometry import VertexNeighborhood
      >>> from jmeshtex.ops import FieldConvParams, field_conv
      >>> nb = VertexNeighborhood(np.array([[0, 1], [1, 0]]), np.ones((2, 2), bool),
      ...     np.array([[0, 1], [0, -1]], complex), np.ones((2, 2), complex), np.ones((2, 2)),
      ...     np.ones(2), np.ones(2, bool))
      >>> x = jnp.ones((2, 3), jnp.complex64)
      >>> m = FieldConv(4, hdim=8)
      >>> v = jax.eval_shape(m.init, jax.random.key(0), x, nb)  # shapes only; m.init for values
      >>> jax.eval_shape(m.apply, v, x, nb).shape, v["params"]["mix"].shape
      ((2, 4), (3, 8, 4))
      >>> m2 = FieldConv(4, hdim=8, filter_layers=2, channel_embedding=True)
      >>> e = jnp.ones((2, 3), jnp.float32)
      >>> v2 = m2.init(jax.random.key(0), x, nb, e)
      >>> sorted(v2["params"]), v2["params"]["hidden_weight"].shape
      (['channel_weight', 'filter_bias', 'filter_weight', 'hidden_bias', 'hidden_weight', 'mix'], (8, 8))
      >>> p = FieldConvParams(**v2["params"])
      >>> bool(jnp.allclose(m2.apply(v2, x, nb, e), field_conv(x, nb, p, channel_embedding=e)))
      True
    """

    features: int
    hdim: int = 16
    delta: float = 1e-4
    activation: str = "silu"
    filter_layers: int = 1
    channel_embedding: bool = False
    argument: str = "transported"
    param_dtype: Any = jnp.complex64

    @nn.compact
    def __call__(self, x, nbhd, channel_embedding=None):
        params = _params(
            self, x, channel_embedding=self.channel_embedding, hidden_layers=self.filter_layers
        )
        return field_conv(
            x,
            nbhd,
            params,
            channel_embedding=channel_embedding,
            delta=self.delta,
            activation=self.activation,
            argument=self.argument,
        )


class FieldConvEmb(nn.Module):
    """Field convolution with a scalar embedding appended to the filter input (2024 eq. 35).

    Attributes:
      features: output channels ``D``.
      hdim: filter responses per input channel ``H``.
      delta: ``δ`` of the smoothed feature direction.
      activation: filter nonlinearity, ``"silu"`` or ``"relu"``.
      param_dtype: complex dtype of the mix.

    Call with ``embedding`` of shape ``[V, E]`` (per vertex, e.g. labels) or ``[E]`` (global, e.g. a
    timestep embedding; broadcast to every vertex).

    Example:
      >>> import jax, numpy as np
      >>> from jmeshtex.geometry import VertexNeighborhood
      >>> nb = VertexNeighborhood(np.array([[0, 1], [1, 0]]), np.ones((2, 2), bool),
      ...     np.array([[0, 1], [0, -1]], complex), np.ones((2, 2), complex), np.ones((2, 2)),
      ...     np.ones(2), np.ones(2, bool))
      >>> x, t = jnp.ones((2, 3), jnp.complex64), jnp.array([0.1, 0.2, 0.3, 0.4])
      >>> m = FieldConvEmb(4)
      >>> v = jax.eval_shape(m.init, jax.random.key(0), x, nb, t)  # shapes only; m.init for values
      >>> jax.eval_shape(m.apply, v, x, nb, t).shape, v["params"]["filter_weight"].shape
      ((2, 4), (6, 16))
    """

    features: int
    hdim: int = 16
    delta: float = 1e-4
    activation: str = "silu"
    param_dtype: Any = jnp.complex64

    @nn.compact
    def __call__(self, x, nbhd, embedding):
        embedding = _per_vertex(embedding, x)
        params = _params(self, x, embedding_features=embedding.shape[-1])
        return field_conv(
            x, nbhd, params, embedding=embedding, delta=self.delta, activation=self.activation
        )


def _per_vertex(embedding, x):
    emb = jnp.asarray(embedding).astype(real_dtype(x.dtype))
    if emb.ndim == 1:
        emb = jnp.broadcast_to(emb, (x.shape[0], emb.shape[0]))
    return emb


def _params(module: nn.Module, x, **options):
    """A field-convolution module's :class:`~jmeshtex.ops.FieldConvParams` from ``x``'s channels to
    ``module.features``, drawn by :func:`jmeshtex.ops.init_field_conv` with ``options``."""
    return pytree_params(
        module,
        lambda key: init_field_conv(
            key,
            x.shape[-1],
            module.features,
            hdim=module.hdim,
            dtype=module.param_dtype,
            **options,
        ),
    )

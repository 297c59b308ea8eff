"""Flax modules for complex tangent-feature layers: thin wrappers that create parameters and call
:mod:`jmeshtex.ops`.

Each module's parameters are exactly the fields of the matching ops NamedTuple (nested names joined
with ``_``, e.g. ``attention_query``), drawn by the matching ``jmeshtex.ops.init_*`` function, so a
module's variables convert to the plain pytree the op takes (and back) without flax. Complex
weights are complex LeCun normal (:func:`jmeshtex.ops.complex_lecun_normal`: circular Gaussian with
``E|w|² = 1/fan_in``); gains are 1.

Training complex parameters with optax: for a real loss, ``jax.grad`` returns the *conjugate* of the
steepest-ascent direction for complex leaves (``∂L/∂a − i ∂L/∂b`` for ``w = a + ib``), and optax
treats complex leaves as plain numbers. Conjugate the gradients before the update::

    grads = jmeshtex.ops.conjugate_complex_grads(jax.grad(loss)(params))
    updates, opt_state = optimizer.update(grads, opt_state, params)

Without it, the imaginary parts move uphill.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp

from ..ops import (
    complex_attention,
    complex_linear,
    filter_response_norm,
    init_complex_attention,
    init_complex_linear,
    init_frn,
    init_vn,
    init_vn_transformer_block,
    vn_nonlinearity,
    vn_transformer_block,
)


def pytree_params(module: nn.Module, init: Callable[[jax.Array], Any]) -> Any:
    """Create one flax parameter per array leaf of ``init(key)`` and return the same pytree.

    Leaves are named by their path in the pytree (NamedTuple fields joined with ``_``); ``None``
    fields stay ``None``. ``init`` runs once, at initialisation, with the module's ``"params"`` RNG;
    at apply time the stored values are returned.

    Args:
      module: the calling module (inside its ``@nn.compact`` ``__call__``).
      init: ``key -> params`` (a NamedTuple of arrays, e.g. a ``jmeshtex.ops.init_*`` partial).

    Returns:
      The params pytree, its leaves being the module's parameters.
    """
    template = jax.eval_shape(init, jax.random.key(0))
    paths, treedef = jax.tree_util.tree_flatten_with_path(template)
    values = [None] * len(paths)
    if module.is_initializing():
        values = jax.tree_util.tree_leaves(init(module.make_rng("params")))
    leaves = []
    for (path, _), value in zip(paths, values, strict=False):
        name = "_".join(str(getattr(p, "name", getattr(p, "idx", p))) for p in path)
        leaves.append(module.param(name, lambda _key, value=value: value))
    return jax.tree_util.tree_unflatten(treedef, leaves)


class ComplexDense(nn.Module):
    """Complex linear layer without bias, :func:`jmeshtex.ops.complex_linear`.

    Attributes:
      features: output channels ``D``.
      param_dtype: complex dtype of the kernel (cast to the input's dtype at call time).

    Example:
      >>> x = jnp.ones((5, 3), jnp.complex64)
      >>> variables = ComplexDense(4).init(jax.random.key(0), x)
      >>> variables["params"]["kernel"].shape, ComplexDense(4).apply(variables, x).shape
      ((3, 4), (5, 4))
    """

    features: int
    param_dtype: Any = jnp.complex64

    @nn.compact
    def __call__(self, x):
        kernel = self.param(
            "kernel",
            lambda key: init_complex_linear(
                key, x.shape[-1], self.features, dtype=self.param_dtype
            ),
        )
        return complex_linear(x, kernel)


class VNNonlinearity(nn.Module):
    """Vector-neuron nonlinearity, :func:`jmeshtex.ops.vn_nonlinearity` (2024 supplement eq. 19).

    Attributes:
      features: output channels; ``None`` (default) gives the residual form ``q = x`` (only a
        ``direction`` parameter, ``D = C``), an int the dense form with ``weight`` and ``direction``.
      delta: ``δ > 0``.
      param_dtype: complex dtype of the weights.

    Example:
      >>> x = jnp.ones((5, 3), jnp.complex64)
      >>> sorted(VNNonlinearity().init(jax.random.key(0), x)["params"])
      ['direction']
    """

    features: int | None = None
    delta: float = 1e-6
    param_dtype: Any = jnp.complex64

    @nn.compact
    def __call__(self, x):
        params = pytree_params(
            self, lambda key: init_vn(key, x.shape[-1], self.features, dtype=self.param_dtype)
        )
        return vn_nonlinearity(x, params, delta=self.delta)


class FRN(nn.Module):
    """Filter response normalisation over the mesh, :func:`jmeshtex.ops.filter_response_norm` (eq. 20).

    Parameters: ``scale`` (real gain, init 1) and ``eps`` (learned stabiliser, init ``eps_init``).

    Attributes:
      delta: fixed ``δ > 0``.
      eps_init: initial value of the learned ``ε``.
      param_dtype: real dtype of the parameters.

    Example:
      >>> x = jnp.ones((5, 3), jnp.complex64)
      >>> v = FRN().init(jax.random.key(0), x, area=jnp.ones(5))
      >>> FRN().apply(v, x, area=jnp.ones(5)).shape
      (5, 3)
    """

    delta: float = 1e-6
    eps_init: float = 1e-3
    param_dtype: Any = jnp.float32

    @nn.compact
    def __call__(self, x, *, area, vertex_mask=None):
        params = pytree_params(
            self, lambda key: init_frn(x.shape[-1], dtype=self.param_dtype, eps=self.eps_init)
        )
        return filter_response_norm(x, params, area=area, vertex_mask=vertex_mask, delta=self.delta)


class ComplexAttention(nn.Module):
    """Multi-head self-attention over a set of complex features, :func:`jmeshtex.ops.complex_attention`.

    Attributes:
      num_heads: ``H``.
      head_features: query/key/value width per head; default ``C // H``.
      out_features: ``D``; default ``C``.
      param_dtype: complex dtype of the weights.

    Example:
      >>> x = jnp.ones((2, 6, 4), jnp.complex64)
      >>> m = ComplexAttention(num_heads=2)
      >>> variables = jax.eval_shape(m.init, jax.random.key(0), x)  # shapes only; m.init for values
      >>> variables["params"]["query"].shape, jax.eval_shape(m.apply, variables, x).shape
      ((4, 2, 2), (2, 6, 4))
    """

    num_heads: int
    head_features: int | None = None
    out_features: int | None = None
    param_dtype: Any = jnp.complex64

    @nn.compact
    def __call__(self, x, *, mask=None):
        def init(key):
            return init_complex_attention(
                key,
                x.shape[-1],
                num_heads=self.num_heads,
                head_features=self.head_features,
                out_features=self.out_features,
                dtype=self.param_dtype,
            )

        return complex_attention(x, pytree_params(self, init), mask=mask)


class VNTransformerBlock(nn.Module):
    """Pre-norm VN-Transformer block, :func:`jmeshtex.ops.vn_transformer_block`.

    Attributes:
      num_heads: attention heads (``C`` divisible by it).
      mlp_features: hidden width of the VN MLP; default ``C``.
      delta: ``δ > 0`` of the layer norms and VN layers.
      param_dtype: complex dtype of the weights.

    Example:
      >>> x = jnp.ones((2, 6, 4), jnp.complex64)
      >>> m = VNTransformerBlock(num_heads=2)
      >>> v = jax.eval_shape(m.init, jax.random.key(0), x)  # shapes only; m.init for values
      >>> jax.eval_shape(m.apply, v, x).shape, sorted(v["params"])[:3]
      ((2, 6, 4), ['attention_key', 'attention_norm', 'attention_out'])
    """

    num_heads: int
    mlp_features: int | None = None
    delta: float = 1e-6
    param_dtype: Any = jnp.complex64

    @nn.compact
    def __call__(self, x, *, mask=None):
        def init(key):
            return init_vn_transformer_block(
                key,
                x.shape[-1],
                num_heads=self.num_heads,
                mlp_features=self.mlp_features,
                dtype=self.param_dtype,
            )

        return vn_transformer_block(x, pytree_params(self, init), mask=mask, delta=self.delta)

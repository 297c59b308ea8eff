"""Run a gradient transformation on the parameters concatenated into one vector per dtype."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import optax


class FlatState(NamedTuple):
    """The state of :func:`flat`: the inner transformation's state over the flat vectors."""

    inner: optax.OptState


def _flatten(tree) -> dict[str, jax.Array]:
    """The leaves of ``tree`` raveled and concatenated, one vector per dtype (keyed by its name)."""
    groups: dict[str, list] = {}
    for leaf in jax.tree.leaves(tree):
        groups.setdefault(jnp.dtype(leaf.dtype).name, []).append(jnp.ravel(leaf))
    return {k: jnp.concatenate(v) if len(v) > 1 else v[0] for k, v in groups.items()}


def _unflatten(flat: dict[str, jax.Array], like):
    """The inverse of :func:`_flatten`: ``flat``'s vectors cut into leaves shaped as ``like``'s."""
    leaves, treedef = jax.tree.flatten(like)
    offsets = dict.fromkeys(flat, 0)
    out = []
    for leaf in leaves:
        name = jnp.dtype(leaf.dtype).name
        start, size = offsets[name], leaf.size
        out.append(flat[name][start : start + size].reshape(leaf.shape))
        offsets[name] = start + size
    return jax.tree.unflatten(treedef, out)


def flat(inner: optax.GradientTransformation) -> optax.GradientTransformation:
    """``inner`` applied to the parameters and updates concatenated into one vector per dtype.

    An elementwise transformation (``optax.adam``, ``sgd``, ``clip_by_global_norm``, schedules) gives
    the same updates as on the tree (the global norm up to the order of its sum), with one set of
    operations per dtype instead of one per leaf: a network of many small leaves compiles its
    training step in markedly less time (FLDM's tiny denoiser, 67 leaves: 9,538 → 6,579 StableHLO
    lines, a third less compile time, as little as with plain SGD) and dispatches fewer kernels.
    Unlike ``optax.flatten``, leaves of different dtypes (complex weights beside real ones) are
    never promoted to a common one. The state holds the flat vectors' moments, so it is not
    interchangeable with ``inner``'s state over the tree.

    Args:
      inner: the transformation to run on the flat vectors; it sees a ``dict`` of one vector per
        dtype name (``"complex64"``, ``"float32"``, ...).

    Returns:
      An ``optax.GradientTransformation`` over the original tree.

    Example:
      >>> import jax, jax.numpy as jnp, optax
      >>> params = {"w": jnp.ones((2, 2), jnp.float32), "b": jnp.zeros(3, jnp.float64)}
      >>> grads = {"w": jnp.full((2, 2), 0.5, jnp.float32), "b": jnp.ones(3, jnp.float64)}
      >>> opt, ref = flat(optax.adam(0.1)), optax.adam(0.1)
      >>> with jax.numpy_dtype_promotion("standard"):  # optax mixes Python floats and int32 steps
      ...     u, _ = opt.update(grads, opt.init(params), params)
      ...     r, _ = ref.update(grads, ref.init(params), params)
      >>> all(bool(jnp.allclose(u[k], r[k])) for k in params)
      True
    """

    def init_fn(params):
        return FlatState(inner.init(_flatten(params)))

    def update_fn(updates, state, params=None):
        flat_params = None if params is None else _flatten(params)
        flat_updates, inner_state = inner.update(_flatten(updates), state.inner, flat_params)
        return _unflatten(flat_updates, updates), FlatState(inner_state)

    return optax.GradientTransformation(init_fn, update_fn)

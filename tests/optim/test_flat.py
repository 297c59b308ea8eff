"""flat: the trainers' optimisers on one vector per dtype give the tree optimiser's updates, keep
each leaf's dtype and shape, and compile to a smaller program."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import optax

from jmeshtex.optim import complex_steepest, flat


def _tree(rng, scale=1.0):
    """Leaves of three dtypes and assorted shapes, a scalar and an empty one among them."""
    c = lambda *s: (rng.normal(size=s) + 1j * rng.normal(size=s)).astype(np.complex64) * scale  # noqa: E731
    return {
        "conv": {"w": c(3, 4), "b": c(4)},
        "dense": [jnp.asarray(rng.normal(size=(5, 2)) * scale, jnp.float32), jnp.float32(scale)],
        "table": jnp.asarray(rng.normal(size=(2, 3)) * scale, jnp.float64),
        "empty": jnp.zeros((0, 3), jnp.float32),
    }


def _chain():
    return optax.chain(complex_steepest(), optax.clip_by_global_norm(0.5), optax.adam(1e-2))


def test_flat_updates_equal_the_tree_optimisers_over_several_steps():
    rng = np.random.default_rng(0)
    params = _tree(rng)
    tree_opt, flat_opt = _chain(), flat(_chain())
    p_tree, s_tree = params, tree_opt.init(params)
    p_flat, s_flat = params, flat_opt.init(params)
    for step in range(4):
        grads = _tree(np.random.default_rng(step + 1), scale=3.0)  # global norm > 0.5: clipped
        with jax.numpy_dtype_promotion("standard"):  # as the trainers: optax mixes weak dtypes
            u_tree, s_tree = tree_opt.update(grads, s_tree, p_tree)
            u_flat, s_flat = flat_opt.update(grads, s_flat, p_flat)
        p_tree = optax.apply_updates(p_tree, u_tree)
        p_flat = optax.apply_updates(p_flat, u_flat)
    for a, b in zip(jax.tree.leaves(p_tree), jax.tree.leaves(p_flat), strict=True):
        assert a.dtype == b.dtype and a.shape == b.shape
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=2e-6, atol=1e-7)
    moved = [
        not np.allclose(a, b)
        for a, b in zip(jax.tree.leaves(params), jax.tree.leaves(p_flat), strict=True)
    ]
    assert sum(moved) == 5  # every non-empty leaf moved


def test_flat_state_is_one_vector_per_dtype_and_the_step_compiles_smaller():
    rng = np.random.default_rng(0)
    params = {f"layer{i}": _tree(rng) for i in range(12)}
    adam = flat(optax.adam(1e-3))
    state = adam.init(params)
    mu = state.inner[0].mu
    assert sorted(mu) == ["complex64", "float32", "float64"]
    assert mu["complex64"].shape == (12 * 16,) and mu["float32"].shape == (12 * 11,)

    def step(opt):
        def run(p, s, g):
            with jax.numpy_dtype_promotion("standard"):
                u, s = opt.update(g, s, p)
            return optax.apply_updates(p, u), s

        return run

    def ops(opt):
        text = jax.jit(step(opt)).lower(params, opt.init(params), params).as_text()
        return text.count(" = ")

    assert ops(adam) < ops(optax.adam(1e-3)) / 2

"""complex_steepest: plain optax goes uphill on complex parameters, the chained one descends, and it
equals the explicit ``conjugate_complex_grads`` path."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from jmeshtex import VertexNeighborhood, to_jax
from jmeshtex.ops import (
    conjugate_complex_grads,
    field_conv,
    init_field_conv,
    init_vn,
    vn_nonlinearity,
)
from jmeshtex.optim import complex_steepest

V, K, C, D = 12, 4, 2, 3
STEPS = 15


def _problem(seed=0):
    """A fixed teacher problem: a field convolution then a vector-neuron layer, fit to the output of
    the same network whose complex weights are shifted along the imaginary axis (the direction plain
    optax gets backwards); the real filter weights start at the teacher's."""
    rng = np.random.default_rng(seed)
    index = rng.integers(0, V, (V, K))
    index[:, 0] = np.arange(V)
    log = rng.uniform(0.2, 1.0, (V, K)) * np.exp(1j * rng.uniform(-np.pi, np.pi, (V, K)))
    log[:, 0] = 0
    transport = np.exp(1j * rng.uniform(-np.pi, np.pi, (V, K)))
    transport[:, 0] = 1
    nbhd = to_jax(
        VertexNeighborhood(
            index=index.astype(np.int32),
            mask=np.ones((V, K), bool),
            log=log,
            transport=transport,
            weight=np.full((V, K), 1.0 / K),
            area=np.ones(V),
            vertex_mask=np.ones(V, bool),
        )
    )
    x = jnp.asarray(rng.standard_normal((V, C)) + 1j * rng.standard_normal((V, C)), jnp.complex64)
    k1, k2 = jax.random.split(jax.random.key(seed))
    params = (init_field_conv(k1, C, D, hdim=4), init_vn(k2, D, C))

    def model(p):
        return vn_nonlinearity(field_conv(x, nbhd, p[0]), p[1])

    def shift(w):
        if not jnp.iscomplexobj(w):
            return w
        return w + jnp.asarray(0.5j * rng.standard_normal(w.shape), w.dtype)

    target = model(jax.tree.map(shift, params))

    def loss(p):
        return jnp.mean(jnp.abs(model(p) - target) ** 2)

    return params, jax.jit(loss)


def _train(params, loss, optimizer, *, conjugate=False):
    state = optimizer.init(params)
    grad = jax.jit(jax.grad(loss))
    for _ in range(STEPS):
        g = grad(params)
        if conjugate:
            g = conjugate_complex_grads(g)
        # optax's adam mixes complex moments with real norms: fine under JAX's default promotion,
        # refused by the suite's strict mode (the methods' steps also switch to "standard" here)
        with jax.numpy_dtype_promotion("standard"):
            updates, state = optimizer.update(g, state, params)
            params = optax.apply_updates(params, updates)
    return params


@pytest.mark.parametrize("seed", [0, 1])
def test_plain_adam_rises_and_the_chained_one_falls(seed):
    params, loss = _problem(seed)
    start = float(loss(params))
    plain = float(loss(_train(params, loss, optax.adam(0.05))))
    chained = float(loss(_train(params, loss, optax.chain(complex_steepest(), optax.adam(0.05)))))
    assert plain > start, (start, plain)  # the imaginary parts move uphill
    assert chained < 0.5 * start, (start, chained)


def test_equals_the_explicit_conjugation():
    params, loss = _problem()
    a = _train(params, loss, optax.chain(complex_steepest(), optax.adam(0.05)))
    b = _train(params, loss, optax.adam(0.05), conjugate=True)
    for u, w in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(u), np.asarray(w))


def test_real_and_none_leaves_pass_through_and_state_is_empty():
    tree = {"w": jnp.array([1 + 2j]), "b": jnp.array([3.0]), "n": None}
    t = complex_steepest()
    state = t.init(tree)
    out, state2 = t.update(tree, state)
    assert out["n"] is None and state2 == state
    np.testing.assert_array_equal(out["w"], jnp.array([1 - 2j]))
    np.testing.assert_array_equal(out["b"], jnp.array([3.0]))
    assert out["w"].dtype == tree["w"].dtype


@pytest.mark.parametrize("dtype", [jnp.complex64, jnp.complex128])
def test_under_jit_keeps_dtype(dtype):
    g = jnp.array([1 + 2j, -3j], dtype)
    out, _ = jax.jit(complex_steepest().update)(g, optax.EmptyState())
    assert out.dtype == dtype
    np.testing.assert_array_equal(out, jnp.conj(g))

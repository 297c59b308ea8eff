"""Forward-mode autodiff through field_conv's default (fast) path: jvp, jacfwd and forward-over-
reverse run the same formula on the general path; reverse mode keeps the hand-written VJP."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jmeshtex import VertexNeighborhood, to_jax
from jmeshtex.ops import _field_conv, field_conv, init_field_conv

V, K, C, D, H = 5, 3, 2, 3, 4


def _setup(seed=0):
    """A tiny k-NN-like neighbourhood (self slot, one padded slot), float64 / complex128."""
    rng = np.random.default_rng(seed)
    index = rng.integers(0, V, (V, K))
    index[:, 0] = np.arange(V)
    mask = np.ones((V, K), bool)
    mask[1, 2] = False
    log = rng.uniform(0.2, 1.0, (V, K)) * np.exp(1j * rng.uniform(-np.pi, np.pi, (V, K)))
    log[:, 0] = 0
    transport = np.exp(1j * rng.uniform(-np.pi, np.pi, (V, K)))
    transport[:, 0] = 1
    log[~mask], transport[~mask], index[~mask] = 0, 1, 0
    nbhd = to_jax(
        VertexNeighborhood(
            index=index.astype(np.int32),
            mask=mask,
            log=log,
            transport=transport,
            weight=np.where(mask, rng.uniform(0.5, 1.5, (V, K)), 0.0),
            area=np.ones(V),
            vertex_mask=np.ones(V, bool),
        )
    )
    x = jnp.asarray(rng.standard_normal((V, C)) + 1j * rng.standard_normal((V, C)))
    params = init_field_conv(jax.random.key(seed), C, D, hdim=H, dtype=jnp.complex128)
    return x, nbhd, params


@pytest.mark.parametrize("activation", ["silu", "relu"])
def test_check_grads_forward_and_reverse_to_second_order(activation):
    x, nbhd, params = _setup()

    def f(x, params):
        return field_conv(x, nbhd, params, activation=activation)

    check_grads(f, (x, params), order=2, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6)


def test_check_grads_with_a_channel_embedding():
    x, nbhd, _ = _setup()
    params = init_field_conv(
        jax.random.key(1), C, D, hdim=H, channel_embedding=True, dtype=jnp.complex128
    )
    emb = jnp.asarray(np.random.default_rng(2).standard_normal((V, C)))

    def f(x, params, emb):
        return field_conv(x, nbhd, params, channel_embedding=emb)

    check_grads(f, (x, params, emb), order=2, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6)


def test_jacfwd_equals_jacrev_under_jit():
    x, nbhd, params = _setup()

    def f(xr):  # a real function of a real input: jacfwd and jacrev both apply
        y = field_conv(jax.lax.complex(xr[:, :C], xr[:, C:]), nbhd, params)
        return jnp.concatenate([y.real, y.imag], axis=1)

    xr = jnp.concatenate([x.real, x.imag], axis=1)
    fwd = jax.jit(jax.jacfwd(f))(xr)
    rev = jax.jit(jax.jacrev(f))(xr)
    np.testing.assert_allclose(fwd, rev, rtol=1e-10, atol=1e-12)
    assert np.abs(fwd).max() > 0


def test_jvp_values_equal_the_fast_path():
    x, nbhd, params = _setup()

    def f(x):
        return field_conv(x, nbhd, params)

    y, _ = jax.jit(lambda x, t: jax.jvp(f, (x,), (t,)))(x, x)
    np.testing.assert_allclose(y, jax.jit(f)(x), rtol=1e-12, atol=1e-14)


def test_reverse_mode_still_runs_the_hand_written_vjp(monkeypatch):
    x, nbhd, params = _setup()
    calls = []
    fast = _field_conv._blocks_vjp_fast

    def counted(*args, **kwargs):
        calls.append(1)
        return fast(*args, **kwargs)

    monkeypatch.setattr(_field_conv, "_blocks_vjp_fast", counted)

    def loss(x):
        return jnp.sum(jnp.abs(field_conv(x, nbhd, params)) ** 2)

    jax.grad(loss)(x)
    assert calls, "jax.grad no longer runs the hand-written VJP"
    calls.clear()
    jax.jvp(loss, (x,), (x,))
    assert not calls

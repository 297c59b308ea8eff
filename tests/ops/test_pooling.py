"""Tangent pooling / unpooling: hand case, loop references, gauge equivariance on synthetic maps,
padding, batching, jit, dtypes, zero features and gradients."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jmeshtex import InputError
from jmeshtex.geometry import PoolingMap, pad_to
from jmeshtex.ops import tangent_pool, tangent_unpool
from tests._random_fields import crandn, rel_err

_pool, _unpool = jax.jit(tangent_pool), jax.jit(tangent_unpool)
VF, VC, C = 9, 4, 3


def random_map(rng, vf=VF, vc=VC):
    """A synthetic fine → coarse map: every coarse vertex has at least one child."""
    parent = np.concatenate([rng.permutation(vc), rng.integers(0, vc, vf - vc)])
    rng.shuffle(parent)
    to_parent = np.exp(1j * rng.uniform(-np.pi, np.pi, vf))
    area = rng.uniform(0.5, 2.0, vf)
    kids = [np.flatnonzero(parent == p) for p in range(vc)]
    m = max(len(k) for k in kids)
    children = np.zeros((vc, m), np.int32)
    mask = np.zeros((vc, m), bool)
    for p, k in enumerate(kids):  # host set-up of a tiny test map
        children[p, : len(k)], mask[p, : len(k)] = k, True
    return PoolingMap(
        parent=parent.astype(np.int32),
        to_parent=to_parent,
        children=children,
        children_mask=mask,
        children_weight=np.where(mask, area[children], 0.0),
        children_transport=np.where(mask, to_parent[children], 1),
    )


def ref_pool(x, pm):
    y = np.zeros((len(pm.children), x.shape[1]), complex)
    for p in range(len(pm.children)):
        tot = sum(
            pm.children_weight[p, j] for j in range(pm.children.shape[1]) if pm.children_mask[p, j]
        )
        for j in range(pm.children.shape[1]):
            if pm.children_mask[p, j]:
                y[p] += (
                    pm.children_weight[p, j]
                    / tot
                    * pm.children_transport[p, j]
                    * x[pm.children[p, j]]
                )
    return y


def ref_unpool(x, pm):
    return np.array([np.conj(pm.to_parent[f]) * x[pm.parent[f]] for f in range(len(pm.parent))])


def gauge(pm, beta, alpha):
    """Fine frames turned by beta, coarse frames by alpha."""
    tp = pm.to_parent * np.exp(1j * (beta - alpha[pm.parent]))
    ct = np.where(
        pm.children_mask,
        pm.children_transport * np.exp(1j * (beta[pm.children] - alpha[:, None])),
        1,
    )
    return pm._replace(to_parent=tp, children_transport=ct)


def test_hand_case():
    pm = PoolingMap(
        parent=np.array([0, 0, 1]),
        to_parent=np.array([1, 1j, -1]),
        children=np.array([[0, 1], [2, 0]]),
        children_mask=np.array([[True, True], [True, False]]),
        children_weight=np.array([[1.0, 3.0], [2.0, 0.0]]),
        children_transport=np.array([[1, 1j], [-1, 1]]),
    )
    x = jnp.array([[2 + 0j], [-1j], [1 + 1j]])
    np.testing.assert_allclose(_pool(x, pm), [[(2 + 3) / 4], [-1 - 1j]], rtol=1e-15)
    np.testing.assert_allclose(
        _unpool(jnp.array([[1j], [2.0 + 0j]]), pm), [[1j], [1], [-2]], rtol=1e-15
    )


def test_matches_loop_reference(rng):
    pm = random_map(rng)
    x, xc = crandn(rng, VF, C), crandn(rng, VC, C)
    assert rel_err(_pool(jnp.asarray(x), pm), ref_pool(x, pm)) < 1e-14
    assert rel_err(_unpool(jnp.asarray(xc), pm), ref_unpool(xc, pm)) < 1e-14


def test_gauge_equivariance(rng):
    pm = random_map(rng)
    beta, alpha = rng.uniform(-np.pi, np.pi, VF), rng.uniform(-np.pi, np.pi, VC)
    pm2 = gauge(pm, beta, alpha)
    x, xc = crandn(rng, VF, C), crandn(rng, VC, C)
    fine, coarse = np.exp(-1j * beta)[:, None], np.exp(-1j * alpha)[:, None]
    assert rel_err(_pool(x * fine, pm2), _pool(x, pm) * coarse) < 1e-14
    assert rel_err(_unpool(xc * coarse, pm2), _unpool(xc, pm) * fine) < 1e-14
    # pool after unpool is the identity on the coarse level, in any gauge
    assert rel_err(_pool(_unpool(xc * coarse, pm2), pm2), xc * coarse) < 1e-14


def test_padding_invariance_and_vmap(rng):
    pms = [random_map(rng, 6, 3), random_map(rng)]
    xs, xcs = [crandn(rng, 6, C), crandn(rng, VF, C)], [crandn(rng, 3, C), crandn(rng, VC, C)]
    m = max(p.children.shape[1] for p in pms) + 1
    padded = [pad_to(p, {"Vf": VF, "Vc": VC, "M": m}) for p in pms]
    batch = jax.tree.map(lambda *a: np.stack(a), *padded)
    xb = np.stack(
        [np.concatenate([xs[0], 1e3 * crandn(rng, VF - 6, C)]), xs[1]]
    )  # garbage on padding
    xcb = np.stack([np.concatenate([xcs[0], 1e3 * crandn(rng, VC - 3, C)]), xcs[1]])
    yb = jax.jit(jax.vmap(tangent_pool))(xb, batch)
    ub = jax.jit(jax.vmap(tangent_unpool))(xcb, batch)
    for i, (pm, x, xc) in enumerate(zip(pms, xs, xcs, strict=False)):
        assert rel_err(yb[i, : len(xc)], _pool(x, pm)) < 1e-14
        assert rel_err(ub[i, : len(x)], _unpool(xc, pm)) < 1e-14
    # padded coarse vertices (no children) pool to exactly 0
    np.testing.assert_array_equal(np.asarray(yb[0, 3:]), 0)


@pytest.mark.parametrize("op", [tangent_pool, tangent_unpool])
def test_jit_matches_eager_without_recompiling(rng, op):
    pm = random_map(rng)
    n = VF if op is tangent_pool else VC
    traces = []

    def fn(x):
        traces.append(1)
        return op(x, pm)

    jitted = jax.jit(fn)
    x1, x2 = (
        jnp.asarray(crandn(rng, n, C), jnp.complex64),
        jnp.asarray(crandn(rng, n, C), jnp.complex64),
    )
    np.testing.assert_allclose(jitted(x1), op(x1, pm), rtol=1e-6, atol=1e-6)
    jitted(x2)
    assert len(traces) == 1


@pytest.mark.parametrize("dtype", [jnp.complex64, jnp.complex128])
def test_dtype_follows_input(rng, dtype):
    pm = random_map(rng)  # float64 / complex128 map: cast to the features' precision
    assert jax.eval_shape(tangent_pool, jnp.zeros((VF, C), dtype), pm).dtype == dtype
    assert jax.eval_shape(tangent_unpool, jnp.zeros((VC, C), dtype), pm).dtype == dtype


@pytest.mark.parametrize("op", [tangent_pool, tangent_unpool])
def test_gradients_at_random_and_zero_features(rng, op):
    pm = random_map(rng)
    n = VF if op is tangent_pool else VC

    def f(xr, xi):
        y = op(jax.lax.complex(xr, xi), pm)
        return jnp.concatenate([y.real, y.imag])

    f = jax.jit(f)
    x = crandn(rng, n, C)
    for point in (x, np.zeros_like(x)):
        check_grads(f, (point.real, point.imag), order=1, modes=("fwd", "rev"))


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_bad_inputs_raise_typed_errors(rng):
    pm = random_map(rng)
    with pytest.raises(InputError, match="complex"):
        tangent_pool(jnp.ones((VF, C)), pm)
    with pytest.raises(InputError, match="fine"):
        tangent_pool(jnp.ones((VC, C), jnp.complex64), pm)
    with pytest.raises(InputError, match="coarse"):
        tangent_unpool(jnp.ones((VF, C), jnp.complex64), pm)
    with pytest.raises(InputError, match="children_weight"):
        tangent_pool(
            jnp.ones((VF, C), jnp.complex64), pm._replace(children_weight=pm.children_weight[:, :1])
        )

"""Chamfer distance and nearest neighbours: brute-force NumPy references, chunking, masks, grads."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads
from scipy.spatial import cKDTree

from jmeshtex import InputError
from jmeshtex.ops import chamfer_distance, nearest_neighbor

_chamfer = jax.jit(chamfer_distance, static_argnames=("squared", "oriented", "chunk_size"))
_nn = jax.jit(nearest_neighbor, static_argnames=("chunk_size",))


def _unit(rng, n):
    x = rng.standard_normal((n, 3))
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def _chamfer_ref(p, q, pn=None, qn=None, *, squared=True, oriented=False):
    """Brute force with the full N × M distance matrix."""
    d2 = ((p[:, None, :] - q[None, :, :]) ** 2).sum(-1)
    j, i = d2.argmin(1), d2.argmin(0)
    dist = d2 if squared else np.sqrt(d2)
    out = [dist[np.arange(len(p)), j].mean(), dist[i, np.arange(len(q))].mean()]
    if pn is None:
        return out + [0.0, 0.0]
    cos_pq, cos_qp = (pn * qn[j]).sum(1), (qn * pn[i]).sum(1)
    f = (lambda c: 1 - c) if oriented else (lambda c: 1 - np.abs(c))
    return out + [f(cos_pq).mean(), f(cos_qp).mean()]


def test_exact_small_case():
    p = jnp.array([[0.0, 0, 0], [2, 0, 0]])
    q = jnp.array([[0.0, 0, 1], [3, 0, 0], [3, 0, 2]])
    pn = jnp.array([[0.0, 0, 1], [1, 0, 0]])
    qn = jnp.array([[0.0, 0, -1], [0, 1, 0], [0.6, 0.8, 0]])
    cd = _chamfer(p, q, p_normals=pn, q_normals=qn)
    # p -> q: 1 (to q0), 1 (to q1); q -> p: 1 (p0), 1 (p1), 1 + 4 = 5 (p1)
    assert float(cd.p_to_q) == 1.0 and float(cd.q_to_p) == pytest.approx(7 / 3, abs=1e-15)
    assert float(cd.distance) == pytest.approx(10 / 3, abs=1e-15)
    # normals: p0·q0 = -1 -> 0 unoriented, 2 oriented; p1·q1 = 0 -> 1; q2·p1 = 0.6 -> 0.4
    assert float(cd.normal_p_to_q) == pytest.approx(0.5, abs=1e-15)
    assert float(cd.normal_q_to_p) == pytest.approx((0 + 1 + 0.4) / 3, abs=1e-15)
    cdo = _chamfer(p, q, p_normals=pn, q_normals=qn, oriented=True)
    assert float(cdo.normal_p_to_q) == pytest.approx(1.5, abs=1e-15)
    cde = _chamfer(p, q, squared=False)
    assert float(cde.q_to_p) == pytest.approx((2 + np.sqrt(5)) / 3, abs=1e-15)


@pytest.mark.parametrize("squared, oriented", [(True, False), (False, True)])
def test_against_brute_force(squared, oriented, rng):
    p, q = rng.standard_normal((57, 3)), rng.standard_normal((40, 3))
    pn, qn = _unit(rng, 57), _unit(rng, 40)
    cd = _chamfer(
        jnp.asarray(p),
        jnp.asarray(q),
        p_normals=jnp.asarray(pn),
        q_normals=jnp.asarray(qn),
        squared=squared,
        oriented=oriented,
        chunk_size=16,
    )
    np.testing.assert_allclose(
        cd, _chamfer_ref(p, q, pn, qn, squared=squared, oriented=oriented), rtol=1e-12
    )


def test_nearest_neighbor_against_kdtree(rng):
    p, q = rng.standard_normal((200, 3)), rng.standard_normal((150, 3))
    nn = _nn(jnp.asarray(p), jnp.asarray(q), chunk_size=64)
    d, j = cKDTree(q).query(p)
    np.testing.assert_array_equal(nn.index, j)
    np.testing.assert_allclose(nn.sq_distance, d**2, rtol=1e-12)
    # float32: the same neighbours (random points: no near-ties at float32 precision)
    nn32 = _nn(jnp.asarray(p, jnp.float32), jnp.asarray(q, jnp.float32), chunk_size=64)
    assert nn32.sq_distance.dtype == jnp.float32
    np.testing.assert_allclose(nn32.sq_distance, d**2, rtol=1e-5, atol=1e-6)


def test_chunk_size_does_not_change_the_result(rng):
    p, q = jnp.asarray(rng.standard_normal((50, 3))), jnp.asarray(rng.standard_normal((31, 3)))
    ref = _nn(p, q, chunk_size=50)
    for chunk in (1, 7, 1000):
        got = _nn(p, q, chunk_size=chunk)
        np.testing.assert_array_equal(got.index, ref.index)
        np.testing.assert_array_equal(got.sq_distance, ref.sq_distance)
    np.testing.assert_array_equal(_chamfer(p, q, chunk_size=7), _chamfer(p, q, chunk_size=64))


def test_no_n_by_m_matrix_when_chunked():
    N, M = 4096, 3000
    jaxpr = jax.make_jaxpr(lambda p, q: chamfer_distance(p, q, chunk_size=256).distance)(
        jnp.zeros((N, 3)), jnp.zeros((M, 3))
    )
    shapes = set()

    def walk(jx):
        for eqn in jx.eqns:
            shapes.update(tuple(v.aval.shape) for v in eqn.outvars if hasattr(v.aval, "shape"))
            for val in eqn.params.values():
                inner = getattr(val, "jaxpr", None)
                if inner is not None:
                    walk(getattr(inner, "jaxpr", inner))

    walk(jaxpr.jaxpr)
    biggest = max(np.prod(s) for s in shapes)
    assert biggest <= 256 * max(N, M), f"an intermediate of {biggest} values (N·M = {N * M})"
    assert (256, M) in shapes and (256, N) in shapes  # the search blocks are there


def test_masks_ignore_padded_points(rng):
    p, q = rng.standard_normal((20, 3)), rng.standard_normal((13, 3))
    pn, qn = _unit(rng, 20), _unit(rng, 13)
    # padded points sit right on top of real ones: they would change every nearest neighbour
    p_pad = np.concatenate([p, q[:5] + 1e-9])
    q_pad = np.concatenate([q, p[:4] - 1e-9, np.full((3, 3), 1e6)])
    pn_pad = np.concatenate([pn, _unit(rng, 5)])
    qn_pad = np.concatenate([qn, _unit(rng, 7)])
    pm = np.arange(25) < 20
    qm = np.arange(20) < 13
    got = _chamfer(
        jnp.asarray(p_pad),
        jnp.asarray(q_pad),
        p_mask=jnp.asarray(pm),
        q_mask=jnp.asarray(qm),
        p_normals=jnp.asarray(pn_pad),
        q_normals=jnp.asarray(qn_pad),
        chunk_size=8,
    )
    np.testing.assert_allclose(got, _chamfer_ref(p, q, pn, qn), rtol=1e-12)
    # no valid target at all: that direction contributes 0, the other is unaffected
    none = _chamfer(jnp.asarray(p), jnp.asarray(q), q_mask=jnp.zeros(13, bool))
    assert float(none.p_to_q) == 0.0 and float(none.q_to_p) == 0.0


def test_rigid_motion_invariance(rng):
    p, q = rng.standard_normal((15, 3)), rng.standard_normal((11, 3))
    pn, qn = _unit(rng, 15), _unit(rng, 11)
    a, r = np.linalg.qr(rng.standard_normal((3, 3)))
    R = a * np.sign(np.diag(r))
    t = rng.standard_normal(3)
    base = _chamfer(
        *(jnp.asarray(x) for x in (p, q)), p_normals=jnp.asarray(pn), q_normals=jnp.asarray(qn)
    )
    moved = _chamfer(
        jnp.asarray(p @ R.T + t),
        jnp.asarray(q @ R.T + t),
        p_normals=jnp.asarray(pn @ R.T),
        q_normals=jnp.asarray(qn @ R.T),
    )
    np.testing.assert_allclose(moved, base, rtol=1e-12, atol=1e-14)


def test_jit_eager_and_single_compilation(rng):
    p, q = jnp.asarray(rng.standard_normal((30, 3))), jnp.asarray(rng.standard_normal((20, 3)))
    traces = []

    def fn(p, q):
        traces.append(1)
        return chamfer_distance(p, q, chunk_size=8)

    jitted = jax.jit(fn)
    np.testing.assert_allclose(jitted(p, q), fn(p, q), rtol=1e-14)
    jitted(p + 1, q * 2)
    assert len(traces) == 2  # eager once, compiled once


def test_vmap_over_two_padded_point_sets(rng):
    sizes = [(12, 9), (20, 15)]
    sets = [(rng.standard_normal((n, 3)), rng.standard_normal((m, 3))) for n, m in sizes]
    N, M = 20, 15
    P = jnp.stack([jnp.pad(jnp.asarray(p), ((0, N - len(p)), (0, 0))) for p, _ in sets])
    Q = jnp.stack([jnp.pad(jnp.asarray(q), ((0, M - len(q)), (0, 0))) for _, q in sets])
    PM = jnp.stack([jnp.arange(N) < n for n, _ in sizes])
    QM = jnp.stack([jnp.arange(M) < m for _, m in sizes])
    out = jax.jit(
        jax.vmap(lambda p, q, pm, qm: chamfer_distance(p, q, p_mask=pm, q_mask=qm, chunk_size=8))
    )(P, Q, PM, QM)
    for b, (p, q) in enumerate(sets):
        np.testing.assert_allclose([o[b] for o in out], _chamfer_ref(p, q), rtol=1e-12)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_dtype_preserved(dtype, rng):
    p, q = (
        jnp.asarray(rng.standard_normal((9, 3)), dtype),
        jnp.asarray(rng.standard_normal((7, 3)), dtype),
    )
    cd = _chamfer(p, q, p_normals=p, q_normals=q)
    assert all(v.dtype == dtype for v in cd)
    assert _nn(p, q).sq_distance.dtype == dtype


def _away_from_kinks(rng, margin: float = 0.05):
    """Points and normals drawn until finite differences cannot cross a kink of the loss.

    The Chamfer terms are smooth except where a point's nearest neighbour changes and where a
    matched pair's normals are perpendicular (``|n_p · n_q|``); a finite difference across either
    disagrees with the derivative (seed sweep: 1 draw in 100 did). Each point's nearest squared
    distance is at least ``margin`` below its second nearest and every matched ``|n_p · n_q|`` is at
    least ``margin``, far above what check_grads' steps can change.
    """
    for _ in range(1000):
        p, q = rng.standard_normal((10, 3)), rng.standard_normal((8, 3))
        pn, qn = _unit(rng, 10), _unit(rng, 8)
        d2 = ((p[:, None] - q[None]) ** 2).sum(-1)
        gaps = np.concatenate([np.diff(np.sort(d2, 1)[:, :2]), np.diff(np.sort(d2, 0)[:2].T)])
        j, i = d2.argmin(1), d2.argmin(0)
        dots = np.abs(np.concatenate([(pn * qn[j]).sum(1), (pn[i] * qn).sum(1)]))
        if gaps.min() > margin and dots.min() > margin:
            return p, q, pn, qn
    raise AssertionError("no draw away from the kinks in 1000 tries")


def test_gradients(rng):
    p, q, pn, qn = _away_from_kinks(rng)

    @jax.jit
    def loss(flat):  # one flat vector in: check_grads' eager pytree arithmetic stays cheap
        p, q, pn, qn = jnp.split(flat, [30, 54, 84])
        cd = chamfer_distance(
            p.reshape(10, 3),
            q.reshape(8, 3),
            p_normals=pn.reshape(10, 3),
            q_normals=qn.reshape(8, 3),
            chunk_size=4,
        )
        return cd.distance + 0.5 * cd.normal

    args = tuple(jnp.asarray(a) for a in (p, q, pn, qn))
    check_grads(loss, (jnp.concatenate([a.ravel() for a in args]),), order=1, modes=["fwd", "rev"])
    # analytic gradient of the squared term w.r.t. p: 2 (p - q_j)/N + Σ_{q: i(q) = p} 2 (p - q)/M
    gp = jax.jit(jax.grad(lambda p, q: chamfer_distance(p, q).distance))(args[0], args[1])
    d2 = ((p[:, None] - q[None]) ** 2).sum(-1)
    j, i = d2.argmin(1), d2.argmin(0)
    want = 2 * (p - q[j]) / len(p)
    np.add.at(want, i, 2 * (p[i] - q) / len(q))
    np.testing.assert_allclose(gp, want, rtol=1e-12, atol=1e-14)


def test_finite_gradient_at_coincident_points():
    p = jnp.array([[0.0, 0, 0], [1, 0, 0]])
    q = jnp.array([[0.0, 0, 0], [1, 0, 0]])  # every distance is exactly 0
    for squared in (True, False):
        g = jax.jit(
            jax.grad(lambda p, q, s=squared: chamfer_distance(p, q, squared=s).distance, (0, 1))
        )(p, q)
        assert all(np.isfinite(np.asarray(x)).all() for x in g)
    n = jnp.array([[0.0, 0, 1], [1, 0, 0]])
    gn = jax.jit(
        jax.grad(lambda a: chamfer_distance(p, q, p_normals=a, q_normals=n[::-1] * 0).normal)
    )(n)
    assert np.isfinite(np.asarray(gn)).all()  # |cos| at cos = 0


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_bad_input_raises_typed_errors():
    p = jnp.zeros((4, 3))
    with pytest.raises(InputError, match="same dimension"):
        chamfer_distance(p, jnp.zeros((4, 2)))
    with pytest.raises(InputError, match="non-empty"):
        chamfer_distance(p, jnp.zeros((0, 3)))
    with pytest.raises(InputError, match="both"):
        chamfer_distance(p, p, p_normals=p)
    with pytest.raises(InputError, match="p_mask"):
        chamfer_distance(p, p, p_mask=jnp.ones(3, bool))
    with pytest.raises(InputError, match="same dimension and dtype"):
        nearest_neighbor(p, jnp.zeros((4, 3), jnp.float32))

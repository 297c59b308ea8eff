"""k-NN geodesic neighbourhoods: selection against Dijkstra, composition against a loop reference,
exact flat cases, padding, fold invariance, and igl.exact_geodesic as a distance oracle."""

from __future__ import annotations

import igl
import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st
from scipy.sparse.csgraph import dijkstra

from jmeshtex import InputError
from jmeshtex.data import grid, icosahedron, icosphere, single_triangle, torus
from jmeshtex.geometry import geodesic_knn_neighborhood, knn_from_one_ring, one_ring_neighborhood
from jmeshtex.testing import fold_sheet, valid_meshes


def _graph(ring):
    p, j = np.nonzero(ring.mask)
    V = ring.index.shape[0]
    return sp.csr_matrix((np.abs(ring.log[p, j]), (p, ring.index[p, j])), shape=(V, V))


def _reference(v, f, k):
    """Loop reference: full Dijkstra per vertex, walk each path and compose one-ring maps."""
    ring = one_ring_neighborhood(v, f, scale=None)
    step = {}
    for p, j in zip(*np.nonzero(ring.mask), strict=True):
        step[p, ring.index[p, j]] = (ring.log[p, j], ring.transport[p, j])
    dist, pred = dijkstra(_graph(ring), return_predecessors=True)
    out = {}
    for p in range(len(v)):
        for q in np.argsort(dist[p], kind="stable")[:k]:
            path = [q]
            while path[-1] != p:
                path.append(pred[p, path[-1]])
            path = path[::-1]
            log, tr = 0j, 1 + 0j
            for m, r in zip(path[:-1], path[1:], strict=True):
                s_log, s_tr = step[m, r]
                log, tr = log + tr * s_log, tr * s_tr
            out[p, q] = (log, tr, dist[p, q])
    return out


@pytest.mark.parametrize(
    "make",
    [lambda: icosphere(2), lambda: grid(6), lambda: torus(12, 8)],
    ids=["sphere", "grid", "torus"],
)
def test_matches_dijkstra_and_loop_composition(make, rng):
    v, f = make()
    v = v + 0.01 * rng.normal(size=v.shape)  # no ties: shortest paths are unique
    k = 10
    nb = geodesic_knn_neighborhood(v, f, k=k, scale=None)
    ref = _reference(v, f, k)
    assert nb.index.shape == (len(v), k) and nb.mask.all()
    np.testing.assert_array_equal(nb.index[:, 0], np.arange(len(v)))
    for p in range(len(v)):
        assert set(nb.index[p].tolist()) == {q for (a, q) in ref if a == p}
        d = [ref[p, q][2] for q in nb.index[p]]
        assert np.all(np.diff(d) >= 0)  # sorted by path length
        np.testing.assert_allclose(
            nb.log[p], [ref[p, q][0] for q in nb.index[p]], rtol=0, atol=1e-12
        )
        np.testing.assert_allclose(
            nb.transport[p], [ref[p, q][1] for q in nb.index[p]], rtol=0, atol=1e-12
        )
    ring = one_ring_neighborhood(v, f, scale=None)
    np.testing.assert_allclose(nb.area, ring.area, rtol=0)
    np.testing.assert_allclose(nb.weight, ring.area[nb.index], rtol=0)
    assert nb.log[:, 0].tolist() == [0j] * len(v) and nb.transport[:, 0].tolist() == [1 + 0j] * len(
        v
    )


def test_selected_distances_are_the_k_smallest_even_with_ties():
    v, f = grid(6, diagonals="uniform")  # many equal path lengths
    k = 12
    nb = geodesic_knn_neighborhood(v, f, k=k, scale=None)
    dist = dijkstra(_graph(one_ring_neighborhood(v, f, scale=None)))
    got = dist[np.arange(len(v))[:, None], nb.index]
    np.testing.assert_allclose(got, np.sort(dist, axis=1)[:, :k], rtol=1e-12)


def test_flat_grid_exact_including_the_boundary():
    v, f = grid(6, 5, size=(1.2, 1.0))
    nb = geodesic_knn_neighborhood(v, f, k=16, scale=None)
    ring = one_ring_neighborhood(v, f, scale=None)
    z = v[:, 0] + 1j * v[:, 1]
    frame = z[ring.index[:, 0]] - z
    frame /= np.abs(frame)
    np.testing.assert_allclose(
        nb.log, (z[nb.index] - z[:, None]) / frame[:, None], rtol=0, atol=1e-14
    )
    np.testing.assert_allclose(nb.transport, frame[nb.index] / frame[:, None], rtol=0, atol=1e-14)


def test_gauge_consistency_for_mutual_neighbours(rng):
    v, f = icosphere(2)
    v = v + 0.01 * rng.normal(size=v.shape)
    nb = geodesic_knn_neighborhood(v, f, k=12, scale=None)
    checked = 0
    for p in range(len(v)):
        for j in range(1, 12):
            q = nb.index[p, j]
            back = np.nonzero(nb.index[q] == p)[0]
            if back.size:
                # the same (unique) path walked backwards: exact up to rounding
                assert abs(nb.transport[p, j] * nb.log[q, back[0]] + nb.log[p, j]) < 1e-13
                assert abs(nb.transport[p, j] * nb.transport[q, back[0]] - 1) < 1e-13
                checked += 1
    assert checked > 5 * len(v)


def test_small_components_are_padded():
    v1, f1 = single_triangle()
    v2, f2 = icosahedron()
    v = np.concatenate([v1, v2 + 5.0])
    f = np.concatenate([f1, f2 + 3])
    nb = geodesic_knn_neighborhood(v, f, k=14, scale=None)
    assert nb.mask[:3].sum(axis=1).tolist() == [3, 3, 3]
    assert nb.mask[3:].sum(axis=1).tolist() == [12] * 12
    pad = ~nb.mask
    assert (
        np.all(nb.index[pad] == 0) and np.all(nb.log[pad] == 0) and np.all(nb.transport[pad] == 1)
    )
    assert np.all(nb.weight[pad] == 0)
    assert set(nb.index[0, :3].tolist()) == {0, 1, 2}
    # k = 1 is the vertex alone
    one = geodesic_knn_neighborhood(v, f, k=1, scale=None)
    assert one.index[:, 0].tolist() == list(range(len(v))) and one.mask.all()


def test_unchanged_under_folds():
    v, f = grid(8, 8)  # a regular grid: ties everywhere, broken identically after folding
    folded = fold_sheet(v, f, lines=[("x", 0.375), ("x", 0.75)], angles=[2.0, -1.2])
    a = geodesic_knn_neighborhood(v, f, k=12, scale=None)
    b = geodesic_knn_neighborhood(folded, f, k=12, scale=None)
    np.testing.assert_array_equal(a.index, b.index)
    np.testing.assert_array_equal(a.mask, b.mask)
    for name in ("log", "transport", "weight", "area"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    "mesh, bound",
    [
        (icosphere(3), 0.01),  # measured 0.20 % (k = 16, 30 sources)
        (torus(30, 15), 0.04),  # measured 2.0 %: the exp map drifts more where K < 0
    ],
    ids=["sphere", "torus"],
)
def test_distances_agree_with_exact_geodesics(mesh, bound):
    v, f = mesh
    k = 16
    nb = geodesic_knn_neighborhood(v, f, k=k, scale=None)
    path = dijkstra(
        _graph(one_ring_neighborhood(v, f, scale=None)), indices=np.arange(0, len(v), len(v) // 30)
    )
    worst_log, worst_path = 0.0, 0.0
    for row, p in enumerate(np.arange(0, len(v), len(v) // 30)):
        q = nb.index[p, 1:]
        exact = igl.exact_geodesic(
            v, f, np.array([p]), np.array([], np.int64), q.astype(np.int64), np.array([], np.int64)
        )
        worst_log = max(worst_log, np.max(np.abs(np.abs(nb.log[p, 1:]) - exact) / exact))
        worst_path = max(worst_path, np.max((path[row, q] - exact) / exact))
    print(f"k-NN |log| vs igl.exact_geodesic: {worst_log:.2%}; edge-path length: {worst_path:.2%}")
    assert worst_log < bound
    assert worst_log < worst_path  # the composed map beats the zig-zag edge path


def test_knn_from_a_precomputed_one_ring_is_the_same():
    v, f = torus(8, 6)
    a = geodesic_knn_neighborhood(v, f, k=7, scale=None)
    b = knn_from_one_ring(one_ring_neighborhood(v, f, scale=None), 7)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("k", [0, -3, 2.5, True, "8"])
@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_bad_k(k):
    v, f = icosahedron()
    with pytest.raises(InputError):
        geodesic_knn_neighborhood(v, f, k=k, scale=None)


@given(valid_meshes(max_vertices=150), st.integers(1, 20))
def test_property_selection_is_the_k_nearest(mesh, k):
    v, f = mesh.vertices, mesh.faces
    nb = geodesic_knn_neighborhood(v, f, k=k, scale=None)
    dist = dijkstra(_graph(one_ring_neighborhood(v, f, scale=None)))
    want = np.sort(np.pad(dist, ((0, 0), (0, k)), constant_values=np.inf), axis=1)[:, :k]
    got = np.where(nb.mask, dist[np.arange(len(v))[:, None], nb.index], np.inf)
    np.testing.assert_allclose(got, want, rtol=1e-9)
    assert np.all(np.isfinite(nb.log)) and np.allclose(np.abs(nb.transport), 1, atol=1e-13)


def test_knn_on_a_coarse_hierarchy_level_uses_its_intrinsic_lengths():
    from jmeshtex.geometry import mesh_hierarchy

    v, f = grid(12)
    h = mesh_hierarchy(v, f, levels=2)
    nb = knn_from_one_ring(h.neighborhoods[1], 6)
    z = (v[:, 0] + 1j * v[:, 1])[h.vertex_index[1]]
    ring = h.neighborhoods[1]
    frame = z[ring.index[:, 0]] - z
    frame /= np.abs(frame)
    # flat: the coarse level's composed maps are exact planar offsets in its own frames
    np.testing.assert_allclose(nb.log, (z[nb.index] - z[:, None]) / frame[:, None], atol=1e-12)

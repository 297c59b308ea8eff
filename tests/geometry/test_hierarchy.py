"""Mesh hierarchy: topology kept, subsets and Voronoi parents, exact flat transports, exact gauge
equivariance under relabelling, invariance under folds, open meshes and several components."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given
from scipy.sparse.csgraph import dijkstra

from jmeshtex import ConfigError, InputError
from jmeshtex.data import grid, icosahedron, icosphere, torus
from jmeshtex.geometry import (
    DecimationError,
    boundary_loops,
    connected_components,
    geodesic_knn_neighborhood,
    mesh_hierarchy,
    one_ring_neighborhood,
    prepare_mesh,
    tangent_frames,
    validate_mesh,
)
from jmeshtex.testing import BAD_MESH_KINDS, fold_sheet, valid_meshes
from tests.geometry._helpers import bad_mesh_cases, euler


def _level_graph(h, level):
    """Edge graph of a level with its intrinsic lengths (from ``h.lengths``)."""
    f, lengths = h.faces[level], h.lengths[level]
    n = len(h.vertices[level])
    a, b = f.ravel(), np.roll(f, -1, axis=1).ravel()
    g = sp.csr_matrix((lengths.ravel(), (a, b)), shape=(n, n))
    return g.maximum(g.T)


@pytest.mark.parametrize(
    "make, chi, loops, stretch",
    [
        (lambda: icosphere(3), 2, 0, (1 - 1e-12, 1.15)),  # measured 1.0 .. 1.125
        (
            lambda: torus(30, 12),
            0,
            0,
            (0.9, 2.0),
        ),  # measured 0.97 .. 1.88: coarse edges wrap the tube
        (lambda: grid(20, 14), 1, 1, (1 - 1e-12, 1 + 1e-12)),  # flat: composed maps are exact
    ],
    ids=["sphere", "torus", "open-grid"],
)
def test_levels_keep_topology_and_are_subsets(make, chi, loops, stretch):
    v, f = make()
    h = mesh_hierarchy(v, f, min_vertices=40)
    sizes = [len(x) for x in h.vertices]
    assert h.num_levels == len(h.pooling) + 1 >= 3
    for n, m in zip(sizes[:-1], sizes[1:], strict=True):
        assert m == math.ceil(0.5 * n)  # the target is reached exactly on these meshes
    assert math.ceil(0.5 * sizes[-1]) < 40 <= sizes[-1]
    np.testing.assert_array_equal(h.vertex_index[0], np.arange(len(v)))
    for level in range(h.num_levels):
        vl, fl = h.vertices[level], h.faces[level]
        validate_mesh(vl, fl)  # manifold, oriented, no degenerate faces
        assert euler(vl, fl) == chi and len(boundary_loops(fl)) == loops
        np.testing.assert_array_equal(vl, v[h.vertex_index[level]])
        if level:
            assert set(h.vertex_index[level]) <= set(h.vertex_index[level - 1])
        # intrinsic lengths are geodesic estimates: chord lengths on a plane, longer on a sphere
        ratio = h.lengths[level] / np.linalg.norm(vl[np.roll(fl, -1, axis=1)] - vl[fl], axis=-1)
        assert stretch[0] <= ratio.min() and ratio.max() <= stretch[1]


def test_pooling_maps_are_voronoi_and_consistent(rng):
    v, f = icosphere(3)
    v = v * (1 + 0.02 * rng.normal(size=(len(v), 1)))
    h = mesh_hierarchy(v, f, levels=4)
    for level, pm in enumerate(h.pooling):
        fine_n, coarse_n = len(h.vertices[level]), len(h.vertices[level + 1])
        fine_pos = {int(g): i for i, g in enumerate(h.vertex_index[level])}
        kept = np.array([fine_pos[int(g)] for g in h.vertex_index[level + 1]])
        assert pm.parent.shape == (fine_n,) and pm.children.shape[0] == coarse_n
        np.testing.assert_array_equal(pm.parent[kept], np.arange(coarse_n))  # own copy is its child
        # every fine vertex goes to a nearest coarse vertex by edge path within the fine level
        dist = dijkstra(_level_graph(h, level), indices=kept)
        np.testing.assert_allclose(dist[pm.parent, np.arange(fine_n)], dist.min(axis=0), rtol=1e-9)
        # children are the inverse of parent, own copy first; weights are normalised areas
        m = pm.children_mask
        assert sorted(pm.children[m].tolist()) == list(range(fine_n))
        np.testing.assert_array_equal(pm.parent[pm.children[m]], np.nonzero(m)[0])
        np.testing.assert_array_equal(pm.children[:, 0], kept)
        area = h.neighborhoods[level].area
        np.testing.assert_allclose(pm.children_weight.sum(axis=1), 1.0, rtol=1e-13)
        total = np.bincount(pm.parent, weights=area, minlength=coarse_n)
        np.testing.assert_allclose(
            pm.children_weight[m], area[pm.children[m]] / total[np.nonzero(m)[0]], rtol=1e-13
        )
        np.testing.assert_allclose(
            pm.children_transport[m], pm.to_parent[pm.children[m]], rtol=0, atol=0
        )
        np.testing.assert_allclose(np.abs(pm.to_parent), 1.0, atol=1e-14)
        assert np.all(pm.children[~m] == 0) and np.all(pm.children_weight[~m] == 0)
        assert np.all(pm.children_transport[~m] == 1)
        assert pm.parent.dtype == np.int32 and pm.children.dtype == np.int32


def _frame_dirs(h, level, z):
    """Global direction (complex, in the sheet's plane) of each level-ℓ vertex's reference edge."""
    nb = h.neighborhoods[level]
    zl = z[h.vertex_index[level]]
    d = zl[nb.index[:, 0]] - zl
    return zl, d / np.abs(d)


def test_flat_sheet_transports_and_coarse_log_maps_are_exact():
    """On a flat sheet every composed map is exact, so pooling is the rotation between frames."""
    v, f = grid(16, 12, size=(1.0, 0.8))
    h = mesh_hierarchy(v, f, levels=4)
    z = v[:, 0] + 1j * v[:, 1]
    for level in range(h.num_levels):
        zl, frame = _frame_dirs(h, level, z)
        nb = h.neighborhoods[level]
        want = np.where(nb.mask, (zl[nb.index] - zl[:, None]) / frame[:, None], 0)
        np.testing.assert_allclose(nb.log, want, rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            nb.transport[nb.mask], (frame[nb.index] / frame[:, None])[nb.mask], atol=1e-12
        )
        _, frame0 = _frame_dirs(h, 0, z)
        np.testing.assert_allclose(
            h.to_input_frame[level], frame / frame0[h.vertex_index[level]], atol=1e-12
        )
        if level + 1 < h.num_levels:
            _, coarse = _frame_dirs(h, level + 1, z)
            pm = h.pooling[level]
            np.testing.assert_allclose(pm.to_parent, frame / coarse[pm.parent], rtol=0, atol=1e-12)


def _relabelled(v, f, rng):
    """Shuffle vertex ids, face order and each face's first corner; return the new mesh and
    ``old_id`` (the original id of every new vertex)."""
    perm = rng.permutation(len(v))  # new id of each old vertex
    old_id = np.argsort(perm)
    f2 = perm[f][rng.permutation(len(f))]
    f2 = np.stack([np.roll(row, s) for row, s in zip(f2, rng.integers(0, 3, len(f2)), strict=True)])
    return v[old_id], f2, old_id


def test_exactly_gauge_equivariant_under_relabelling():
    """Relabelling moves every gauge (slot 0 changes); pooling must change by exactly those rotations.

    The data are fixed: the greedy decimation orders candidate collapses by float costs whose
    rounding depends on the summation order, so for some random draws (seed 1544528487 of the old
    random fixture is one) a near-tie between two collapses flips under relabelling and the coarse
    vertex sets differ. That is the decimation's known limit, not a gauge error.
    """
    rng = np.random.default_rng(20261201)
    v, f = icosphere(3)
    v = v * (1 + 0.03 * rng.normal(size=(len(v), 1)))  # generic: no ties anywhere
    a = mesh_hierarchy(v, f, levels=4)
    v2, f2, old_id = _relabelled(v, f, rng)
    b = mesh_hierarchy(v2, f2, levels=4)
    assert [len(x) for x in a.vertices] == [len(x) for x in b.vertices]
    gauge = []  # per level: b's frame x-axis expressed in a's frame, and the vertex map a -> b
    for level in range(a.num_levels):
        ids_a, ids_b = a.vertex_index[level], old_id[b.vertex_index[level]]  # both in a's input ids
        assert set(ids_a) == set(ids_b)
        to_b = np.argsort(ids_b)[
            np.searchsorted(np.sort(ids_b), ids_a)
        ]  # a's vertex i is b's to_b[i]
        faces_a = {tuple(sorted(t)) for t in ids_a[a.faces[level]].tolist()}
        faces_b = {tuple(sorted(t)) for t in ids_b[b.faces[level]].tolist()}
        assert faces_a == faces_b
        np.testing.assert_allclose(b.lengths[level].sum(), a.lengths[level].sum(), rtol=1e-12)
        nb_a, nb_b = a.neighborhoods[level], b.neighborhoods[level]
        ref_in_a = np.argsort(to_b)[nb_b.index[to_b, 0]]  # b's slot-0 neighbour, as a's vertex
        slot = np.argmax(nb_a.index == ref_in_a[:, None], axis=1)
        beta = nb_a.log[np.arange(len(slot)), slot]
        beta = beta / np.abs(beta)
        gauge.append((beta, to_b))
        # the level's log maps differ by exactly the gauge rotation: log_b = conj(β) log_a
        nbr_in_a = np.argsort(to_b)[nb_b.index[to_b]]  # b's ring of a's vertex i, as a's ids
        match = np.argmax(nb_a.index[:, None, :] == nbr_in_a[:, :, None], axis=2)
        log_a = np.take_along_axis(nb_a.log, match, axis=1)
        m = nb_b.mask[to_b]
        np.testing.assert_allclose(
            nb_b.log[to_b][m], (np.conj(beta)[:, None] * log_a)[m], rtol=0, atol=1e-12
        )
        # and the alignment with the input frames changes by both gauges
        beta0 = gauge[0][0][ids_a]
        want = np.conj(beta0) * a.to_input_frame[level] * beta
        np.testing.assert_allclose(b.to_input_frame[level][to_b], want, rtol=0, atol=1e-12)
    for level, (pa, pb) in enumerate(zip(a.pooling, b.pooling, strict=True)):
        beta_f, to_b_f = gauge[level]
        beta_c, to_b_c = gauge[level + 1]
        np.testing.assert_array_equal(to_b_c[pa.parent], pb.parent[to_b_f])
        want = np.conj(beta_c[pa.parent]) * pa.to_parent * beta_f
        np.testing.assert_allclose(pb.to_parent[to_b_f], want, rtol=0, atol=1e-12)


def test_unchanged_under_folds():
    v, f = grid(16, 16)  # regular: ties everywhere, broken identically after folding
    folded = fold_sheet(
        v, f, lines=[("y", 0.25), ("y", 0.5), ("y", 0.8125)], angles=[0.9, -1.7, 2.4]
    )
    assert np.abs(folded[:, 2]).max() > 0.15
    a = mesh_hierarchy(v, f, levels=4)
    b = mesh_hierarchy(folded, f, levels=4)
    for level in range(4):
        np.testing.assert_array_equal(a.faces[level], b.faces[level])
        np.testing.assert_array_equal(a.vertex_index[level], b.vertex_index[level])
        np.testing.assert_allclose(b.lengths[level], a.lengths[level], rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            b.to_input_frame[level], a.to_input_frame[level], rtol=0, atol=1e-12
        )
        for x, y in zip(a.neighborhoods[level], b.neighborhoods[level], strict=True):
            if x is None or y is None:  # optional fields (log_unit) unset in both
                assert x is None and y is None
                continue
            np.testing.assert_allclose(y, x, rtol=0, atol=1e-12)
    for pa, pb in zip(a.pooling, b.pooling, strict=True):
        for x, y in zip(pa, pb, strict=True):
            np.testing.assert_allclose(y, x, rtol=0, atol=1e-12)


def test_several_components_and_boundaries():
    (v1, f1), (v2, f2) = torus(16, 8), grid(12, 6)
    v = np.concatenate([v1, v2 + [3.0, 0, 0]])
    f = np.concatenate([f1, f2 + len(v1)])
    h = mesh_hierarchy(v, f, levels=3)
    for fl, vl in zip(h.faces, h.vertices, strict=True):
        validate_mesh(vl, fl)
        assert connected_components(fl).max() == 1 and len(boundary_loops(fl)) == 1
        assert euler(vl, fl) == 1


def test_level_zero_is_the_input_neighborhood():
    v, f = torus(12, 8)
    h = mesh_hierarchy(v, f, levels=2)
    ref = one_ring_neighborhood(v, f, scale=None)  # the hierarchy's maps are in mesh units
    for x, y in zip(h.neighborhoods[0], ref, strict=True):
        np.testing.assert_array_equal(x, y)
    assert np.all(h.to_input_frame[0] == 1)


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_errors():
    v, f = icosahedron()
    with pytest.raises(DecimationError, match="too small"):
        mesh_hierarchy(v, f)  # 12 vertices: one level would have 6 < 128
    with pytest.raises(DecimationError):
        mesh_hierarchy(v, f, levels=4)  # 12 -> 6 -> 3: below a closed surface's minimum
    assert mesh_hierarchy(v, f, levels=1).num_levels == 1
    for bad in (
        dict(ratio=0.0),
        dict(ratio=1.0),
        dict(ratio="half"),
        dict(min_vertices=2),
        dict(levels=0),
        dict(levels=2.5),
    ):
        with pytest.raises(ConfigError):
            mesh_hierarchy(v, f, **bad)
    with pytest.raises(InputError, match="unreferenced"):
        mesh_hierarchy(np.concatenate([v, [[9.0, 9, 9]]]), f, levels=2)


@pytest.mark.shared_data
def test_real_open_mesh_with_several_components(shared_data):
    from jmeshtex.io import load_mesh

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the loader reports merged / split vertices
        mesh, _ = prepare_mesh(load_mesh(shared_data / "teapot.obj"), repair=True)
    v, f = mesh.vertices, mesh.faces
    h = mesh_hierarchy(v, f, levels=3)
    loops, parts = len(boundary_loops(f)), connected_components(f).max()
    for vl, fl in zip(h.vertices, h.faces, strict=True):
        validate_mesh(vl, fl)
        assert len(boundary_loops(fl)) == loops and connected_components(fl).max() == parts
        assert euler(vl, fl) == euler(v, f)
    assert len(h.vertices[2]) == math.ceil(0.5 * math.ceil(0.5 * len(v)))


@given(valid_meshes(min_vertices=40, max_vertices=250))
def test_property_any_valid_mesh_decimates_with_its_topology(mesh):
    v, f = mesh.vertices, mesh.faces
    h = mesh_hierarchy(v, f, levels=3)
    loops, parts = len(boundary_loops(f)), connected_components(f).max()
    for level, (vl, fl) in enumerate(zip(h.vertices, h.faces, strict=True)):
        validate_mesh(vl, fl)
        assert euler(vl, fl) == euler(v, f)
        assert len(boundary_loops(fl)) == loops and connected_components(fl).max() == parts
        if level:
            n = len(h.vertices[level - 1])
            assert len(vl) <= n - (n - math.ceil(n / 2)) / 2
    for pm in h.pooling:
        np.testing.assert_allclose(np.abs(pm.to_parent), 1.0, atol=1e-13)
        np.testing.assert_allclose(pm.children_weight.sum(axis=1), 1.0, rtol=1e-12)


@given(bad_mesh_cases())
@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_property_bad_meshes_raise_typed_errors(case):
    kind, (v, f) = case
    for build in (
        geodesic_knn_neighborhood,
        tangent_frames,
        lambda v, f: mesh_hierarchy(v, f, levels=2),
    ):
        with pytest.raises(BAD_MESH_KINDS[kind]):
            build(v, f)

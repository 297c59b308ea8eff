"""Midpoint subdivision: counts, orientation, Euler characteristic, area, parent maps, UVs, rescaling."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from jmeshtex import (
    EmptyMeshError,
    FaceIndexError,
    InputError,
    NonFiniteVertexError,
    NonTriangleFaceError,
)
from jmeshtex.data import grid, icosahedron, icosphere, single_triangle, torus
from jmeshtex.geometry import (
    boundary_edges,
    face_neighborhood,
    mean_edge_length,
    rescale_to_mean_edge,
    subdivide_midpoint,
    subdivide_uv,
)

MESHES = {
    "triangle": single_triangle,
    "icosahedron": icosahedron,
    "grid": lambda: grid(3, 2),
    "torus": lambda: torus(6, 4),
}


def _num_edges(faces: np.ndarray) -> int:
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return len(np.unique(e, axis=0))


def _face_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    return np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])


def _reference_subdivide(v: np.ndarray, f: np.ndarray):
    """Slow, loop-based midpoint subdivision with a dict of edges (independent reference)."""
    edge_id: dict[tuple[int, int], int] = {}
    for a, b in sorted(
        {
            tuple(sorted((int(x), int(y))))
            for tri in f
            for x, y in zip(tri, np.roll(tri, -1), strict=True)
        }
    ):
        edge_id[(a, b)] = len(v) + len(edge_id)
    verts = [*v]
    for (a, b), _ in sorted(edge_id.items(), key=lambda kv: kv[1]):
        verts.append(0.5 * (v[a] + v[b]))
    mid = lambda x, y: edge_id[(min(x, y), max(x, y))]  # noqa: E731
    children: list[list[list[int]]] = [[], [], [], []]
    for a, b, c in f.tolist():
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        for j, child in enumerate(([a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca])):
            children[j].append(child)
    return np.array(verts), np.array([t for group in children for t in group])


@pytest.mark.parametrize("name", list(MESHES))
def test_matches_loop_reference(name):
    v, f = MESHES[name]()
    s = subdivide_midpoint(v, f)
    rv, rf = _reference_subdivide(v, f)
    np.testing.assert_array_equal(s.faces, rf)
    np.testing.assert_allclose(s.vertices, rv, rtol=0, atol=1e-15)


@pytest.mark.parametrize("name", list(MESHES))
def test_counts_and_euler_characteristic(name):
    v, f = MESHES[name]()
    chi = len(v) - _num_edges(f) + len(f)
    for _ in range(2):
        s = subdivide_midpoint(v, f)
        assert s.vertices.shape == (len(v) + _num_edges(f), 3)
        assert s.faces.shape == (4 * len(f), 3)
        assert s.edge_vertices.shape == (_num_edges(f), 2)
        assert s.face_parent.shape == (4 * len(f),)
        assert s.faces.dtype == np.int64 and s.vertices.dtype == np.float64
        v, f = s.vertices, s.faces
        assert len(v) - _num_edges(f) + len(f) == chi


def test_icosphere_counts():
    for s in range(4):
        v, f = icosphere(s)
        assert (len(v), len(f)) == (10 * 4**s + 2, 20 * 4**s)
        np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-15)


@pytest.mark.parametrize("name", list(MESHES))
def test_orientation_preserved(name):
    v, f = MESHES[name]()
    s = subdivide_midpoint(v, f)
    # topologically consistent: the half-edge table raises InconsistentOrientationError otherwise
    face_neighborhood(s.faces)
    # geometrically: every child's normal points exactly like its parent's (children are coplanar)
    n_parent = _face_normals(v, f)[s.face_parent]
    n_child = _face_normals(s.vertices, s.faces)
    np.testing.assert_allclose(n_child, n_parent / 4.0, rtol=0, atol=1e-14)


def test_area_preserved_on_flat_mesh_and_each_child_is_a_quarter(rng):
    v, f = grid(5, 4, size=(2.0, 1.5))
    v[:, :2] += rng.uniform(-0.05, 0.05, size=(len(v), 2))  # still flat, irregular triangles
    area = lambda v, f: 0.5 * np.linalg.norm(_face_normals(v, f), axis=1)  # noqa: E731
    s = subdivide_midpoint(v, f)
    assert np.isclose(area(s.vertices, s.faces).sum(), area(v, f).sum(), rtol=1e-14)
    np.testing.assert_allclose(
        area(s.vertices, s.faces), area(v, f)[s.face_parent] / 4.0, rtol=1e-12
    )


def test_parent_maps():
    v, f = torus(6, 4)
    s = subdivide_midpoint(v, f)
    V = len(v)
    # each new vertex is the midpoint of an existing coarse edge, every coarse edge gets exactly one
    coarse_edges = {
        tuple(sorted(e)) for tri in f.tolist() for e in zip(tri, tri[1:] + tri[:1], strict=True)
    }
    assert {tuple(e) for e in s.edge_vertices.tolist()} == coarse_edges
    assert len(s.edge_vertices) == len(coarse_edges)
    np.testing.assert_allclose(
        s.vertices[V:], 0.5 * (v[s.edge_vertices[:, 0]] + v[s.edge_vertices[:, 1]])
    )
    np.testing.assert_array_equal(s.vertices[:V], v)
    # the new vertex is joined to both of its parents in the fine mesh
    fine_edges = {
        tuple(sorted(e))
        for tri in s.faces.tolist()
        for e in zip(tri, tri[1:] + tri[:1], strict=True)
    }
    for i, (a, b) in enumerate(s.edge_vertices.tolist()):
        assert (a, V + i) in fine_edges and (b, V + i) in fine_edges
    # a fine face only uses its parent's corners and the midpoints of its parent's edges
    for child, parent in zip(s.faces.tolist(), s.face_parent.tolist(), strict=True):
        corners = set(f[parent].tolist())
        for x in child:
            assert x in corners or set(s.edge_vertices[x - V].tolist()) <= corners
    # every coarse face has exactly four children
    np.testing.assert_array_equal(np.bincount(s.face_parent), np.full(len(f), 4))


def test_boundary_is_split_in_two():
    v, f = grid(3, 2)
    s = subdivide_midpoint(v, f)
    assert len(boundary_edges(s.faces)) == 2 * len(boundary_edges(f))


def test_upsample_carries_vertex_values():
    v, f = icosahedron()
    s = subdivide_midpoint(v, f)
    np.testing.assert_allclose(s.upsample(v), s.vertices, rtol=0, atol=1e-15)
    with pytest.raises(InputError, match="coarse vertex"):
        s.upsample(np.zeros(5))


def test_subdivide_uv_matches_positions_on_a_flat_mesh():
    # on a flat mesh whose UVs are its xy coordinates, subdivided UVs are the fine vertices' xy
    v, f = grid(3, 2, size=(1.0, 0.5))
    s = subdivide_midpoint(v, f)
    np.testing.assert_allclose(
        subdivide_uv(v[f][..., :2]), s.vertices[s.faces][..., :2], atol=1e-15
    )


def test_subdivide_uv_keeps_seams():
    # the shared edge (1, 2) carries different UVs in the two faces: its midpoint must too
    uv = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], [[5.0, 5.0], [7.0, 5.0], [5.0, 7.0]]])
    fine = subdivide_uv(uv)
    assert fine.shape == (8, 3, 2)
    # fine face j·F + f is child j of face f; child 3 is the middle one
    np.testing.assert_allclose(fine[3 * 2 + 0], [[0.5, 0.0], [0.5, 0.5], [0.0, 0.5]])
    np.testing.assert_allclose(fine[3 * 2 + 1], [[6.0, 5.0], [6.0, 6.0], [5.0, 6.0]])
    np.testing.assert_allclose(fine[1 * 2 + 1], [[6.0, 5.0], [7.0, 5.0], [6.0, 6.0]])


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_subdivide_uv_rejects_bad_shapes():
    with pytest.raises(InputError, match=r"\[F, 3, 2\]"):
        subdivide_uv(np.zeros((2, 3)))


def test_rescale_to_mean_edge():
    v, f = torus(8, 6)
    w, scale = rescale_to_mean_edge(v, f, target=0.25)
    assert np.isclose(mean_edge_length(w, f), 0.25, rtol=1e-13)
    np.testing.assert_allclose(w, v * scale, rtol=1e-15)
    # the single triangle: edges 1, 1, sqrt 2
    assert np.isclose(mean_edge_length(*single_triangle()), (2 + np.sqrt(2)) / 3, rtol=1e-15)
    with pytest.raises(InputError, match="positive"):
        rescale_to_mean_edge(v, f, target=0.0)
    with pytest.raises(InputError, match="zero length"):
        rescale_to_mean_edge(np.zeros((3, 3)), np.array([[0, 1, 2]]))


@given(nx=st.integers(1, 5), ny=st.integers(1, 5), uniform=st.booleans(), levels=st.integers(1, 2))
def test_flat_grids_property(nx, ny, uniform, levels):
    v, f = grid(nx, ny, diagonals="uniform" if uniform else "alternate")
    v0, f0 = v, f
    for _ in range(levels):
        v, f = subdivide_midpoint(v, f)[:2]
    assert len(v) == (nx * 2**levels + 1) * (ny * 2**levels + 1)
    assert np.isclose(0.5 * np.linalg.norm(_face_normals(v, f), axis=1).sum(), 1.0, rtol=1e-13)
    assert (_face_normals(v, f)[:, 2] > 0).all()
    # every fine edge is a coarse edge or a mid-line halved: the extreme lengths halve per level
    lengths = lambda v, f: np.linalg.norm(v[f] - v[np.roll(f, -1, axis=1)], axis=-1)  # noqa: E731
    for stat in (np.min, np.max):
        assert np.isclose(stat(lengths(v, f)) * 2**levels, stat(lengths(v0, f0)), rtol=1e-13)


@pytest.mark.parametrize(
    ("vertices", "faces", "error", "match"),
    [
        (np.zeros((4, 3)), np.array([[0, 1, 2, 3]]), NonTriangleFaceError, r"\[F, 3\]"),
        (np.eye(3), np.array([[0, 1, 3]]), FaceIndexError, "out of range"),
        (np.eye(3), np.array([[0, -1, 2]]), FaceIndexError, "out of range"),
        (
            np.array([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]]),
            np.array([[0, 1, 2]]),
            NonFiniteVertexError,
            "NaN",
        ),
        (np.zeros((0, 3)), np.zeros((0, 3), int), EmptyMeshError, "no vertices"),
        (np.eye(3)[:, :2], np.array([[0, 1, 2]]), InputError, r"\[V, 3\]"),
        (np.eye(3), np.array([[0.0, 1.0, 2.0]]), InputError, "integer"),
    ],
)
@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_bad_input_raises_typed_errors(vertices, faces, error, match):
    with pytest.raises(error, match=match):
        subdivide_midpoint(vertices, faces)

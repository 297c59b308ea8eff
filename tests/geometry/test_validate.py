"""validate_mesh, prepare_mesh and mesh_statistics: exact cases, a loop reference, real meshes."""

from __future__ import annotations

import json
import warnings
from collections import defaultdict

import numpy as np
import pytest

from jmeshtex import (
    DegenerateFaceError,
    DuplicateFaceError,
    EmptyMeshError,
    FaceIndexError,
    InconsistentOrientationError,
    InputError,
    Mesh,
    MeshError,
    MeshRepairWarning,
    NonFiniteVertexError,
    NonManifoldEdgeError,
    NonManifoldVertexError,
    NonTriangleFaceError,
)
from jmeshtex.data import grid, icosahedron, icosphere, single_triangle, torus
from jmeshtex.geometry import mesh_statistics, prepare_mesh, tracer_geometry, validate_mesh

# ------------------------------------------------------------------------------------------------
# an independent, slow reference: Python loops and dicts, written from the definitions
# ------------------------------------------------------------------------------------------------


def reference_first_error(v: np.ndarray, f: np.ndarray, area_tol: float = 1e-7):
    """(error class, sorted offending items) of the first failed check, or None; loops only."""
    degenerate = []
    for i, (a, b, c) in enumerate(f.tolist()):
        pa, pb, pc = v[a], v[b], v[c]
        lengths = [float(np.linalg.norm(q - p)) for p, q in ((pa, pb), (pb, pc), (pc, pa))]
        longest = max(lengths)
        if len({a, b, c}) < 3 or longest == 0:
            degenerate.append(i)
            continue
        # Heron's formula on the lengths over the longest, in Kahan's stable order
        x, y, z = sorted((length / longest for length in lengths), reverse=True)
        prod = (x + (y + z)) * (z - (x - y)) * (z + (x - y)) * (x + (y - z))
        if 2 * 0.25 * np.sqrt(max(prod, 0.0)) <= area_tol:
            degenerate.append(i)
    if degenerate:
        return DegenerateFaceError, degenerate
    seen, dups = {}, []
    for i, face in enumerate(f.tolist()):
        key = frozenset(face)
        if key in seen:
            dups.append((seen[key], i))
        else:
            seen[key] = i
    if dups:
        return DuplicateFaceError, dups
    halves = defaultdict(list)  # undirected edge -> directed traversals
    for face in f.tolist():
        for k in range(3):
            a, b = face[k], face[(k + 1) % 3]
            halves[(min(a, b), max(a, b))].append((a, b))
    over = sorted(e for e, h in halves.items() if len(h) > 2)
    if over:
        return NonManifoldEdgeError, over
    flipped = sorted(e for e, h in halves.items() if len(h) == 2 and h[0] == h[1])
    if flipped:
        return InconsistentOrientationError, flipped
    bowties = []
    for p in sorted(set(f.ravel().tolist())):
        incident = [i for i, face in enumerate(f.tolist()) if p in face]
        parent = {i: i for i in incident}

        def find(i, parent=parent):
            while parent[i] != i:
                i = parent[i]
            return i

        for i in incident:
            for j in incident:
                if len(set(f[i]) & set(f[j])) >= 2:  # share an edge through p
                    parent[find(i)] = find(j)
        if len({find(i) for i in incident}) > 1:
            bowties.append(p)
    if bowties:
        return NonManifoldVertexError, bowties
    return None


def _items(err: MeshError) -> list:
    idx = err.indices
    return [tuple(int(x) for x in row) for row in idx] if idx.ndim == 2 else [int(x) for x in idx]


def test_loop_reference_agrees_on_random_face_soups(rng):
    """Random faces over a few vertices hit every check; class and named items must agree."""
    hits = defaultdict(int)
    for _ in range(400):
        n_v = int(rng.integers(3, 8))
        v = rng.normal(size=(n_v, 3))
        v[rng.integers(0, n_v)] = v[0] if rng.random() < 0.2 else v[rng.integers(0, n_v)]
        f = rng.integers(0, n_v, (int(rng.integers(1, 7)), 3))
        if rng.random() < 0.5:  # mostly distinct corners, so the later checks are reached too
            f = np.array([rng.choice(n_v, 3, replace=False) for _ in range(len(f))])
        expected = reference_first_error(v, f)
        if expected is None:
            validate_mesh(v, f)
            hits["valid"] += 1
            continue
        with pytest.raises(expected[0]) as info:
            validate_mesh(v, f)
        assert type(info.value) is expected[0]
        assert sorted(_items(info.value)) == sorted(expected[1]), (v, f)
        hits[expected[0].__name__] += 1
    assert len(hits) >= 5, hits  # the soups reached most checks (all six, in practice)


# ------------------------------------------------------------------------------------------------
# validate_mesh: exact cases
# ------------------------------------------------------------------------------------------------

SQUARE_V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
SQUARE_F = np.array([[0, 1, 2], [0, 2, 3]])


def test_valid_meshes_of_every_kind_pass():
    for v, f in [
        single_triangle(),
        icosahedron(),
        icosphere(2),
        torus(6, 4),
        grid(3, 2),
        (SQUARE_V, SQUARE_F),
    ]:
        validate_mesh(v, f)
    # several components of different genus, an unreferenced vertex, int32 faces, a list input
    sv, sf = icosphere(1)
    tv, tf = torus(6, 4)
    v = np.concatenate([sv, tv + 5.0, [[9.0, 9.0, 9.0]]])
    f = np.concatenate([sf, tf + len(sv)]).astype(np.int32)
    validate_mesh(v, f)
    validate_mesh(v.tolist(), f.tolist())


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_shape_errors():
    v, f = icosahedron()
    with pytest.raises(InputError, match=r"shape \[V, 3\], got \(12, 2\)"):
        validate_mesh(v[:, :2], f)
    with pytest.raises(NonTriangleFaceError, match="4 corners") as info:
        validate_mesh(v, np.concatenate([f, f[:, :1]], axis=1))
    assert len(info.value.indices) == 20
    with pytest.raises(NonTriangleFaceError, match=r"reshape\(-1, 3\)"):
        validate_mesh(v, f.ravel())
    with pytest.raises(NonTriangleFaceError, match=r"\[4\] corners") as info:
        validate_mesh(v, [[0, 1, 2], [0, 2, 3, 4], [1, 2, 3]])
    assert _items(info.value) == [1]
    with pytest.raises(InputError, match="integer"):
        validate_mesh(v, f.astype(float))
    with pytest.raises(InputError, match="real numbers"):
        validate_mesh(v.astype(complex), f)


def test_index_errors_name_the_faces():
    v, f = icosahedron()
    f = f.copy()
    f[3, 1] = 12
    f[7, 0] = -1
    with pytest.raises(FaceIndexError, match=r"out of range \[0, 12\)") as info:
        validate_mesh(v, f)
    assert _items(info.value) == [3, 7]
    with pytest.raises(FaceIndexError):  # no vertices at all: indices fail before emptiness
        validate_mesh(np.zeros((0, 3)), [[0, 1, 2]])


def test_non_finite_vertices_named():
    v, f = icosahedron()
    v = v.copy()
    v[4, 2] = np.nan
    v[9, 0] = -np.inf
    with pytest.raises(NonFiniteVertexError) as info:
        validate_mesh(v, f)
    assert _items(info.value) == [4, 9]


def test_empty():
    with pytest.raises(EmptyMeshError, match="V=3, F=0"):
        validate_mesh(np.eye(3), np.zeros((0, 3), int))
    with pytest.raises(EmptyMeshError):
        validate_mesh(np.zeros((0, 3)), [])


def test_degenerate_faces_named():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]])
    with pytest.raises(DegenerateFaceError) as info:
        validate_mesh(v, [[0, 1, 3], [0, 1, 2], [1, 1, 3]])  # collinear, repeated index
    assert _items(info.value) == [1, 2]
    # collinear up to round-off: (0.1, 0.2, 0.3) lies on the line through 0 and (1, 2, 3) only
    # approximately in float64, and is still caught by the relative tolerance
    w = np.array([[0.0, 0, 0], [1, 2, 3], [0.1, 0.2, 0.3]])
    assert np.cross(w[1], w[2]).any()
    with pytest.raises(DegenerateFaceError):
        validate_mesh(w, [[0, 1, 2]])
    # a genuine needle of aspect ratio 1e6 is fine, and area_tol is honoured
    needle = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 1e-6, 0]])
    validate_mesh(needle, [[0, 1, 2]])
    with pytest.raises(DegenerateFaceError):
        validate_mesh(needle, [[0, 1, 2]], area_tol=1e-5)


def test_a_needle_the_tracer_rejects_is_degenerate_and_repair_drops_it():
    """One definition (``flat_faces``): a needle whose apex is 1e-9 off the line has a non-zero
    cross product, but its edge lengths round to 1, 0.5, 0.5 (zero area), which is all the tracer
    sees. Validation rejects it, repair drops it, and the repaired mesh traces."""
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 1e-9, 0], [0.5, -1, 0]])
    f = np.array([[0, 1, 2], [1, 0, 3]])
    assert np.cross(v[1] - v[0], v[2] - v[0])[2] > 1e-14  # not flat by the cross product
    with pytest.raises(DegenerateFaceError) as info:
        tracer_geometry(v, f)
    assert _items(info.value) == [0]
    with pytest.raises(DegenerateFaceError) as info:
        validate_mesh(v, f)
    assert _items(info.value) == [0]
    m, report = prepare_mesh((v, f), repair=True)
    assert report.dropped_degenerate_faces.tolist() == [0]
    assert np.array_equal(m.faces, [[1, 0, 2]])  # face 1, unused vertex 2 dropped
    tracer_geometry(m.vertices, m.faces)


@pytest.mark.parametrize("height_exponent", np.arange(-12.0, -4.0, 0.25))
def test_validation_and_the_tracer_agree_on_every_near_needle(height_exponent):
    """Apexes from 1e-12 to 1e-4 off the base line, at random positions along it and rotated in
    space: validate_mesh rejects a face exactly when tracer_geometry does."""
    rng = np.random.default_rng(int(-4 * height_exponent))
    f = np.array([[0, 1, 2]])
    for _ in range(20):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        apex = [rng.uniform(-0.2, 1.2), 10.0**height_exponent * rng.uniform(0.5, 2), 0.0]
        v = np.array([[0.0, 0, 0], [1, 0, 0], apex]) @ q.T * 10.0 ** rng.uniform(-3, 3)
        try:
            validate_mesh(v, f)
            by_validation = False
        except DegenerateFaceError:
            by_validation = True
        try:
            tracer_geometry(v, f)
            by_tracer = False
        except DegenerateFaceError:
            by_tracer = True
        assert by_validation == by_tracer, (v, by_validation, by_tracer)


def test_duplicate_faces_any_order():
    v, f = icosahedron()
    for perm in ([1, 2, 0], [2, 1, 0]):
        g = np.concatenate([f[:5], f[2:3, perm], f[5:]])
        with pytest.raises(DuplicateFaceError, match=r"\(first, repeat\)") as info:
            validate_mesh(v, g)
        assert _items(info.value) == [(2, 5)]


def test_non_manifold_edge_named():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]])
    with pytest.raises(NonManifoldEdgeError) as info:
        validate_mesh(v, [[0, 1, 2], [1, 0, 3], [1, 0, 4]])
    assert _items(info.value) == [(0, 1)]


def test_inconsistent_orientation_named():
    with pytest.raises(InconsistentOrientationError) as info:
        validate_mesh(SQUARE_V, [[0, 1, 2], [0, 3, 2]])
    assert _items(info.value) == [(0, 2)]


def test_bowtie_vertex_named():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [-1, 0, 0], [-1, -1, 0]])
    with pytest.raises(NonManifoldVertexError, match=r"prepare_mesh\(mesh, repair=True\)") as info:
        validate_mesh(v, [[0, 1, 2], [0, 3, 4]])
    assert _items(info.value) == [0]
    # two cones touching at their apex (closed fans on both sides) are a bow-tie too
    ring = np.array([[np.cos(t), np.sin(t), 0.0] for t in np.linspace(0, 2 * np.pi, 5)[:-1]])
    v = np.concatenate([[[0.0, 0, 0]], ring + [0, 0, 1], ring - [0, 0, 1]])
    f = [[0, 1 + k, 1 + (k + 1) % 4] for k in range(4)] + [
        [0, 5 + (k + 1) % 4, 5 + k] for k in range(4)
    ]
    with pytest.raises(NonManifoldVertexError) as info:
        validate_mesh(v, f)
    assert _items(info.value) == [0]


def test_checks_run_in_the_documented_order():
    """Each defect pair reports the earlier check, whichever face it sits in."""
    v, f = icosphere(1)

    def defect(kind, v, f):
        v, f = v.copy(), f.copy()
        if kind == "index":
            f[10, 0] = len(v) + 3
        elif kind == "finite":
            v[30, 1] = np.nan
        elif kind == "degenerate":
            v[f[50, 1]] = v[f[50, 0]]
        elif kind == "duplicate":
            f = np.concatenate([f, f[60:61, ::-1]])
        elif kind == "nm_edge":
            a, b = f[70, 0], f[70, 1]
            v = np.concatenate([v, [2 * v[a]]])
            f = np.concatenate([f, [[a, b, len(v) - 1]]])
        elif kind == "orientation":
            f[75] = f[75, ::-1]
        elif kind == "bowtie":
            v = np.concatenate([v, 2 * v[f[5, 0]] + [[0, 0, 0.3], [0, 0.3, 0]]])
            f = np.concatenate([f, [[f[5, 0], len(v) - 2, len(v) - 1]]])
        return v, f

    order = ["index", "finite", "degenerate", "duplicate", "nm_edge", "orientation", "bowtie"]
    errors = [
        FaceIndexError,
        NonFiniteVertexError,
        DegenerateFaceError,
        DuplicateFaceError,
        NonManifoldEdgeError,
        InconsistentOrientationError,
        NonManifoldVertexError,
    ]
    for i, first in enumerate(order):
        only = defect(first, v, f)
        with pytest.raises(errors[i]):
            validate_mesh(*only)
        for later in order[i + 1 :]:
            both = (
                defect(first, *defect(later, v, f))
                if later in ("nm_edge", "bowtie", "duplicate")
                else defect(later, *defect(first, v, f))
            )
            with pytest.raises(errors[i]):
                validate_mesh(*both)


def test_inputs_are_not_modified():
    v, f = icosahedron()
    v0, f0 = v.copy(), f.copy()
    validate_mesh(v, f)
    prepare_mesh((v, f), repair=True)
    assert np.array_equal(v, v0) and np.array_equal(f, f0)


# ------------------------------------------------------------------------------------------------
# prepare_mesh
# ------------------------------------------------------------------------------------------------


def test_prepare_valid_mesh_changes_nothing():
    v, f = torus(6, 4)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m, report = prepare_mesh((v, f), repair=True)
    assert not report.changed and "no changes" in str(report)
    assert np.array_equal(m.vertices, v) and np.array_equal(m.faces, f)
    assert m.split_faces is None and m.split_to_merged is None
    assert np.array_equal(report.vertex_index, np.arange(len(v)))
    assert np.array_equal(report.face_index, np.arange(len(f)))


def test_triangle_soup_is_merged_with_a_warning_and_split_maps():
    v, f = icosahedron()
    soup_v = v[f.ravel()]  # every face has its own three vertices
    soup_f = np.arange(60).reshape(20, 3)
    soup_v = np.concatenate([soup_v, [[5.0, 5.0, 5.0]]])  # and one unreferenced vertex
    with pytest.warns(MeshRepairWarning, match="removed 1 unreferenced vertices and merged 48"):
        m, report = prepare_mesh((soup_v, soup_f))
    assert m.num_vertices == 12
    assert report.unreferenced_vertices.tolist() == [60]
    assert len(report.merged_vertices) == 48
    # each merged vertex keeps its lowest input index; positions are exact copies
    assert np.array_equal(m.vertices, soup_v[report.vertex_index])
    assert np.array_equal(m.vertices[m.faces], soup_v[soup_f])
    # the input indexing is kept as the stored one
    assert np.array_equal(m.split_to_merged[m.split_faces], m.faces)
    assert np.array_equal(m.split_faces, soup_f)
    validate_mesh(m.vertices, m.faces)


def test_touching_parts_are_kept_apart():
    """Coincident vertices whose merge would pinch the surface are not merged."""
    v, f = icosphere(1)
    top = int(np.argmax(v[:, 2]))
    bottom = int(np.argmin(v[:, 2]))
    w = v - v[bottom] + v[top]  # a second sphere touching the first at one point
    both_v = np.concatenate([v, w])
    both_f = np.concatenate([f, f + len(v)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing merged: no warning
        m, report = prepare_mesh((both_v, both_f))
    assert report.kept_apart_vertices.tolist() == [top, len(v) + bottom]
    assert m.num_vertices == 2 * len(v) and not report.changed
    # three fins along one edge: merging their coincident edge would make it non-manifold
    fin_v = np.array(
        [
            [0.0, 0, 0],
            [1, 0, 0],
            [0.5, 1, 0],
            [0.0, 0, 0],
            [1, 0, 0],
            [0.5, 0, 1],
            [0.0, 0, 0],
            [1, 0, 0],
            [0.5, -1, -1],
        ]
    )
    fin_f = np.array([[0, 1, 2], [3, 4, 5], [6, 7, 8]])
    m, report = prepare_mesh((fin_v, fin_f))
    assert m.num_vertices == 9 and len(report.kept_apart_vertices) == 6
    # two sheets meeting along an edge form a manifold hinge: that seam is merged
    hinge_v = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 1, 0], [1, 0, 0], [0.0, 0, 0], [0.5, 0, 1]])
    with pytest.warns(MeshRepairWarning, match="merged 2"):
        m, _ = prepare_mesh((hinge_v, [[0, 1, 2], [3, 4, 5]]))
    assert m.faces.tolist() == [[0, 1, 2], [1, 0, 3]]


def test_repair_drops_degenerate_and_duplicate_faces():
    v, f = icosphere(1)
    extra_v = np.concatenate([v, [v[0]]])  # a coincident copy makes face (0, 1, 42) degenerate
    g = np.concatenate([f, f[[7]][:, [1, 2, 0]], f[[3]][:, ::-1]])
    with pytest.raises(DuplicateFaceError):
        prepare_mesh((v, g))
    m, report = prepare_mesh((v, g), repair=True)
    assert report.dropped_duplicate_faces.tolist() == [80, 81]
    assert np.array_equal(m.faces, f)
    h = np.concatenate([f, [[0, 1, 42]], [[5, 5, 5]]])
    with pytest.warns(MeshRepairWarning, match="merged 1 exactly coincident"):
        m, report = prepare_mesh((extra_v, h), repair=True)
    assert report.dropped_degenerate_faces.tolist() == [80, 81]
    assert report.merged_vertices.tolist() == [[42, 0]]
    assert np.array_equal(m.faces, f) and np.array_equal(m.vertices, v)
    with pytest.raises(EmptyMeshError, match="no faces left"):
        prepare_mesh((SQUARE_V, [[0, 1, 1], [2, 2, 3]]), repair=True)


def test_repair_orientation_open_majority_and_closed_outward():
    v, f = grid(4, 1)  # 8 faces in a strip
    g = f.copy()
    g[[2, 5]] = g[[2, 5]][:, ::-1]
    m, report = prepare_mesh((v, g), repair=True)
    assert report.flipped_faces.tolist() == [2, 5]
    assert np.array_equal(np.sort(m.faces, 1), np.sort(f, 1))
    validate_mesh(m.vertices, m.faces)
    normals = np.cross(v[m.faces[:, 1]] - v[m.faces[:, 0]], v[m.faces[:, 2]] - v[m.faces[:, 0]])
    assert (normals[:, 2] > 0).all()
    # a consistently but inward oriented sphere, with 3 faces flipped back: all made outward
    sv, sf = icosphere(1)
    inward = sf[:, ::-1].copy()
    inward[[0, 10, 20]] = sf[[0, 10, 20]]
    m, report = prepare_mesh((sv, inward), repair=True)
    assert len(report.flipped_faces) == 77
    assert np.array_equal(np.sort(m.faces, 1), np.sort(sf, 1))
    p = m.vertices[m.faces]
    volume = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6
    assert volume > 0
    # non-orientable: a Möbius strip cannot be repaired
    from jmeshtex.testing._strategies import _mobius_strip

    with pytest.raises(InconsistentOrientationError, match="non-orientable"):
        prepare_mesh(_mobius_strip(7, np.random.default_rng(0)), repair=True)


def test_repair_splits_bowties_and_keeps_attributes_consistent():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [-1, 0, 0], [-1, -1, 0]])
    f = np.array([[0, 1, 2], [0, 3, 4]])
    uv = np.arange(12.0).reshape(2, 3, 2) / 12
    colors = np.linspace(0, 1, 15).reshape(5, 3)
    mesh = Mesh(v, f, uv=uv, vertex_colors=colors)
    with pytest.raises(NonManifoldVertexError):
        prepare_mesh(mesh)
    m, report = prepare_mesh(mesh, repair=True)
    assert report.split_vertices.tolist() == [0]
    assert m.num_vertices == 6 and report.vertex_index.tolist() == [0, 1, 2, 3, 4, 0]
    assert np.array_equal(m.vertices[m.faces], v[f])
    assert np.array_equal(m.vertex_colors, colors[report.vertex_index])
    assert np.array_equal(m.uv, uv)
    validate_mesh(m.vertices, m.faces)
    # idempotent: the copies coincide, but merging them back would pinch the surface again
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        again, report2 = prepare_mesh(m, repair=True)
    assert not report2.changed and np.array_equal(again.faces, m.faces)


def test_repair_keeps_seams_and_corner_uvs_consistent():
    """Seam-split input + flips + a bow-tie: every corner keeps its (position, uv) pair."""
    v, f = grid(3, 2)
    stored_v = np.concatenate([v, v[[4, 5, 6, 7]]])  # vertices 12..15 duplicate 4..7 (a seam)
    split_f = f.copy()
    upper = v[f].mean(axis=1)[:, 1] > 0.5
    split_f[upper] = np.where(np.isin(f[upper], [4, 5, 6, 7]), f[upper] + 8, f[upper])
    uv = np.asarray(stored_v[split_f][..., :2]) * 0.5 + np.where(upper, 0.5, 0.0)[:, None, None]
    g = f.copy()
    g[[1, 2]] = g[[1, 2]][:, ::-1]
    split_g = split_f.copy()
    split_g[[1, 2]] = split_g[[1, 2]][:, ::-1]
    uv_g = uv.copy()
    uv_g[[1, 2]] = uv_g[[1, 2]][:, ::-1]
    mesh = Mesh(
        v, g, uv=uv_g, split_faces=split_g, split_to_merged=np.r_[np.arange(12), [4, 5, 6, 7]]
    )
    m, report = prepare_mesh(mesh, repair=True)
    assert report.flipped_faces.tolist() == [1, 2]
    assert np.array_equal(m.split_to_merged[m.split_faces], m.faces)
    pos = m.vertices[m.faces]
    for a in range(m.num_faces):
        src = report.face_index[a]
        for k in range(3):  # each output corner is one of its input face's corners, same uv
            match = np.nonzero((v[g[src]] == pos[a, k]).all(axis=1))[0]
            assert len(match) == 1 and np.array_equal(uv_g[src, match[0]], m.uv[a, k])
    assert len(m.split_to_merged) == 16  # the stored seam copies survive


def test_prepare_mesh_rejects_inconsistent_attributes():
    v, f = icosahedron()
    with pytest.raises(InputError, match="uv"):
        prepare_mesh(Mesh(v, f, uv=np.zeros((20, 3))))
    with pytest.raises(InputError, match="vertex_colors"):
        prepare_mesh(Mesh(v, f, vertex_colors=np.zeros((11, 3))))
    with pytest.raises(InputError, match="split_to_merged"):
        prepare_mesh(Mesh(v, f, split_faces=f, split_to_merged=np.roll(np.arange(12), 1)))
    with pytest.raises(InputError, match="together"):
        prepare_mesh(Mesh(v, f, split_faces=f))


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_prepare_mesh_rejects_what_is_no_mesh():
    with pytest.raises(InputError, match="pair"):
        prepare_mesh(icosahedron().vertices)


def test_report_str_lists_changes():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [-1, 0, 0], [-1, -1, 0], [7, 7, 7]])
    with pytest.warns(MeshRepairWarning):
        _, report = prepare_mesh((v, [[0, 1, 2], [0, 4, 3]]), repair=True)
    text = str(report)
    assert "unreferenced vertices: 1 (5)" in text
    assert "split bow-tie vertices, one copy per fan: 1 (0)" in text


# ------------------------------------------------------------------------------------------------
# mesh_statistics
# ------------------------------------------------------------------------------------------------


def _cylinder(n: int = 8, rows: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A grid rolled up: its last column is identified with the first (open, 2 loops, genus 0)."""
    v, f = grid(n, rows)
    ids = np.arange(len(v)).reshape(rows + 1, n + 1)
    ids[:, -1] = ids[:, 0]
    t = v[:, 0] * 2 * np.pi
    w = np.stack([np.cos(t), np.sin(t), v[:, 1]], 1)
    keep = np.unique(ids)
    remap = np.full(len(v), -1)
    remap[keep] = np.arange(len(keep))
    return w[keep], remap[ids.ravel()][f]


@pytest.mark.parametrize(
    "make, expected",
    [
        (
            lambda: icosphere(2),
            dict(components=1, boundary_loops=0, euler_characteristic=2, genus=0, closed=True),
        ),
        (
            lambda: torus(8, 5),
            dict(components=1, boundary_loops=0, euler_characteristic=0, genus=1, closed=True),
        ),
        (
            lambda: grid(3, 2),
            dict(
                components=1,
                boundary_loops=1,
                euler_characteristic=1,
                genus=0,
                closed=False,
                edges=23,
            ),
        ),
        (
            _cylinder,
            dict(components=1, boundary_loops=2, euler_characteristic=0, genus=0, closed=False),
        ),
        (
            lambda: (torus(8, 5).vertices, torus(8, 5).faces[1:]),
            dict(boundary_loops=1, euler_characteristic=-1, genus=1),
        ),
        (
            lambda: (
                np.concatenate([icosphere(1).vertices, torus(6, 4).vertices + 4]),
                np.concatenate([icosphere(1).faces, torus(6, 4).faces + 42]),
            ),
            dict(components=2, euler_characteristic=2, genus=1, closed=True),
        ),
    ],
    ids=["sphere", "torus", "grid", "cylinder", "torus-with-hole", "sphere+torus"],
)
def test_statistics_topology(make, expected):
    v, f = make()
    s = mesh_statistics((v, f))
    assert s.valid and s.error is None
    for key, value in expected.items():
        assert getattr(s, key) == value, key


def test_statistics_numbers_and_json():
    v, f = grid(2, 1, size=(2.0, 1.0), diagonals="uniform")  # unit squares, diagonals √2
    s = mesh_statistics(Mesh(v, f, vertex_colors=np.ones((6, 3)), name="sheet"))
    assert (s.vertices, s.faces, s.edges, s.boundary_edges) == (6, 4, 9, 6)
    assert s.mean_edge_length == pytest.approx((7 * 1.0 + 2 * np.sqrt(2)) / 9, rel=1e-12)
    assert s.bbox_min == (0.0, 0.0, 0.0) and s.bbox_max == (2.0, 1.0, 0.0)
    assert s.has_vertex_colors and not s.has_uv and not s.has_texture
    d = json.loads(json.dumps(s.to_dict()))
    assert d["bbox_max"] == [2.0, 1.0, 0.0] and d["name"] == "sheet" and d["valid"] is True
    assert "verdict" in str(s) and "valid" in str(s)


def test_statistics_of_invalid_meshes():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [-1, 0, 0], [-1, -1, 0]])
    s = mesh_statistics((v, [[0, 1, 2], [0, 3, 4]]))
    assert not s.valid and s.error_type == "NonManifoldVertexError" and s.genus is None
    assert s.components == 1 and s.boundary_loops == 1 and s.edges == 6
    s = mesh_statistics((np.full((3, 3), np.nan), [[0, 1, 2]]))
    assert s.error_type == "NonFiniteVertexError" and s.edges is None and s.bbox_min is None
    s = mesh_statistics((v, [[0, 1, 2, 3]]))
    assert s.error_type == "NonTriangleFaceError" and s.components is None
    assert "INVALID (NonTriangleFaceError)" in str(s)


# ------------------------------------------------------------------------------------------------
# real meshes (../shared/data)
# ------------------------------------------------------------------------------------------------


def _load_raw(path):
    import trimesh

    m = trimesh.load_mesh(str(path), process=False)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


@pytest.mark.shared_data
def test_suzanne_duplicate_face_hides_a_non_manifold_edge(shared_data):
    v, f = _load_raw(shared_data / "suzanne.obj")
    with pytest.raises(DuplicateFaceError) as info:  # duplicates are checked first
        validate_mesh(v, f)
    assert _items(info.value) == [(269, 270)]
    with pytest.raises(NonManifoldEdgeError, match=r"\(70, 138\)") as info:
        prepare_mesh((v, f), repair=True)  # dropping the duplicate leaves the non-manifold edge
    assert _items(info.value) == [(70, 138)]


@pytest.mark.shared_data
def test_teapot_open_several_components_valid_after_repair(shared_data):
    v, f = _load_raw(shared_data / "teapot.obj")
    with pytest.raises(NonManifoldVertexError):
        prepare_mesh((v, f))  # the merged seams leave one point where two parts touch
    with pytest.warns(MeshRepairWarning, match="merged 403"):
        m, report = prepare_mesh((v, f), repair=True)
    assert len(report.split_vertices) == 1 and not len(report.flipped_faces)
    s = mesh_statistics(m)
    assert s.valid and not s.closed and s.components == 4 and s.boundary_loops == 6


@pytest.mark.shared_data
def test_cow_has_one_bowtie(shared_data):
    v, f = _load_raw(shared_data / "cow.obj")
    with pytest.raises(NonManifoldVertexError) as info:
        validate_mesh(v, f)
    assert _items(info.value) == [253]
    m, _ = prepare_mesh((v, f), repair=True)
    assert m.num_vertices == len(v) + 1 and mesh_statistics(m).valid

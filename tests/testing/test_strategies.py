"""Hypothesis mesh strategies: valid meshes validate, each bad kind raises exactly its typed error."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jmeshtex import (
    EmptyMeshError,
    InputError,
    MeshError,
    MeshRepairWarning,
    NonManifoldVertexError,
)
from jmeshtex.geometry import mesh_statistics, prepare_mesh, validate_mesh
from jmeshtex.testing import BAD_MESH_KINDS, bad_meshes, valid_meshes


@given(mesh=valid_meshes())
def test_valid_meshes_pass_validation_and_need_no_repair(mesh):
    validate_mesh(mesh.vertices, mesh.faces)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no unreferenced or coincident vertices either
        out, report = prepare_mesh(mesh, repair=True)
    assert not report.changed and not len(report.kept_apart_vertices)
    np.testing.assert_array_equal(out.faces, mesh.faces)  # already outward / consistently oriented
    s = mesh_statistics(mesh)
    expected = {
        "icosphere": (True, 0, 0),
        "torus": (True, 1, 0),
        "grid": (False, 0, 1),
        "delaunay": (False, 0, 1),
    }
    assert (s.closed, s.genus, s.boundary_loops) == expected[mesh.name]
    assert s.components == 1


@given(mesh=valid_meshes(closed=True, min_vertices=10, max_vertices=60))
def test_closed_meshes_are_closed_outward_and_in_range(mesh):
    assert mesh.name in ("icosphere", "torus") and 10 <= mesh.num_vertices <= 60
    p = mesh.vertices[mesh.faces]
    assert np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() > 0  # outward


@given(mesh=valid_meshes(closed=False, max_vertices=30))
def test_open_meshes_are_open_and_in_range(mesh):
    assert mesh.name in ("grid", "delaunay") and mesh.num_vertices <= 30
    assert not mesh_statistics(mesh).closed


def test_strategy_arguments_are_checked():
    with pytest.raises(InputError, match="unknown mesh kinds"):
        valid_meshes(kinds=("cube",))
    with pytest.raises(InputError, match="between 13 and 14"):
        valid_meshes(kinds=("icosphere",), min_vertices=13, max_vertices=14)
    with pytest.raises(InputError, match="unknown bad-mesh kind"):
        bad_meshes("wobbly")


# ------------------------------------------------------------------------------------------------
# bad meshes: the typed error, the named indices really are bad, repair fixes what it can
# ------------------------------------------------------------------------------------------------


def _edge_faces(f: np.ndarray) -> dict:
    halves: dict = {}
    for face in f.tolist():
        for k in range(3):
            a, b = face[k], face[(k + 1) % 3]
            halves.setdefault((min(a, b), max(a, b)), []).append((a, b))
    return halves


def _named_items_are_bad(kind: str, err: MeshError, v, f) -> None:
    """Check the offending indices an error names against the definition (Python loops)."""
    idx = err.indices
    if kind in ("index_out_of_range", "negative_index"):
        for i in idx:
            assert any(x < 0 or x >= len(v) for x in f[i])
    elif kind == "non_finite":
        assert sorted(idx.tolist()) == sorted(np.nonzero(~np.isfinite(v).all(1))[0].tolist())
    elif kind == "degenerate_face":
        for i in idx:
            a, b, c = v[f[i]]
            assert np.linalg.norm(np.cross(b - a, c - a)) <= 1e-14 * max(
                np.sum((b - a) ** 2), np.sum((c - b) ** 2), np.sum((a - c) ** 2)
            )
    elif kind == "duplicate_face":
        for first, repeat in idx:
            assert first < repeat and set(f[first]) == set(f[repeat])
    elif kind == "non_manifold_edge":
        halves = _edge_faces(f)
        assert all(len(halves[tuple(e)]) > 2 for e in idx.tolist())
    elif kind == "inconsistent_orientation":
        halves = _edge_faces(f)
        for e in idx.tolist():
            h = halves[tuple(e)]
            assert len(h) == 2 and h[0] == h[1]
    elif kind == "non_manifold_vertex":
        for p in idx.tolist():
            incident = [set(face) for face in f.tolist() if p in face]
            fans = [{0}]
            for _ in incident:  # grow the first fan through shared edges
                fans[0] |= {
                    j
                    for j in range(len(incident))
                    for i in fans[0]
                    if len(incident[i] & incident[j]) >= 2
                }
            assert len(fans[0]) < len(incident)  # some incident face is unreachable: a bow-tie


REPAIRABLE = {  # kind -> the only kind of change repair may make to fix it
    "degenerate_face": "dropped_degenerate_faces",
    "duplicate_face": "dropped_duplicate_faces",
    "inconsistent_orientation": "flipped_faces",
    "non_manifold_vertex": "split_vertices",
}


@pytest.mark.unchecked  # ill-typed arguments on purpose (e.g. flat faces): validate_mesh's own typed errors
@pytest.mark.parametrize("kind", list(BAD_MESH_KINDS))
@settings(max_examples=15)
@given(data=st.data())
def test_each_bad_mesh_kind_raises_its_typed_error(kind, data):
    v, f = data.draw(bad_meshes(kind, max_vertices=60))
    error = BAD_MESH_KINDS[kind]
    with pytest.raises(error) as info:
        validate_mesh(v, f)
    assert type(info.value) is error  # the exact class, not a subclass or an IndexError
    f_arr = np.asarray(f) if not isinstance(f, list) else None
    if f_arr is not None and f_arr.ndim == 2 and f_arr.shape[1] == 3 and kind != "empty":
        _named_items_are_bad(kind, info.value, np.asarray(v), f_arr)
    if kind == "non_manifold_edge":  # the last fin is the only defect: without it all is valid
        validate_mesh(v, f_arr[:-1])
    # prepare_mesh without repair rejects it the same way
    with pytest.raises(error):
        prepare_mesh((v, f))
    # with repair: the repairable kinds come out valid (a Möbius strip stays non-orientable),
    # changed in the one way that fixes that kind and in no other
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MeshRepairWarning)
        try:
            out, report = prepare_mesh((v, f), repair=True)
        except MeshError as err:
            mobius = kind == "inconsistent_orientation" and "non-orientable" in str(err)
            nothing_left = kind == "degenerate_face" and isinstance(err, EmptyMeshError)
            assert kind not in REPAIRABLE or mobius or nothing_left, f"{kind}: {err}"
            return
    assert kind in REPAIRABLE
    validate_mesh(out.vertices, out.faces)
    changes = {name for name in REPAIRABLE.values() if len(getattr(report, name))}
    allowed = {REPAIRABLE[kind]}
    if kind == "duplicate_face":  # the first copy is kept; if it is the reversed one, it is flipped
        allowed.add("flipped_faces")
    if kind == "degenerate_face" and len(report.split_vertices):
        # dropping a sliver can leave a vertex whose fans met only through it: a bow-tie that
        # repair must then split; the split is allowed only where that really happened
        kept = np.delete(np.asarray(f), report.dropped_degenerate_faces, axis=0)
        with pytest.raises(NonManifoldVertexError) as bowtie:
            validate_mesh(v, kept)
        # compared by position: repair welds coincident vertices, so the index may be a twin's
        named = {tuple(p) for p in np.asarray(v)[bowtie.value.indices].tolist()}
        assert {tuple(p) for p in np.asarray(v)[report.split_vertices].tolist()} <= named
        allowed.add("split_vertices")
    assert REPAIRABLE[kind] in changes and changes <= allowed

"""Edge lengths, corner angles, face and vertex areas: exact cases, independent formulas, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from jmeshtex import (
    DegenerateFaceError,
    EmptyMeshError,
    FaceIndexError,
    NonFiniteVertexError,
    NonTriangleFaceError,
)
from jmeshtex.data import grid, icosahedron, icosphere, single_triangle
from jmeshtex.geometry import (
    corner_angles,
    edge_lengths,
    face_areas,
    one_ring_neighborhood,
    vertex_areas,
)


def _angles_from_positions(v, f):
    """Independent reference: atan2(|a×b|, a·b) from 3D edge vectors (no lengths involved)."""
    out = np.zeros(f.shape)
    for k in range(3):
        p, a, b = v[f[:, k]], v[f[:, (k + 1) % 3]], v[f[:, (k + 2) % 3]]
        e1, e2 = a - p, b - p
        out[:, k] = np.arctan2(np.linalg.norm(np.cross(e1, e2), axis=1), np.sum(e1 * e2, axis=1))
    return out


def test_single_triangle_exact():
    v, f = single_triangle()
    lengths = edge_lengths(v, f)
    np.testing.assert_allclose(lengths, [[1.0, np.sqrt(2.0), 1.0]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        corner_angles(lengths), [[np.pi / 2, np.pi / 4, np.pi / 4]], rtol=0, atol=1e-15
    )
    np.testing.assert_allclose(face_areas(lengths), [0.5], rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        vertex_areas(f, face_areas(lengths), 3), [1 / 6] * 3, rtol=0, atol=1e-15
    )


def test_regular_icosahedron_exact():
    v, f = icosahedron()
    lengths = edge_lengths(v, f)
    edge = 1.0 / np.sin(2 * np.pi / 5)  # circumradius 1
    np.testing.assert_allclose(lengths, edge, rtol=1e-14)
    np.testing.assert_allclose(corner_angles(lengths), np.pi / 3, rtol=0, atol=1e-14)
    area = np.sqrt(3) / 4 * edge**2
    np.testing.assert_allclose(face_areas(lengths), area, rtol=1e-14)
    np.testing.assert_allclose(vertex_areas(f, face_areas(lengths), 12), 5 * area / 3, rtol=1e-14)


def test_3_4_5_and_equilateral():
    np.testing.assert_allclose(
        face_areas(np.array([[3.0, 4.0, 5.0], [2.0, 2.0, 2.0]])), [6.0, np.sqrt(3)], rtol=1e-15
    )
    # corner k faces edge k+1: in (3, 4, 5) the right angle (opposite 5) is corner 1
    np.testing.assert_allclose(
        corner_angles(np.array([[3.0, 4.0, 5.0]])),
        [[np.arctan2(4, 3), np.pi / 2, np.arctan2(3, 4)]],
        atol=1e-15,
    )


@given(st.integers(0, 2**32 - 1))
def test_angles_and_areas_match_position_formulas(seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(30, 3))
    f = rng.integers(0, 30, size=(40, 3))
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    lengths = edge_lengths(v, f)
    ref = _angles_from_positions(v, f)
    np.testing.assert_allclose(corner_angles(lengths), ref, rtol=0, atol=1e-10)
    np.testing.assert_allclose(corner_angles(lengths).sum(axis=1), np.pi, rtol=0, atol=1e-12)
    cross = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    np.testing.assert_allclose(face_areas(lengths), cross, rtol=1e-9, atol=1e-14)


def test_needle_and_flat_triangles_stay_accurate_and_finite():
    # a needle: the law of cosines loses ~8 digits at angle 1e-8, the half-angle form does not
    eps = 1e-8
    v = np.array([[0.0, 0, 0], [1, 0, 0], [1, eps, 0]])
    f = np.array([[0, 1, 2]])
    got = corner_angles(edge_lengths(v, f))
    np.testing.assert_allclose(got, _angles_from_positions(v, f), rtol=1e-7)
    np.testing.assert_allclose(got[0, 0], np.arctan(eps), rtol=1e-7)
    # lengths violating the triangle inequality clip to 0 / π, never NaN
    bad = corner_angles(np.array([[1.0, 1.0, 3.0]]))
    assert np.all(np.isfinite(bad)) and np.isclose(bad.sum(), np.pi)
    assert face_areas(np.array([[1.0, 1.0, 3.0], [1.0, 2.0, 3.0]])).tolist() == [0.0, 0.0]


def test_vertex_areas_sum_to_total_and_match_the_neighborhood():
    v, f = icosphere(2)
    areas = face_areas(edge_lengths(v, f))
    va = vertex_areas(f, areas, len(v))
    assert np.isclose(va.sum(), areas.sum(), rtol=1e-13)
    np.testing.assert_allclose(one_ring_neighborhood(v, f).area, va, rtol=1e-14)
    # the flat unit square: total area 1 exactly, corners of the alternate grid get 1/6 or 1/3 of a cell
    v, f = grid(1)
    va = vertex_areas(f, face_areas(edge_lengths(v, f)), 4)
    np.testing.assert_allclose(sorted(va), [1 / 6, 1 / 6, 1 / 3, 1 / 3], rtol=1e-14)


@pytest.mark.parametrize(
    "vertices, faces, error",
    [
        (np.zeros((0, 3)), np.zeros((0, 3), int), EmptyMeshError),
        (np.eye(3), np.array([[0, 1, 2, 0]]), NonTriangleFaceError),
        (np.eye(3), np.array([[0, 1, 3]]), FaceIndexError),
        (
            np.array([[0.0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]),
            np.array([[0, 1, 2]]),
            NonFiniteVertexError,
        ),
        (np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]), np.array([[0, 1, 2]]), DegenerateFaceError),
    ],
)
@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_bad_input_raises_typed_errors(vertices, faces, error):
    with pytest.raises(error):
        one_ring_neighborhood(vertices, faces)

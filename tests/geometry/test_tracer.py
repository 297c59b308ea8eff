"""Tests of the exp-map tracer: exact flat cases, isometry invariance, oracles, edge cases."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from jmeshtex import InputError
from jmeshtex import geometry as G
from jmeshtex.data import grid, icosphere, torus
from jmeshtex.geometry import (
    face_frame_to_world,
    one_rings,
    trace_from_vertices,
    trace_geodesics,
    tracer_geometry,
)


def _start_points(v, f, face, bary):
    return np.einsum("nk,nkd->nd", bary, v[f[face]])


def _random_starts(rng, f, n):
    face = rng.integers(0, len(f), n)
    bary = rng.dirichlet([2.0, 2.0, 2.0], n)
    direction = np.exp(1j * rng.uniform(0, 2 * np.pi, n))
    return face, bary, direction


def _fold(v: np.ndarray, sel: np.ndarray, x0: float, angle: float) -> np.ndarray:
    """Rigidly rotate the vertices ``sel`` about the line x = x0, z = 0 (along y)."""
    out = v.copy()
    dx, dz = v[sel, 0] - x0, v[sel, 2]
    c, s = np.cos(angle), np.sin(angle)
    out[sel, 0] = x0 + c * dx - s * dz
    out[sel, 2] = s * dx + c * dz
    return out


def _cut_sphere():
    """An icosphere with a cap removed: an open, curved mesh with boundary vertices."""
    v, f = icosphere(2)
    keep = v[f].mean(axis=1)[:, 2] < 0.55
    f = f[keep]
    used = np.unique(f)
    remap = np.full(len(v), -1)
    remap[used] = np.arange(len(used))
    return v[used], remap[f]


def _reference_log_maps(v, f):
    """log_p(q) for every vertex p and one-ring slot, with plain loops (independent of the tracer).

    Angles: law of cosines per wedge, accumulated counter-clockwise from slot 0, scaled to sum to 2π
    at interior vertices (DESIGN.md); radius: edge length.
    """
    rings = one_rings(f, len(v))
    out = []
    for p in range(len(v)):
        deg = int(rings.degree[p])
        ring = rings.ring[p, :deg]
        n_wedges = deg - 1 if rings.boundary[p] else deg
        angles = []
        for j in range(n_wedges):
            a, b = ring[j], ring[(j + 1) % deg]
            la, lb = np.linalg.norm(v[a] - v[p]), np.linalg.norm(v[b] - v[p])
            lab = np.linalg.norm(v[a] - v[b])
            cos = (la * la + lb * lb - lab * lab) / (2 * la * lb)
            angles.append(np.arccos(min(1.0, max(-1.0, cos))))
        total = sum(angles)
        scale = 1.0 if rings.boundary[p] else 2 * np.pi / total
        theta = 0.0
        for j in range(deg):
            q = ring[j]
            out.append((p, q, np.linalg.norm(v[q] - v[p]) * np.exp(1j * theta * scale)))
            if j < n_wedges:
                theta += angles[j]
    p, q, log = zip(*out, strict=True)
    return np.array(p), np.array(q), np.array(log)


# ------------------------------------------------------------------------------------------------
# flat sheets: exact answers


@pytest.mark.parametrize("diagonals", ["alternate", "uniform"])
def test_straight_lines_on_a_flat_grid(rng, diagonals):
    v, f = grid(6, 5, size=(1.0, 0.8), diagonals=diagonals)
    face, bary, direction = _random_starts(rng, f, 400)
    length = rng.uniform(0.0, 0.6, 400)
    r = trace_geodesics(v, f, face, bary, direction, length)
    start = _start_points(v, f, face, bary)
    w = face_frame_to_world(v, f, face, direction)
    expected = start + length[:, None] * w
    inside = np.all((expected[:, :2] > 1e-9) & (expected[:, :2] < [1 - 1e-9, 0.8 - 1e-9]), axis=1)
    assert inside.sum() > 100 and (~inside).sum() > 20
    # walks that stay on the sheet end exactly where the straight line does, with the same heading
    np.testing.assert_allclose(r.point[inside], expected[inside], atol=1e-12)
    np.testing.assert_allclose(r.travelled[inside], length[inside], atol=1e-12)
    assert not r.stopped[inside].any()
    end_w = face_frame_to_world(v, f, r.face, r.direction)
    np.testing.assert_allclose(end_w, w, atol=1e-12)
    # the rest stop on the border, on the same line, after the distance to the border
    out = ~inside
    assert r.stopped[out].all()
    np.testing.assert_allclose(
        r.point[out], start[out] + r.travelled[out, None] * w[out], atol=1e-12
    )
    on_border = np.min(
        np.abs(np.concatenate([r.point[out, :2], r.point[out, :2] - [1.0, 0.8]], 1)), 1
    )
    np.testing.assert_allclose(on_border, 0.0, atol=1e-12)
    assert np.all(r.travelled[out] < length[out])
    # the end point is really inside the end face
    np.testing.assert_allclose(_start_points(v, f, r.face, r.bary), r.point, atol=1e-12)
    assert r.bary.min() >= 0.0
    np.testing.assert_allclose(r.bary.sum(1), 1.0, atol=1e-14)


_GRID = grid(4, diagonals="alternate")
_GRID_TABLES = tracer_geometry(*_GRID)


@given(
    face=st.integers(0, _GRID.num_faces - 1),
    weights=st.tuples(*[st.sampled_from([0.0, 0.5, 1.0]) | st.floats(0.0, 1.0)] * 3).filter(
        lambda w: sum(w) > 0.1
    ),
    angle=st.sampled_from(np.arange(8) * np.pi / 4) | st.floats(0.0, 2 * np.pi),
    length=st.sampled_from([0.0, 0.25, 0.5**0.5]) | st.floats(0.0, 1.6),
)
def test_straight_lines_on_a_flat_grid_property(face, weights, angle, length):
    """Any start (corners, edges, boundary), any heading (along mesh lines, through vertices)."""
    v, f = _GRID
    bary = np.array([weights]) / sum(weights)
    d = np.array([np.exp(1j * angle)])
    r = trace_geodesics(v, f, np.array([face]), bary, d, np.array([length]), geometry=_GRID_TABLES)
    start = _start_points(v, f, np.array([face]), bary)[0]
    w = face_frame_to_world(v, f, np.array([face]), d)[0]
    travelled = r.travelled[0]
    assert 0.0 <= travelled <= length + 1e-15
    np.testing.assert_allclose(r.point[0], start + travelled * w, atol=1e-12)
    np.testing.assert_allclose(_start_points(v, f, r.face, r.bary)[0], r.point[0], atol=1e-12)
    end = start + length * w
    if np.all((end[:2] > 1e-9) & (end[:2] < 1 - 1e-9)):
        assert not r.stopped[0] and travelled == length
    if r.stopped[0]:
        assert travelled < length
        assert min(np.abs(r.point[0, :2]).min(), np.abs(r.point[0, :2] - 1).min()) < 1e-12
    else:
        assert travelled == length


def test_boundary_stop_distances_are_exact():
    """From the centre of a unit square, the four axis directions hit the border at distance 0.5."""
    v, f = grid(4, diagonals="uniform")
    g = tracer_geometry(v, f)
    centre = 12  # vertex (0.5, 0.5)
    angles = np.linspace(0.0, 2 * np.pi, 16, endpoint=False)
    # the vertex frame's x-axis is the edge to ring slot 0; directions relative to the world +x
    rings = one_rings(f)
    x_axis = v[rings.ring[centre, 0]] - v[centre]
    alpha = np.arctan2(x_axis[1], x_axis[0])
    r = trace_from_vertices(
        v, f, np.full(16, centre), np.exp(1j * (angles - alpha)), 2.0, geometry=g
    )
    assert r.stopped.all()
    expected = 0.5 / np.maximum(np.abs(np.cos(angles)), np.abs(np.sin(angles)))
    np.testing.assert_allclose(r.travelled, expected, atol=1e-12)
    heading = np.stack([np.cos(angles), np.sin(angles), 0 * angles], 1)
    np.testing.assert_allclose(r.point, v[centre] + expected[:, None] * heading, atol=1e-12)


def test_walks_through_vertices_and_along_edges_are_exact():
    """Straight lines through vertices (diagonals) and along mesh lines, on an exact grid."""
    v, f = grid(4, diagonals="uniform")  # spacing 0.25
    rings = one_rings(f)
    p = 7  # vertex (0.5, 0.25)
    x_axis = v[rings.ring[p, 0]] - v[p]
    alpha = np.arctan2(x_axis[1], x_axis[0])
    angles = np.array([0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75]) * np.pi
    length = np.full(8, 0.3)
    r1 = trace_from_vertices(v, f, np.full(8, p), np.exp(1j * (angles - alpha)), length)
    r2 = trace_from_vertices(v, f, np.full(8, p), np.exp(1j * (angles - alpha)), length)
    heading = np.stack([np.cos(angles), np.sin(angles), 0 * angles], 1)
    expected = v[p] + np.minimum(length, r1.travelled)[:, None] * heading
    np.testing.assert_allclose(r1.point, expected, atol=1e-12)
    # going down (y = 0.25 → 0) stops after 0.25; diagonals down stop at the border too
    np.testing.assert_array_equal(r1.stopped, heading[:, 1] * 0.3 < -0.25 + 1e-12)
    for a, b in zip(r1, r2, strict=True):  # deterministic
        np.testing.assert_array_equal(a, b)


def test_zero_length_returns_the_start():
    v, f = grid(3)
    face = np.array([0, 5, 7])
    bary = np.array([[0.2, 0.3, 0.5], [1.0, 0.0, 0.0], [0.0, 0.5, 0.5]])
    r = trace_geodesics(v, f, face, bary, np.array([1j, 0, -1]), np.zeros(3))
    np.testing.assert_array_equal(r.face, face)
    np.testing.assert_allclose(r.bary, bary, atol=1e-15)
    np.testing.assert_allclose(r.point, _start_points(v, f, face, bary), atol=1e-15)
    np.testing.assert_array_equal(r.travelled, 0.0)
    assert not r.stopped.any()
    np.testing.assert_allclose(r.direction, [1j, 0, -1], atol=1e-15)
    rv = trace_from_vertices(v, f, np.array([0, 5]), np.array([0, 1j]), 0.0)
    np.testing.assert_allclose(rv.point, v[[0, 5]], atol=1e-15)
    assert not rv.stopped.any()


# ------------------------------------------------------------------------------------------------
# intrinsic: folding the sheet along a mesh line changes nothing


def test_fold_leaves_traces_unchanged(rng):
    v, f = grid(8, diagonals="alternate")
    # a bumpy sheet, flat on the two hinge columns x = 0.25 and x = 0.5 (mesh lines)
    hinge = np.isclose(v[:, 0], 0.25) | np.isclose(v[:, 0], 0.5)
    v[:, 2] = np.where(hinge, 0.0, 0.02 * rng.standard_normal(len(v)))
    x = v[:, 0]
    folded = _fold(v, x > 0.5 + 1e-9, 0.5, 1.1)
    folded = _fold(folded, x > 0.25 + 1e-9, 0.25, 0.6)
    # the folds are isometries: every edge length is unchanged
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    np.testing.assert_allclose(
        np.linalg.norm(folded[e[:, 0]] - folded[e[:, 1]], axis=1),
        np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1),
        atol=1e-14,
    )
    assert np.abs(folded - v).max() > 0.3
    face, bary, direction = _random_starts(rng, f, 300)
    length = rng.uniform(0.0, 0.9, 300)
    a = trace_geodesics(v, f, face, bary, direction, length)
    b = trace_geodesics(folded, f, face, bary, direction, length)
    np.testing.assert_array_equal(a.face, b.face)
    np.testing.assert_allclose(a.bary, b.bary, atol=1e-12)
    np.testing.assert_allclose(a.direction, b.direction, atol=1e-12)
    np.testing.assert_allclose(a.travelled, b.travelled, atol=1e-12)
    np.testing.assert_array_equal(a.stopped, b.stopped)
    np.testing.assert_allclose(b.point, _start_points(folded, f, b.face, b.bary), atol=1e-14)
    vert = rng.integers(0, len(v), 200)
    dv = np.exp(1j * rng.uniform(0, 2 * np.pi, 200))
    a = trace_from_vertices(v, f, vert, dv, length[:200])
    b = trace_from_vertices(folded, f, vert, dv, length[:200])
    np.testing.assert_array_equal(a.face, b.face)
    np.testing.assert_allclose(a.bary, b.bary, atol=1e-12)


# ------------------------------------------------------------------------------------------------
# exp ∘ log = id on one-rings (the key consistency with the log maps)


@pytest.mark.parametrize(
    "mesh",
    [
        lambda: icosphere(1),
        lambda: torus(8, 6),
        lambda: grid(3, diagonals="alternate"),
        _cut_sphere,
    ],
    ids=["icosphere", "torus", "grid", "cut-sphere"],
)
def test_exp_of_log_is_the_neighbour(mesh):
    v, f = mesh()
    p, q, log = _reference_log_maps(v, f)
    r = trace_from_vertices(v, f, p, log, np.abs(log))
    assert not r.stopped.any()
    np.testing.assert_allclose(r.travelled, np.abs(log), atol=1e-14)
    # the end point is vertex q: its corner of the end face carries barycentric weight 1
    corner = np.argmax(f[r.face] == q[:, None], axis=1)
    assert np.all(f[r.face, corner] == q)
    np.testing.assert_allclose(r.bary[np.arange(len(q)), corner], 1.0, atol=1e-12)
    np.testing.assert_allclose(r.point, v[q], atol=1e-12)


@pytest.mark.parametrize("mesh", [lambda: torus(8, 6), _cut_sphere], ids=["torus", "cut-sphere"])
def test_exp_of_log_with_the_log_map_module(mesh):
    """One source of truth: the logs of `one_ring_neighborhood` land exactly on their neighbours."""
    v, f = mesh()
    nb = G.one_ring_neighborhood(v, f, scale=None)  # mesh units: traced lengths
    p, k = np.nonzero(nb.mask)
    q, log = nb.index[p, k], nb.log[p, k]
    # and they agree with the loop reference above
    rp, rq, rlog = _reference_log_maps(v, f)
    np.testing.assert_array_equal(rq, q)
    np.testing.assert_allclose(rlog, log, atol=1e-12)
    r = trace_from_vertices(v, f, p, log, np.abs(log))
    assert not r.stopped.any()
    np.testing.assert_allclose(r.point, v[q], atol=1e-12)
    corner = np.argmax(f[r.face] == q[:, None], axis=1)
    np.testing.assert_allclose(r.bary[np.arange(len(q)), corner], 1.0, atol=1e-12)


# ------------------------------------------------------------------------------------------------
# curved surfaces: oracles and convergence


def test_agrees_with_potpourri3d(rng):
    import potpourri3d as pp3d

    v, f = icosphere(3)
    v = v * np.array([1.0, 0.8, 1.2])  # not a symmetric surface
    face, bary, direction = _random_starts(rng, f, 60)
    length = rng.uniform(0.05, 0.6, 60)
    r = trace_geodesics(v, f, face, bary, direction, length)
    tracer = pp3d.GeodesicTracer(v, f)
    w = face_frame_to_world(v, f, face, direction) * length[:, None]
    ends = np.array(
        [
            tracer.trace_geodesic_from_face(int(a), b, c)[-1]
            for a, b, c in zip(face, bary, w, strict=True)
        ]
    )
    # both unfold the same polyhedral surface exactly; observed ~3e-15
    np.testing.assert_allclose(r.point, ends, atol=1e-9)


def test_great_circles_on_a_sphere_return_with_refinement(rng):
    face_rng = np.random.default_rng(rng.integers(2**31))
    errors = []
    for level in (2, 3, 4):
        v, f = icosphere(level)
        face, bary, direction = _random_starts(face_rng, f, 40)
        r = trace_geodesics(v, f, face, bary, direction, 2 * np.pi)
        assert not r.stopped.any()
        errors.append(np.linalg.norm(r.point - _start_points(v, f, face, bary), axis=1).mean())
    # halving the edge length divides the return error by ~3 (observed 3.1, 2.9)
    assert errors[0] / errors[1] > 2.0 and errors[1] / errors[2] > 2.0, errors
    assert errors[-1] < 0.02


def test_continuing_a_walk_equals_one_longer_walk(rng):
    v, f = torus(12, 8)
    face, bary, direction = _random_starts(rng, f, 100)
    a, b = rng.uniform(0.0, 0.5, 100), rng.uniform(0.0, 0.5, 100)
    whole = trace_geodesics(v, f, face, bary, direction, a + b)
    first = trace_geodesics(v, f, face, bary, direction, a)
    second = trace_geodesics(v, f, first.face, first.bary, first.direction, b)
    np.testing.assert_allclose(second.point, whole.point, atol=1e-12)
    np.testing.assert_allclose(
        face_frame_to_world(v, f, second.face, second.direction),
        face_frame_to_world(v, f, whole.face, whole.direction),
        atol=1e-10,
    )


def test_geometry_reuse_and_scalar_length_give_the_same_result(rng):
    v, f = torus(10, 6)
    g = tracer_geometry(v, f)
    face, bary, direction = _random_starts(rng, f, 50)
    a = trace_geodesics(v, f, face, bary, direction, np.full(50, 0.4))
    b = trace_geodesics(v, f, face, bary, direction, 0.4, geometry=g)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


# ------------------------------------------------------------------------------------------------
# boundary vertices and bad input


def test_directions_off_the_surface_at_a_boundary_vertex_stop_at_once():
    v, f = grid(2)
    corner = 0  # (0, 0): a quarter-plane corner, angle sum π/2
    r = trace_from_vertices(
        v,
        f,
        np.array([corner] * 3),
        np.exp(1j * np.array([0.2, 2.0, 5.0])),
        np.array([0.3, 0.3, 0.0]),
    )
    np.testing.assert_array_equal(r.stopped, [False, True, False])
    np.testing.assert_array_equal(r.travelled, [0.3, 0.0, 0.0])
    np.testing.assert_allclose(r.point[1:], v[[corner, corner]], atol=1e-15)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(start_face=np.array([99])), "start_face out of range"),
        (dict(start_face=np.array([0.0])), "integer"),
        (dict(start_bary=np.array([[0.5, 0.6, 0.2]])), "barycentric"),
        (dict(start_bary=np.array([[0.5, 0.5]])), "shape"),
        (dict(length=np.array([-1.0])), "length must be finite and >= 0"),
        (dict(length=np.array([np.nan])), "length must be finite"),
        (dict(direction=np.array([0j])), "direction is zero"),
        (dict(direction=np.array([np.nan + 0j])), "direction must be finite"),
        (dict(direction=np.array([1j, 1j])), "entries"),
        (dict(max_steps=1, length=np.array([5.0])), "max_steps"),
    ],
)
@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_trace_geodesics_rejects_bad_input(kwargs, match):
    v, f = torus(6, 4)
    args = dict(
        start_face=np.array([0]),
        start_bary=np.array([[0.2, 0.3, 0.5]]),
        direction=np.array([1j]),
        length=np.array([0.5]),
    )
    max_steps = kwargs.pop("max_steps", None)
    args.update(kwargs)
    with pytest.raises(InputError, match=match):
        trace_geodesics(v, f, **args, max_steps=max_steps)


def test_trace_from_vertices_rejects_bad_input():
    v, f = grid(2)
    with pytest.raises(InputError, match="vertex out of range"):
        trace_from_vertices(v, f, np.array([9]), np.array([1j]), 0.1)
    v_extra = np.concatenate([v, [[5.0, 5.0, 5.0]]])
    with pytest.raises(InputError, match="belong to no face"):
        trace_from_vertices(v_extra, f, np.array([9]), np.array([1j]), 0.1)
    with pytest.raises(InputError, match="different mesh"):
        trace_from_vertices(
            v, f[:4], np.array([0]), np.array([1j]), 0.1, geometry=tracer_geometry(v, f)
        )


def test_degenerate_faces_are_rejected():
    from jmeshtex import DegenerateFaceError

    v = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]])
    with pytest.raises(DegenerateFaceError, match=r"\(count 1: 0\)"):
        tracer_geometry(v, np.array([[0, 1, 2], [0, 3, 1]]))

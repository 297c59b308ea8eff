"""Tests of the UV-atlas rasteriser: exact small layouts, slow per-texel references, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from jmeshtex import InputError
from jmeshtex.geometry import Raster, fill_unused_texels, rasterize_uv

# the unit square split along its diagonal u = v (one triangle counter-clockwise, one clockwise)
SQUARE = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]], [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0]]])


def _centres(row, col, size):
    """``(u, v)`` of texel centres, written from the documented convention."""
    return np.stack([(col + 0.5) / size, 1.0 - (row + 0.5) / size], axis=-1)


def _pairs(r: Raster) -> set[tuple[int, int, int]]:
    return set(zip(r.face.tolist(), r.row.tolist(), r.col.tolist(), strict=True))


def _loop_center(uv, size):
    """Slow reference: every texel centre against every triangle (signed areas, 1e-9 tolerance)."""
    out = {}
    for f, (a, b, c) in enumerate(uv):
        area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        for row in range(size):
            for col in range(size):
                p = _centres(np.array(row), np.array(col), size)
                w = []
                for q, s in ((b, c), (c, a), (a, b)):  # weight of the corner opposite edge (q, s)
                    w.append(((q[0] - p[0]) * (s[1] - p[1]) - (q[1] - p[1]) * (s[0] - p[0])) / area)
                if min(w) >= -1e-9:
                    out[(f, row, col)] = np.array(w)
    return out


def _clip_area(tri, x0, y0):
    """Area of triangle ``tri`` (texel plane) inside the square ``[x0, x0+1] × [y0, y0+1]``
    (Sutherland–Hodgman clipping against the square's four half-planes)."""
    poly = [tuple(p) for p in tri]
    for axis, bound, keep_below in (
        (0, x0, False),
        (0, x0 + 1, True),
        (1, y0, False),
        (1, y0 + 1, True),
    ):

        def inside(p, axis=axis, bound=bound, keep_below=keep_below):
            return p[axis] <= bound if keep_below else p[axis] >= bound

        out = []
        for i in range(len(poly)):
            p, q = poly[i], poly[(i + 1) % len(poly)]
            if inside(p):
                out.append(p)
            if inside(p) != inside(q):
                t = (bound - p[axis]) / (q[axis] - p[axis])
                out.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
        poly = out
        if not poly:
            return 0.0
    xs, ys = np.array(poly).T
    return 0.5 * abs(np.dot(xs, np.roll(ys, -1)) - np.dot(ys, np.roll(xs, -1)))


def _closest_point(tri, x):
    """Closest point of a triangle to a point ``x`` outside it: the nearest of the three edges'
    clamped orthogonal projections, and its distance."""
    best, best_d = None, np.inf
    for k in range(3):
        a, b = tri[k], tri[(k + 1) % 3]
        t = np.clip(np.dot(x - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
        q = a + t * (b - a)
        if np.linalg.norm(q - x) < best_d:
            best, best_d = q, np.linalg.norm(q - x)
    return best, best_d


@pytest.mark.parametrize("size", [1, 2, 5, 8])
def test_two_triangles_cover_the_unit_square(size):
    r = rasterize_uv(SQUARE, size)
    count = np.zeros((size, size), int)
    np.add.at(count, (r.row, r.col), 1)
    rows, cols = np.mgrid[0:size, 0:size]
    # centres on the diagonal u = v (row + col = size − 1) belong to both triangles, all others to one
    np.testing.assert_array_equal(count, np.where(rows + cols == size - 1, 2, 1))
    # the face is the one on the centre's side of the diagonal
    u, v = _centres(r.row, r.col, size).T
    assert ((r.face == 0) <= (u >= v - 1e-12)).all() and ((r.face == 1) <= (u <= v + 1e-12)).all()
    # barycentrics reproduce the texel centres
    np.testing.assert_allclose(
        np.einsum("nk,nkd->nd", r.bary, SQUARE[r.face]), _centres(r.row, r.col, size), atol=1e-12
    )
    np.testing.assert_array_equal(r.distance, 0.0)
    # the diagonal crosses exactly the squares whose centre it holds: "overlap" gives the same set
    o = rasterize_uv(SQUARE, size, coverage="overlap")
    assert _pairs(o) == _pairs(r)
    np.testing.assert_allclose(o.bary, r.bary, atol=1e-12)


def test_exact_barycentrics_and_dtypes():
    uv = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]])
    r = rasterize_uv(uv, 4)
    # centres with u + v <= 1: rows 0..3 from the top hold 1, 2, 3, 4 texels, and 4 on the diagonal
    assert sorted(zip(r.row.tolist(), r.col.tolist(), strict=True)) == [
        (j, i) for j in range(4) for i in range(j + 1)
    ]
    k = np.nonzero((r.row == 2) & (r.col == 1))[0][0]  # centre (3/8, 3/8)
    np.testing.assert_allclose(r.bary[k], [0.25, 0.375, 0.375], atol=1e-15)
    assert r.face.dtype == r.row.dtype == r.col.dtype == np.int64
    assert r.bary.dtype == r.distance.dtype == np.float64
    # integer UVs are accepted (the whole atlas: every centre inside, the diagonal shared)
    assert len(rasterize_uv(np.array([[[0, 0], [1, 0], [0, 1]]]), 3).face) == 6


def test_entries_are_sorted_by_face_row_col(rng):
    uv = rng.random((20, 3, 2))
    for coverage in ("center", "overlap"):
        r = rasterize_uv(uv, 16, coverage=coverage)
        key = (r.face * 16 + r.row) * 16 + r.col
        assert (np.diff(key) > 0).all()


def test_center_matches_a_per_texel_loop_on_random_triangles(rng):
    size = 12
    uv = rng.random((6, 3, 2)) * 1.2 - 0.1  # some corners outside the atlas
    uv[1] = uv[1, ::-1]  # both orientations
    r = rasterize_uv(uv, size)
    ref = _loop_center(uv, size)
    assert _pairs(r) == set(ref)
    assert len(r.face) == len(ref) > 0
    for f, j, i, b in zip(r.face, r.row, r.col, r.bary, strict=True):
        np.testing.assert_allclose(
            b, np.clip(ref[(f, j, i)], 0, 1) / np.clip(ref[(f, j, i)], 0, 1).sum(), atol=1e-12
        )


def test_overlap_matches_square_clipping_and_closest_points(rng):
    size = 10
    uv = rng.random((5, 3, 2))
    uv[2] = uv[2, ::-1]
    o = rasterize_uv(uv, size, coverage="overlap")
    tex = np.stack([uv[..., 0] * size, (1.0 - uv[..., 1]) * size], axis=-1)
    ref = {
        (f, j, i)
        for f in range(len(uv))
        for j in range(size)
        for i in range(size)
        if _clip_area(tex[f], i, j) > 1e-12
    }
    assert _pairs(o) == ref
    # "overlap" contains "center", with the same barycentrics there
    c = rasterize_uv(uv, size)
    assert _pairs(c) <= _pairs(o)
    where = {
        p: n
        for n, p in enumerate(zip(o.face.tolist(), o.row.tolist(), o.col.tolist(), strict=True))
    }
    idx = np.array(
        [where[p] for p in zip(c.face.tolist(), c.row.tolist(), c.col.tolist(), strict=True)]
    )
    np.testing.assert_allclose(o.bary[idx], c.bary, atol=1e-12)
    np.testing.assert_array_equal(o.distance[idx], 0.0)
    # every entry: a point of the triangle, the closest one to the texel centre, at the stated distance
    assert (o.bary >= 0).all()
    np.testing.assert_allclose(o.bary.sum(axis=1), 1.0, atol=1e-12)
    centre = np.stack([o.col + 0.5, o.row + 0.5], axis=1)
    point = np.einsum("nk,nkd->nd", o.bary, tex[o.face])
    np.testing.assert_allclose(np.linalg.norm(point - centre, axis=1), o.distance, atol=1e-9)
    outside = o.distance > 0
    assert outside.sum() > len(o.face) - len(c.face) - 1  # the texels "center" misses lie outside
    for n in np.nonzero(outside)[0]:
        q, d = _closest_point(tex[o.face[n]], centre[n])
        np.testing.assert_allclose(point[n], q, atol=1e-9)
        np.testing.assert_allclose(o.distance[n], d, atol=1e-9)


def test_border_texels_of_a_chart():
    # texel plane (x = 4u, y = 4(1 − v)): corners (0.4, 3.6), (3.2, 3.6), (0.4, 0.8); the hypotenuse
    # y = x + 0.4 passes 0.4/√2 from the centres (i + ½, i + ½) of the diagonal texels
    uv = np.array([[[0.1, 0.1], [0.8, 0.1], [0.1, 0.8]]])
    c, o = rasterize_uv(uv, 4), rasterize_uv(uv, 4, coverage="overlap")
    assert set(zip(c.row.tolist(), c.col.tolist(), strict=True)) == {
        (j, i) for j in range(4) for i in range(j)
    }
    assert set(zip(o.row.tolist(), o.col.tolist(), strict=True)) == {
        (j, i) for j in range(4) for i in range(j + 1)
    }
    diag = np.nonzero(o.row == o.col)[0]
    np.testing.assert_array_equal(o.row[diag], [0, 1, 2, 3])
    # (0, 0) and (3, 3) snap to corners 2 and 1; (1, 1) and (2, 2) to feet on the hypotenuse
    np.testing.assert_allclose(o.distance[diag], np.sqrt([0.1, 0.08, 0.08, 0.1]), atol=1e-12)
    np.testing.assert_allclose(
        o.bary[diag],
        [[0, 0, 1], [0, 0.9 / 2.8, 1.9 / 2.8], [0, 1.9 / 2.8, 0.9 / 2.8], [0, 1, 0]],
        atol=1e-12,
    )
    np.testing.assert_array_equal(o.distance[o.row != o.col], 0.0)


@pytest.mark.parametrize("coverage", ["center", "overlap"])
def test_degenerate_empty_and_outside_layouts_cover_nothing(coverage):
    line = np.array([[[0.1, 0.1], [0.5, 0.5], [0.9, 0.9]]])  # collinear corners
    outside = np.array(
        [[[1.5, 1.5], [2.5, 1.5], [1.5, 2.5]], [[-2.0, 0.2], [-1.0, 0.2], [-1.5, 0.8]]]
    )
    for uv in (line, outside, np.zeros((0, 3, 2))):
        r = rasterize_uv(uv, 8, coverage=coverage)
        assert all(len(a) == 0 for a in r) and r.bary.shape == (0, 3)
    # a degenerate face next to a good one does not disturb the good one
    both = np.concatenate([line, SQUARE[:1]])
    r = rasterize_uv(both, 8, coverage=coverage)
    assert (r.face == 1).all() and len(r.face) == len(
        rasterize_uv(SQUARE[:1], 8, coverage=coverage).face
    )


@pytest.mark.parametrize(
    "uv, size, kwargs, match",
    [
        (np.zeros((2, 3)), 4, {}, r"\[F, 3, 2\]"),
        (np.zeros((2, 4, 2)), 4, {}, r"\[F, 3, 2\]"),
        (np.zeros((2, 3, 3)), 4, {}, r"\[F, 3, 2\]"),
        (np.full((1, 3, 2), "a"), 4, {}, "real"),
        (SQUARE, 0, {}, "positive int"),
        (SQUARE, -3, {}, "positive int"),
        (SQUARE, 2.5, {}, "positive int"),
        (SQUARE, True, {}, "positive int"),
        (SQUARE, 4, {"coverage": "corner"}, "coverage must be one of"),
    ],
)
@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_bad_input_raises_input_error(uv, size, kwargs, match):
    with pytest.raises(InputError, match=match):
        rasterize_uv(uv, size, **kwargs)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_uv_names_the_faces(bad):
    uv = np.concatenate([SQUARE, SQUARE])
    uv[3, 1, 0] = bad
    with pytest.raises(InputError, match=r"NaN or infinite at faces \[3\]"):
        rasterize_uv(uv, 4)


def test_fill_unused_texels_takes_the_nearest_used_value():
    img = np.zeros((3, 4, 1))
    img[0, 0, 0], img[2, 3, 0] = 1.0, 2.0
    used = np.zeros((3, 4), bool)
    used[0, 0] = used[2, 3] = True
    out = fill_unused_texels(img, used)[..., 0]
    assert out.tolist() == [[1, 1, 1, 2], [1, 1, 2, 2], [1, 2, 2, 2]]
    assert fill_unused_texels(img, np.zeros((3, 4), bool)) is img  # nothing used: unchanged


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_fill_unused_texels_rejects_a_mask_of_another_shape():
    img = np.zeros((3, 4, 1))
    with pytest.raises(InputError, match=r"used must be \[H, W\]"):
        fill_unused_texels(img, np.ones((4, 3), bool))

"""Texel atlas: validity by exact square/triangle overlap, snapped surface points, texel size, frames."""

import numpy as np
import pytest

from jmeshtex import InputError
from jmeshtex.data import grid, icosphere
from jmeshtex.surfacecnn import unwrap_uv
from jmeshtex.surfacecnn.core import image_to_texels, texels_to_image, texture_atlas


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _clip_area(square, tri):
    """Area of square ∩ triangle by Sutherland–Hodgman clipping (slow reference, one pair)."""
    poly = [tuple(p) for p in square]
    sign = np.sign(_cross(tri[1] - tri[0], tri[2] - tri[0]))
    for k in range(3):
        a, b = tri[k], tri[(k + 1) % 3]

        def inside(p, a=a, b=b):
            return sign * _cross(b - a, np.asarray(p) - a) >= 0

        def cut(p, q, a=a, b=b):
            p, q = np.asarray(p), np.asarray(q)
            dp, dq = _cross(b - a, p - a), _cross(b - a, q - a)
            return tuple(p + (q - p) * dp / (dp - dq))

        out = []
        for i in range(len(poly)):
            p, q = poly[i], poly[(i + 1) % len(poly)]
            if inside(p):
                out.append(p)
                if not inside(q):
                    out.append(cut(p, q))
            elif inside(q):
                out.append(cut(p, q))
        poly = out
        if not poly:
            return 0.0
    x, y = np.array(poly).T
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def test_identity_grid_is_exact():
    v, f = grid(3)
    atlas = texture_atlas(v, f, v[f][..., :2], size=12)
    assert atlas.num_texels == 144
    assert atlas.texel_size == pytest.approx(1 / 12, rel=1e-12)
    row, col = atlas.rows_cols()
    np.testing.assert_allclose(atlas.point[:, 0], (col + 0.5) / 12, atol=1e-14)
    np.testing.assert_allclose(atlas.point[:, 1], 1 - (row + 0.5) / 12, atol=1e-14)
    # t along +x (growing column), d along -y (growing row), n = +z
    np.testing.assert_allclose(atlas.frame[:, 0], np.tile([1.0, 0, 0], (144, 1)), atol=1e-14)
    np.testing.assert_allclose(atlas.frame[:, 1], np.tile([0.0, -1, 0], (144, 1)), atol=1e-14)
    np.testing.assert_allclose(atlas.frame[:, 2], np.tile([0.0, 0, 1], (144, 1)), atol=1e-14)


@pytest.mark.parametrize("mirrored", [False, True])
def test_validity_and_snapping_match_a_slow_reference(rng, mirrored):
    # one triangle of random UVs inside the unit square, on a flat world triangle
    size = 10
    uv = rng.uniform(0.05, 0.95, (1, 3, 2))
    if _cross(uv[0, 1] - uv[0, 0], uv[0, 2] - uv[0, 0]) < 0:
        uv = uv[:, ::-1]
    if abs(_cross(uv[0, 1] - uv[0, 0], uv[0, 2] - uv[0, 0])) < 0.05:
        uv[0, 2] += [0.0, 0.3] if uv[0, 2, 1] < 0.6 else [0.0, -0.3]
        if _cross(uv[0, 1] - uv[0, 0], uv[0, 2] - uv[0, 0]) < 0:
            uv = uv[:, ::-1]
    if mirrored:  # clockwise in UV (counter-clockwise in texel rows/cols)
        uv = uv[:, ::-1]
    v = np.concatenate([uv[0] * 2.0, np.zeros((3, 1))], axis=1)  # world = 2 × UV
    f = np.array([[0, 1, 2]])
    atlas = texture_atlas(v, f, uv, size=size)
    tri = np.stack([uv[0, :, 0] * size, (1 - uv[0, :, 1]) * size], axis=1)
    expected, snapped = [], []
    for r in range(size):
        for c in range(size):
            sq = np.array([[c, r], [c + 1, r], [c + 1, r + 1], [c, r + 1]], float)
            if _clip_area(sq, tri) > 1e-7:
                expected.append(r * size + c)
                # distance from the centre to the triangle: 0 inside, else to densely sampled edges
                centre = np.array([c + 0.5, r + 0.5])
                signs = [_cross(tri[(k + 1) % 3] - tri[k], centre - tri[k]) for k in range(3)]
                t = np.linspace(0, 1, 4001)[:, None]
                edge_pts = np.concatenate(
                    [tri[k] + t * (tri[(k + 1) % 3] - tri[k]) for k in range(3)]
                )
                inside = all(x >= 0 for x in signs) or all(x <= 0 for x in signs)
                snapped.append(0.0 if inside else np.min(np.linalg.norm(edge_pts - centre, axis=1)))
    assert atlas.texel.tolist() == expected
    assert atlas.texel_size == pytest.approx(2.0 / size, rel=1e-9)
    # the surface point, mapped back to texel coordinates, is the nearest point of the triangle
    back = np.stack([atlas.point[:, 0] / 2 * size, (1 - atlas.point[:, 1] / 2) * size], axis=1)
    row, col = atlas.rows_cols()
    dist = np.linalg.norm(back - np.stack([col + 0.5, row + 0.5], 1), axis=1)
    np.testing.assert_allclose(dist, snapped, atol=2e-3)  # the edge sampling step is ~1e-3 texels


def test_mirrored_chart_flips_the_row_direction():
    v, f = grid(2)
    uv = v[f][..., :2].copy()
    uv[..., 0] = 1 - uv[..., 0]  # mirrored in u: growing column is -x, growing row still -y
    atlas = texture_atlas(v, f, uv, size=8, frames="uv")
    np.testing.assert_allclose(atlas.frame[:, 0], np.tile([-1.0, 0, 0], (64, 1)), atol=1e-14)
    np.testing.assert_allclose(atlas.frame[:, 1], np.tile([0.0, -1, 0], (64, 1)), atol=1e-14)
    np.testing.assert_allclose(atlas.frame[:, 2], np.tile([0.0, 0, 1], (64, 1)), atol=1e-14)
    # surface frames do not see the UV layout: the global vector x, and d = t turned clockwise
    surface = texture_atlas(v, f, uv, size=8)
    np.testing.assert_allclose(surface.frame[:, 0], np.tile([1.0, 0, 0], (64, 1)), atol=1e-14)
    np.testing.assert_allclose(surface.frame[:, 1], np.tile([0.0, -1, 0], (64, 1)), atol=1e-14)
    np.testing.assert_allclose(surface.frame[:, 2], np.tile([0.0, 0, 1], (64, 1)), atol=1e-14)


def test_unwrap_covers_every_face_with_a_nondegenerate_chart():
    v, f = icosphere(2)
    uv = unwrap_uv(v, f)
    area = _cross(uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0])
    assert uv.shape == (len(f), 3, 2) and np.all(np.abs(area) > 0)
    atlas = texture_atlas(v, f, None, size=64)
    assert 0.3 * 64 * 64 < atlas.num_texels < 64 * 64
    # every face holds the surface point of at least one texel at this resolution
    assert len(np.unique(atlas.face)) == len(f)
    np.testing.assert_allclose(np.linalg.norm(atlas.point, axis=1), 1.0, atol=0.05)


def test_image_round_trip_and_fill():
    v, f = grid(1)
    atlas = texture_atlas(v, f, v[f][..., :2] * 0.5, size=8)  # lower-left quarter only
    values = np.arange(atlas.num_texels, dtype=float)[:, None]
    image = texels_to_image(atlas, values)
    np.testing.assert_array_equal(image_to_texels(atlas, image), values)
    np.testing.assert_array_equal(
        image[:4, :4], np.broadcast_to(image[4:5, :4], (4, 4, 1))
    )  # nearest fill
    assert (texels_to_image(atlas, values, fill="zero")[:4] == 0).all()


def test_bad_inputs_raise_typed_errors():
    v, f = grid(1)
    with pytest.raises(InputError, match="size"):
        texture_atlas(v, f, v[f][..., :2], size=0)
    with pytest.raises(InputError, match="uv must be"):
        texture_atlas(v, f, np.zeros((3, 3, 2)), size=4)
    with pytest.raises(InputError, match="NaN"):
        texture_atlas(v, f, np.full((2, 3, 2), np.nan), size=4)
    with pytest.raises(InputError, match="no texel"):
        texture_atlas(v, f, np.full((2, 3, 2), 3.0) + np.array([[0, 0], [1, 0], [0, 1]]), size=4)

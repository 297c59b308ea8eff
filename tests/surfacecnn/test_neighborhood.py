"""3×3 exp-map neighbourhoods: exact on flat sheets, across UV seams, at boundaries, under rotation."""

import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import InputError
from jmeshtex.data import grid
from jmeshtex.ops import image_texel_neighborhood, texel_conv
from jmeshtex.surfacecnn.core import texel_taps, texture_atlas, uv_to_texels


def _dense(nb, n):
    """Dense [N, 9, N] sampling matrix of a TexelNeighborhood (reference)."""
    out = np.zeros((len(nb.index), 9, n))
    rows = np.arange(len(nb.index))[:, None]
    for j in range(nb.index.shape[-1]):
        np.add.at(out, (rows, np.arange(9)[None], nb.index[..., j]), nb.weight[..., j])
    return out


@pytest.mark.parametrize("diagonals", ["alternate", "uniform"])
def test_flat_sheet_taps_are_the_image_taps(diagonals):
    v, f = grid(4, diagonals=diagonals)
    size = 16
    taps = texel_taps(v, f, texture_atlas(v, f, v[f][..., :2], size=size))
    ref = image_texel_neighborhood(size, size)
    np.testing.assert_array_equal(taps.nearest.index, ref.index)
    np.testing.assert_array_equal(taps.nearest.weight, ref.weight)
    np.testing.assert_allclose(
        _dense(taps.bilinear, size * size), _dense(ref, size * size), atol=1e-12
    )
    # the boundary walks are the ones that read zero
    assert taps.stopped.sum() == (ref.weight[..., 0] == 0).sum()


def test_taps_cross_a_uv_seam():
    # the two halves of the sheet swap places in UV space: the walk crosses the seam at x = 0.5
    v, f = grid(2)
    size = 16
    left = v[f][..., 0].mean(axis=1) < 0.5
    uv = v[f][..., :2].copy()
    uv[..., 0] += np.where(left, 0.5, -0.5)[:, None]
    atlas = texture_atlas(v, f, uv, size=size)
    taps = texel_taps(v, f, atlas)
    ref = image_texel_neighborhood(size, size)
    # atlas pixel (r, c) shows world pixel (r, (c + size/2) % size)
    row, col = atlas.rows_cols()
    world = row * size + (col + size // 2) % size
    q = np.arange(size * size)
    to_atlas = atlas.index_of[(q // size) * size + ((q % size) + size // 2) % size]
    expected_index = np.where(ref.weight[world, :, 0] > 0, to_atlas[ref.index[world, :, 0]], 0)
    np.testing.assert_array_equal(taps.nearest.index[..., 0], expected_index)
    np.testing.assert_array_equal(taps.nearest.weight, ref.weight[world])
    # bilinear taps give the same convolution
    x = np.random.default_rng(0).normal(size=(size * size, 2))
    k = np.random.default_rng(1).normal(size=(3, 3, 2, 3))
    got = texel_conv(jnp.asarray(x), taps.bilinear, jnp.asarray(k), jnp.zeros(3))
    x_world = np.empty_like(x)
    x_world[world] = x
    want = texel_conv(jnp.asarray(x_world), ref, jnp.asarray(k), jnp.zeros(3))[world]
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_rotated_frames_read_rotated_offsets():
    v, f = grid(2)
    size = 8
    atlas = texture_atlas(v, f, v[f][..., :2], size=size)
    taps = texel_taps(v, f, atlas, rotation=np.pi / 2)
    ref = image_texel_neighborhood(size, size)
    # turned 90° counter-clockwise (seen from the normal): offset (dx, dy) reads (dy, -dx)
    perm = [3 * (-dx + 1) + (dy + 1) for dy in (-1, 0, 1) for dx in (-1, 0, 1)]
    np.testing.assert_array_equal(taps.nearest.index, ref.index[:, perm])
    np.testing.assert_array_equal(taps.nearest.weight, ref.weight[:, perm])


def test_boundary_clamp_reads_the_stopping_texel():
    v, f = grid(1)
    atlas = texture_atlas(v, f, v[f][..., :2], size=4)
    zero = texel_taps(v, f, atlas)
    clamp = texel_taps(v, f, atlas, boundary="clamp")
    # texel 0 (top-left corner): tap (-1, 0) stops on the left edge, inside texel 0 itself
    assert zero.nearest.weight[0, 3, 0] == 0 and clamp.nearest.weight[0, 3, 0] == 1
    assert clamp.nearest.index[0, 3, 0] == 0
    assert np.all(clamp.nearest.weight == 1)
    np.testing.assert_allclose(clamp.bilinear.weight.sum(-1), 1.0, atol=1e-12)
    with pytest.raises(InputError, match="boundary"):
        texel_taps(v, f, atlas, boundary="wrap")


def test_uv_to_texels_renormalises_over_valid_corners():
    v, f = grid(1)
    atlas = texture_atlas(v, f, v[f][..., :2] * 0.5, size=4)  # valid: the 2×2 lower-left pixels
    # a point between the valid block and invalid pixels above it: only valid corners keep weight
    idx, w, near = uv_to_texels(atlas, np.array([[0.25, 0.5]]), np.array([0]))
    assert np.isclose(w.sum(), 1.0) and set(idx[0][w[0] > 0].tolist()) <= set(
        range(atlas.num_texels)
    )
    assert near[0] in range(atlas.num_texels)


def test_in_face_fast_path_agrees_with_the_tracer():
    from jmeshtex.data import icosphere
    from jmeshtex.geometry import trace_geodesics, uv_at
    from jmeshtex.surfacecnn import unwrap_uv
    from jmeshtex.surfacecnn.core import trace_taps

    v, f = icosphere(2)
    atlas = texture_atlas(v, f, unwrap_uv(v, f), size=32)
    start = np.arange(0, atlas.num_texels, 7)
    end, stopped = trace_taps(v, f, atlas, start, 1.7 * atlas.texel_size, rotation=0.3)
    # reference: every walk through the tracer, directions built independently
    offsets = [(dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dx, dy) != (0, 0)]
    turn = np.exp(0.3j)
    direction = np.stack(
        [(dx * atlas.tangent[start] + dy * atlas.down[start]) * turn for dx, dy in offsets], 1
    )
    length = 1.7 * atlas.texel_size * np.abs(direction)
    ref = trace_geodesics(
        v,
        f,
        np.repeat(atlas.face[start], 8),
        np.repeat(atlas.bary[start], 8, axis=0),
        direction.ravel(),
        length.ravel(),
    )
    np.testing.assert_allclose(
        end.reshape(-1, 2), uv_at(atlas.uv, ref.face.astype(np.int64), ref.bary), atol=1e-12
    )
    assert not stopped.any()

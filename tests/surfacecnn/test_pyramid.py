"""Pooling pyramid: 2×2 blocks on aligned flat sheets, connected-component splits, overshoot fix."""

import numpy as np
import pytest

from jmeshtex import InputError
from jmeshtex.data import grid
from jmeshtex.ops import image_pool_groups, image_texel_neighborhood
from jmeshtex.surfacecnn.core import texel_pyramid, texture_atlas


def test_aligned_sheet_gives_image_pooling_and_taps():
    v, f = grid(4)
    size = 32
    pyr = texel_pyramid(v, f, texture_atlas(v, f, v[f][..., :2], size=size), levels=3)
    for level in range(3):
        s = size >> level
        groups = image_pool_groups(s, s)
        np.testing.assert_array_equal(pyr.pools[level].index, groups.index)
        np.testing.assert_array_equal(pyr.pools[level].mask, groups.mask)
        np.testing.assert_array_equal(
            pyr.parent[level][groups.index],
            np.arange(len(groups.index))[:, None] * np.ones((1, 4), int),
        )
        coarse = image_texel_neighborhood(s // 2, s // 2)
        np.testing.assert_array_equal(pyr.nearest[level + 1].index, coarse.index)
        np.testing.assert_array_equal(pyr.nearest[level + 1].weight, coarse.weight)


def test_groups_never_join_separate_sheets():
    # two parallel unit squares 0.01 apart: every voxel of the coarse levels contains both
    v, f = grid(2)
    v2 = np.concatenate([v, v + [0, 0, 0.01]])
    f2 = np.concatenate([f, f[:, ::-1] + len(v)])
    uv = np.concatenate([v[f][..., :2] * [0.5, 1], v[f][..., :2] * [0.5, 1] + [0.5, 0]])
    atlas = texture_atlas(v2, f2, uv, size=16)
    pyr = texel_pyramid(v2, f2, atlas, levels=3)
    sheet = (atlas.face >= len(f)).astype(int)
    for level in range(1, 4):
        node = pyr.node_of_texel[level]
        both = np.bincount(node, sheet, minlength=node.max() + 1) % np.bincount(node)
        assert np.all(both == 0), f"level {level} mixes the sheets"


def test_overshoot_walks_back_to_an_adjacent_group():
    # a strongly anisotropic UV map (u stretched 4×): coarse walks along x overshoot small groups
    v, f = grid(4, size=(1.0, 0.25))
    uv = v[f][..., :2] * [1.0, 4.0]
    atlas = texture_atlas(v, f, uv, size=32)
    pyr = texel_pyramid(v, f, atlas, levels=2)
    no_backoff = texel_pyramid(v, f, atlas, levels=2, backoff=())
    for level in (1, 2):
        # without walking back, overshooting taps fall back to the centre group more often
        def centre_reads(p, level=level):
            nb = p.nearest[level]
            return int(
                (
                    (nb.index[..., 0] == np.arange(len(nb.index))[:, None])
                    & (nb.weight[..., 0] > 0)
                ).sum()
            )

        assert centre_reads(pyr) < centre_reads(no_backoff)
        nb = pyr.nearest[level]
        G = len(nb.index)
        # adjacency of the level's groups, from the level-0 taps
        t0 = pyr.nearest[0].index[..., 0]
        a = pyr.node_of_texel[level][np.repeat(np.arange(atlas.num_texels), 9)]
        b = pyr.node_of_texel[level][t0.ravel()]
        adjacent = np.zeros((G, G), bool)
        adjacent[a, b] = adjacent[b, a] = True
        np.fill_diagonal(adjacent, True)
        live = nb.weight[..., 0] > 0
        rows = np.repeat(np.arange(G)[:, None], 9, axis=1)
        assert np.all(adjacent[rows[live], nb.index[..., 0][live]])


def test_bad_arguments():
    v, f = grid(1)
    atlas = texture_atlas(v, f, v[f][..., :2], size=4)
    with pytest.raises(InputError, match="levels"):
        texel_pyramid(v, f, atlas, levels=-1)
    with pytest.raises(InputError, match="backoff"):
        texel_pyramid(v, f, atlas, levels=1, backoff=(1.5,))

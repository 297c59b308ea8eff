"""Rotation / gauge: turning the tap frames by 90° reads the texture rotated by 90°; harness entry."""

import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex.data import grid, icosphere
from jmeshtex.metrics import load_vgg16, vgg_features
from jmeshtex.surfacecnn import unwrap_uv
from jmeshtex.surfacecnn.core import mesh_cnn_features, texel_pyramid, texel_taps, texture_atlas
from jmeshtex.testing import REGISTRY, check

LAYERS = ("relu1_1", "relu1_2", "pool1", "relu2_1")


def test_rotating_frames_and_exemplar_together(seed):
    """Mesh CNN with frames turned 90° on image I == 2D CNN on I turned 90° clockwise, re-indexed."""
    v, f = grid(4)
    size = 16
    atlas = texture_atlas(v, f, v[f][..., :2], size=size)
    pyr = texel_pyramid(v, f, atlas, levels=1, rotation=np.pi / 2)
    image = np.random.default_rng(seed).uniform(size=(size, size, 3)).astype(np.float32)
    weights = load_vgg16()
    mesh = mesh_cnn_features(
        jnp.asarray(image.reshape(-1, 3)), pyr.network_arrays(), weights, layers=LAYERS
    )
    turned = np.rot90(image, k=-1)  # R[i, j] = I[H - 1 - j, i]
    flat = vgg_features(
        jnp.asarray(turned.copy()[None]), weights, layers=LAYERS, pool="mean", ceil_mode=True
    )
    for name in LAYERS:
        want = np.asarray(flat[name][0])
        n = want.shape[0]
        got = np.asarray(mesh[name]).reshape(n, n, -1)
        # texel (r, c) of the mesh sees what pixel (c, n - 1 - r) of the turned image sees
        r, c = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
        np.testing.assert_allclose(
            got[r, c], want[c, n - 1 - r], rtol=0, atol=1e-5 * np.abs(want).max()
        )
    # without the frame rotation the features differ (the check can fail)
    plain = texel_pyramid(v, f, atlas, levels=1)
    unturned = mesh_cnn_features(
        jnp.asarray(image.reshape(-1, 3)), plain.network_arrays(), weights, layers=("relu1_1",)
    )["relu1_1"]
    assert np.abs(np.asarray(unturned) - np.asarray(mesh["relu1_1"])).max() > 1e-2


def test_quarter_turn_permutes_taps_on_a_curved_mesh():
    """On any mesh a 90° frame turn walks tap (dx, dy) exactly where tap (dy, -dx) walked."""
    v, f = icosphere(2)
    atlas = texture_atlas(v, f, unwrap_uv(v, f), size=32)
    base = texel_taps(v, f, atlas)
    turned = texel_taps(v, f, atlas, rotation=np.pi / 2)
    mirrored = np.isclose(atlas.down, 1j * atlas.tangent)
    perm = np.array([3 * (-dx + 1) + (dy + 1) for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    keep = ~mirrored
    np.testing.assert_allclose(turned.end_uv[keep], base.end_uv[keep][:, perm], atol=1e-12)
    np.testing.assert_array_equal(turned.nearest.index[keep], base.nearest.index[keep][:, perm])


@pytest.mark.parametrize("transform", ["rigid", "gauge", "permute_vertices", "fold"])
def test_first_layer_entry_is_invariant(transform):
    import jmeshtex.testing._methods.surfacecnn  # noqa: F401  (registers the entry)

    result = check(REGISTRY["surfacecnn.first_layer"], transform, dtype=jnp.float64)
    assert result.passed, result

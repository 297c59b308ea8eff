"""The mesh CNN equals the 2D CNN on a flat sheet with identity UVs (the paper's premise, exactly)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import InputError
from jmeshtex.data import grid
from jmeshtex.metrics import load_vgg16, vgg_features
from jmeshtex.ops import PoolGroups, grouped_pool
from jmeshtex.surfacecnn._network import _pool_groups
from jmeshtex.surfacecnn.core import (
    default_layers,
    mesh_cnn_features,
    required_levels,
    texel_pyramid,
    texture_atlas,
)

LAYERS = ("relu1_1", "relu1_2", "pool1", "relu2_1", "relu2_2", "pool2", "relu3_1")


@pytest.fixture(scope="module")
def sheet():
    v, f = grid(4)
    size = 32
    atlas = texture_atlas(v, f, v[f][..., :2], size=size)
    return size, texel_pyramid(v, f, atlas, levels=2)


@pytest.mark.parametrize("pool", ["mean", "max"])
def test_mesh_cnn_equals_2d_cnn_on_a_flat_sheet(sheet, seed, pool):
    size, pyr = sheet
    weights = load_vgg16()
    image = np.random.default_rng(seed).uniform(size=(size, size, 3)).astype(np.float32)
    layers = (
        LAYERS if pool == "mean" else LAYERS[:4]
    )  # max pooling: the first pooled block suffices
    mesh = mesh_cnn_features(
        jnp.asarray(image.reshape(-1, 3)), pyr.network_arrays(), weights, layers=layers, pool=pool
    )
    flat = vgg_features(jnp.asarray(image[None]), weights, layers=layers, pool=pool, ceil_mode=True)
    for name in layers:
        want = np.asarray(flat[name][0])
        got = np.asarray(mesh[name]).reshape(want.shape)
        assert got.dtype == np.float32
        # interior texels (the whole map agrees too: off-sheet taps are zero padding, as "SAME")
        inner = (slice(1, -1), slice(1, -1))
        scale = np.abs(want).max()
        assert np.abs(got[inner] - want[inner]).max() <= 1e-5 * scale, name
        assert np.abs(got - want).max() <= 1e-5 * scale, name


def test_segment_pooling_equals_grouped_pooling(rng):
    labels = rng.integers(0, 7, 60)
    labels[:7] = np.arange(7)
    order = np.argsort(labels, kind="stable")
    counts = np.bincount(labels)
    index = np.zeros((7, counts.max()), np.int32)
    mask = np.zeros(index.shape, bool)
    slot = np.arange(60) - (np.cumsum(counts) - counts)[labels[order]]
    index[labels[order], slot], mask[labels[order], slot] = order, True
    groups = PoolGroups(jnp.asarray(index), jnp.asarray(mask))
    x = jnp.asarray(rng.normal(size=(60, 5)))
    for mode in ("mean", "max"):
        seg = _pool_groups(x, groups, jnp.asarray(labels, jnp.int32), mode)  # S > 8: segment path
        np.testing.assert_allclose(seg, grouped_pool(x, groups, mode=mode), rtol=1e-12, atol=1e-12)


def test_jit_and_gradients(sheet):
    size, pyr = sheet
    weights = load_vgg16()
    arrays = jax.tree.map(jnp.asarray, pyr.network_arrays())

    @jax.jit
    def energy(x):
        return jnp.mean(mesh_cnn_features(x, arrays, weights, layers=("pool2",))["pool2"] ** 2)

    x = jnp.full((size * size, 3), 0.5, jnp.float32)
    g = jax.grad(energy)(x)
    assert g.shape == x.shape and bool(jnp.all(jnp.isfinite(g)))
    energy(x + 0.1)
    assert energy._cache_size() == 1


def test_layer_bookkeeping_and_errors(sheet):
    _, pyr = sheet
    weights = load_vgg16()
    names = default_layers(weights)
    assert names.count("pool5") == 1 and len(names) == 13 + 5
    assert required_levels(weights, ("relu1_1",)) == 0
    assert required_levels(weights, ("pool2", "relu1_1")) == 2
    with pytest.raises(InputError, match="unknown layer"):
        required_levels(weights, ("relu9_9",))
    with pytest.raises(InputError, match="levels"):
        mesh_cnn_features(jnp.zeros((1024, 3)), pyr.network_arrays(), weights, layers=("relu4_1",))
    with pytest.raises(InputError, match="colors"):
        mesh_cnn_features(jnp.zeros((1024, 4)), pyr.network_arrays(), weights, layers=("relu1_1",))


def test_float64_is_exact_to_rounding():
    v, f = grid(2)
    size = 8
    pyr = texel_pyramid(v, f, texture_atlas(v, f, v[f][..., :2], size=size), levels=1)
    weights = jax.tree.map(lambda a: jnp.asarray(a, jnp.float64), load_vgg16())
    image = np.random.default_rng(0).uniform(size=(size, size, 3))
    layers = ("relu1_2", "pool1", "relu2_1")
    mesh = mesh_cnn_features(
        jnp.asarray(image.reshape(-1, 3)), pyr.network_arrays(), weights, layers=layers
    )
    flat = vgg_features(
        jnp.asarray(image[None]), weights, layers=layers, pool="mean", ceil_mode=True
    )
    for name in layers:
        want = np.asarray(flat[name][0]).reshape(-1, flat[name].shape[-1])
        assert mesh[name].dtype == jnp.float64
        np.testing.assert_allclose(
            np.asarray(mesh[name]), want, rtol=0, atol=1e-10 * np.abs(want).max()
        )

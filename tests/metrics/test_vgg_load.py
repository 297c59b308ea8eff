"""Weight loaders: the embedded VGG-16 and VGG-19 from a user .npz / .h5 (Keras and PyTorch layouts)."""

import importlib.util

import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import ConfigError, MeshIOError
from jmeshtex.metrics import VGG19_NAMES, load_vgg16, load_vgg19, vgg_features

_CHANNELS = [(3, 4), (4, 4), (4, 6), (6, 6)] + [(6, 6)] * 12


def _arrays(rng, scheme):
    out = {}
    for name, (a, b) in zip(VGG19_NAMES, _CHANNELS, strict=True):
        block, i = name[4:].split("_")
        k = rng.normal(size=(3, 3, a, b)).astype(np.float32)
        bias = rng.normal(size=b).astype(np.float32)
        if scheme == "keras":
            out[f"block{block}_conv{i}/block{block}_conv{i}/kernel:0"] = k
            out[f"block{block}_conv{i}/block{block}_conv{i}/bias:0"] = bias
        else:  # PyTorch-style names and OIHW kernels
            out[f"{name}.weight"] = k.transpose(3, 2, 0, 1)
            out[f"{name}.bias"] = bias
    return out


@pytest.mark.parametrize("scheme", ["keras", "torch"])
def test_vgg19_npz_round_trip(tmp_path, rng, scheme):
    arrays = _arrays(rng, scheme)
    path = tmp_path / "vgg19.npz"
    np.savez(path, **arrays)
    w = load_vgg19(path, preprocess="caffe" if scheme == "keras" else "torch")
    assert w.names == VGG19_NAMES and len(w.convs) == 16
    assert w.pools_after == ("conv1_2", "conv2_2", "conv3_4", "conv4_4", "conv5_4")
    ref = (
        arrays["block3_conv2/block3_conv2/kernel:0"]
        if scheme == "keras"
        else arrays["conv3_2.weight"].transpose(2, 3, 1, 0)
    )
    np.testing.assert_array_equal(np.asarray(w.convs[5][0]), ref)
    # caffe preprocessing: BGR, 0-255, mean subtracted
    x = jnp.asarray([[0.0, 0.5, 1.0]], jnp.float32)
    want = (
        [255.0 - 103.939, 127.5 - 116.779, 0.0 - 123.68]
        if scheme == "keras"
        else (np.array([0.0, 0.5, 1.0]) - [0.485, 0.456, 0.406]) / [0.229, 0.224, 0.225]
    )
    np.testing.assert_allclose(w.preprocess(x)[0], want, rtol=1e-5)
    out = vgg_features(
        jnp.full((1, 8, 8, 3), 0.5, jnp.float32),
        w,
        layers=("pool3", "relu4_4"),
        pool="mean",
        ceil_mode=True,
    )
    assert out["pool3"].shape == (1, 1, 1, 6) and out["relu4_4"].shape == (1, 1, 1, 6)


def test_vgg19_errors(tmp_path, rng):
    arrays = _arrays(rng, "keras")
    del arrays["block5_conv4/block5_conv4/bias:0"]
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    with pytest.raises(MeshIOError, match="conv5_4"):
        load_vgg19(path)
    with pytest.raises(MeshIOError, match="does not exist"):
        load_vgg19(tmp_path / "missing.npz")
    (tmp_path / "w.pt").write_bytes(b"x")
    with pytest.raises(ConfigError, match="unsupported"):
        load_vgg19(tmp_path / "w.pt")
    with pytest.raises(ConfigError, match="preprocess"):
        load_vgg19(path, preprocess="tf")


def test_h5_needs_h5py_and_names_the_fix(tmp_path, rng):
    path = tmp_path / "vgg19.h5"
    if importlib.util.find_spec("h5py") is None:
        path.write_bytes(b"\x89HDF")
        with pytest.raises(ConfigError, match="pip install h5py"):
            load_vgg19(path)
    else:  # h5py installed: the Keras layout loads
        import h5py

        with h5py.File(path, "w") as f:
            for key, value in _arrays(rng, "keras").items():
                f[key.replace(":0", "_0")] = value
        assert len(load_vgg19(path).convs) == 16


def test_vgg16_is_the_embedded_torchvision_network():
    w = load_vgg16()
    assert len(w.convs) == 13 and w.pools_after[-1] == "conv5_3" and not w.bgr
    assert w.convs[0][0].shape == (3, 3, 3, 64) and w.convs[0][0].dtype == jnp.float32

"""The method contract: ``Config``, ``synthesize(mesh, exemplar, config, key=)``, ``save(result, path)``
and ``load(path)``; randomness only from ``key``. (The surface CNN has no training stage: no
``train``/``Model``; the pre-trained VGG comes from :mod:`jmeshtex.metrics`.)"""

import dataclasses
import json

import jax
import numpy as np
import pytest

from jmeshtex import InputError, Mesh, MeshIOError, surfacecnn
from jmeshtex._config import ConfigBase
from jmeshtex.data import grid

LAYERS = ("relu1_1",)


@pytest.fixture(scope="module")
def mesh():
    v, f = grid(1)  # two triangles, the identity UV map
    return Mesh(v, f, uv=v[f][..., :2])


@pytest.fixture(scope="module")
def exemplar():
    return np.random.default_rng(0).uniform(size=(8, 8, 3))


def _run(mesh, exemplar, key):
    config = surfacecnn.Config(size=8, steps=3)
    return surfacecnn.synthesize(mesh, exemplar, config, key=key, layers=LAYERS, progress=False)


def test_config_is_a_frozen_config_base_without_a_seed():
    config = surfacecnn.Config(size=8, steps=3)
    assert isinstance(config, ConfigBase) and dataclasses.is_dataclass(config)
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.steps = 4
    names = {f.name for f in dataclasses.fields(config)}
    assert {"steps", "learning_rate"} <= names and "seed" not in names
    assert surfacecnn.Config.from_dict(json.loads(json.dumps(config.to_dict()))) == config


def test_synthesize_save_load_round_trip(mesh, exemplar, tmp_path):
    result = _run(mesh, exemplar, jax.random.key(0))
    assert isinstance(result, surfacecnn.SynthesisResult)
    assert (
        result.texture.shape == (8, 8, 3)
        and result.colors.shape == (64, 3)
        and result.losses.shape == (3,)
    )
    summary = surfacecnn.save(result, tmp_path / "out")
    assert str(tmp_path / "out" / "result.npz") in summary["files"]
    back = surfacecnn.load(tmp_path / "out")
    assert isinstance(back, surfacecnn.SynthesisResult) and back.surface is None
    np.testing.assert_array_equal(back.texture, result.texture)
    assert back.texture.dtype == result.texture.dtype == np.float32
    np.testing.assert_array_equal(back.colors, result.colors)
    np.testing.assert_array_equal(back.losses, result.losses)
    assert back.final_loss == result.final_loss and back.stats["texels"] == 64
    for name in ("vertices", "faces", "uv", "texture"):
        np.testing.assert_array_equal(getattr(back.mesh, name), getattr(result.mesh, name))
    with pytest.raises(MeshIOError, match="result.npz"):
        surfacecnn.load(tmp_path / "nothing")


def test_randomness_comes_only_from_key(mesh, exemplar):
    a = _run(mesh, exemplar, jax.random.key(1))
    b = _run(mesh, exemplar, jax.random.key(1))
    c = _run(mesh, exemplar, jax.random.key(2))
    np.testing.assert_array_equal(a.texture, b.texture)
    np.testing.assert_array_equal(a.losses, b.losses)
    assert np.abs(a.texture - c.texture).max() > 1e-3
    # a (vertices, faces) pair is accepted too (unwrapped, having no UVs); anything else is a typed error
    pair = surfacecnn.synthesize(
        (mesh.vertices, mesh.faces),
        exemplar,
        surfacecnn.Config(size=8, steps=1),
        key=jax.random.key(1),
        layers=LAYERS,
        progress=False,
    )
    assert pair.mesh.uv.shape == (2, 3, 2)
    with pytest.raises(InputError, match="mesh"):
        surfacecnn.synthesize("not a mesh", exemplar, key=jax.random.key(1), progress=False)


def test_stylize_takes_key_but_draws_nothing(mesh, exemplar):
    config = surfacecnn.Config(size=8, steps=2, content_layer="relu1_2")
    content = np.full((8, 8, 3), 0.4)
    runs = [
        surfacecnn.stylize(
            mesh, content, exemplar, config, key=jax.random.key(k), layers=LAYERS, progress=False
        )
        for k in (0, 1)
    ]
    np.testing.assert_array_equal(runs[0].texture, runs[1].texture)
    assert (
        np.abs(runs[0].texture - 0.4).max() > 1e-3
    )  # the optimisation moved away from the content

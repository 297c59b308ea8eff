"""The method contract on DGTS: Mesh in, ``key=`` randomness, ``train`` → ``save`` → ``load`` → ``transfer``."""

from __future__ import annotations

import dataclasses

import jax
import numpy as np
import pytest

from jmeshtex import Mesh, TrainResult, dgts
from jmeshtex.data import icosahedron, icosphere, torus
from tests.dgts.conftest import TINY


@pytest.fixture(scope="module")
def meshes():
    reference, template = icosphere(2), icosahedron()
    assert isinstance(reference, Mesh) and isinstance(template, Mesh)  # Mesh in, not (V, F)
    return dgts.training_meshes(
        reference,
        template,
        config=dgts.PrepareConfig(levels=2, steps=20, samples_per_level=200),
        key=jax.random.key(0),
        progress=False,
    )


def _leaves(tree):
    return [np.asarray(x) for x in jax.tree.leaves(tree)]


def test_config_is_the_shared_config_mechanism():
    from jmeshtex._config import ConfigBase

    for cls in (dgts.Config, dgts.PrepareConfig):
        assert issubclass(cls, ConfigBase) and dataclasses.is_dataclass(cls)
        with pytest.raises(dataclasses.FrozenInstanceError):
            cls().steps = 3  # type: ignore[misc]
    assert dgts.TrainResult is TrainResult


def test_train_save_load_transfer_round_trip(tmp_path, meshes):
    result = dgts.train(meshes, TINY, key=jax.random.key(1), progress=False)
    assert isinstance(result, TrainResult) and isinstance(result.model, dgts.Model)
    folder = dgts.save(result.model, tmp_path / "model")
    model = dgts.load(folder)
    assert isinstance(model, dgts.Model) and model.config == TINY
    target = torus(8, 6)
    before = dgts.transfer(result.model, target, num_samples=2, key=jax.random.key(2))
    after = dgts.transfer(model, target, num_samples=2, key=jax.random.key(2))
    assert isinstance(after, dgts.DGTSTransfer)
    np.testing.assert_array_equal(after.vertices, before.vertices)
    np.testing.assert_array_equal(after.faces, before.faces)
    np.testing.assert_array_equal(after.heights, before.heights)
    assert np.abs(after.vertices - after.base).max() > 0  # the generators did displace the target


def test_the_same_key_gives_the_same_result_and_another_key_another(meshes):
    a = dgts.train(meshes, TINY, key=jax.random.key(1), progress=False)
    b = dgts.train(meshes, TINY, key=jax.random.key(1), progress=False)
    c = dgts.train(meshes, TINY, key=jax.random.key(2), progress=False)
    for x, y in zip(_leaves(a.model), _leaves(b.model), strict=True):
        np.testing.assert_array_equal(x, y)
    assert any(
        not np.array_equal(x, y) for x, y in zip(_leaves(a.model), _leaves(c.model), strict=True)
    )
    target = torus(8, 6)
    t1 = dgts.transfer(a.model, target, key=jax.random.key(3))
    t2 = dgts.transfer(a.model, target, key=jax.random.key(3))
    t3 = dgts.transfer(a.model, target, key=jax.random.key(4))
    np.testing.assert_array_equal(t1.vertices, t2.vertices)
    assert not np.allclose(t1.vertices, t3.vertices)
    i1 = dgts.interpolate(a.model, target, num_frames=2, key=jax.random.key(3))
    i2 = dgts.interpolate(a.model, target, num_frames=2, key=jax.random.key(4))
    assert not np.allclose(i1.vertices, i2.vertices)


def test_no_seed_argument_and_key_is_keyword_only():
    import inspect

    for fn in (
        dgts.training_meshes,
        dgts.train,
        dgts.transfer,
        dgts.interpolate,
        dgts.fit_level,
        dgts.sample_points,
        dgts.init_level,
    ):
        params = inspect.signature(fn).parameters
        assert "seed" not in params, fn.__name__
        assert params["key"].kind is inspect.Parameter.KEYWORD_ONLY, fn.__name__
    assert not hasattr(dgts, "vertex_normals") and not hasattr(dgts, "TrainConfig")

"""The method contract on jmeshtex.fldm: ``Config`` with the shared field names and no seed, ``train(key=)``
returning a ``TrainResult`` of a ``Model``, ``save(model, path)`` / ``load(path)``, task verbs that take a
``Mesh`` (or a ``(V, F)`` pair) and ``key=`` — on a tiny mesh and config, with the analytic stripe codec."""

from __future__ import annotations

import dataclasses
import inspect

import jax
import numpy as np
import pytest

import jmeshtex
from jmeshtex import InputError, Mesh, fldm
from jmeshtex.cli._stages.fldm import stripe_encoder
from jmeshtex.data import striped_sphere

CFG = fldm.Config.tiny(
    latent_channels=2,
    n_copies=2,
    copy_vertices=40,
    steps=3,
    checkpoint_every=2,
    widths=(4, 6),
    hdim=2,
    knn=5,
    diffusion_steps=20,
    bucket=16,
    batch_size=2,
)


@pytest.fixture(scope="module")
def mesh() -> Mesh:
    return striped_sphere(subdivisions=1)  # 42 vertices with striped vertex colours


@pytest.fixture(scope="module")
def data(mesh):
    return fldm.build_dataset(
        mesh, CFG, encode=stripe_encoder, key=jax.random.key(0), progress=False
    )


@pytest.fixture(scope="module")
def result(data):
    return fldm.train(data, CFG, key=jax.random.key(1), progress=False)


def test_config_uses_the_shared_field_names_and_has_no_seed():
    fields = {f.name for f in dataclasses.fields(fldm.Config)}
    assert {"steps", "learning_rate", "batch_size", "diffusion_steps"} <= fields
    assert not fields & {"seed", "train_steps", "num_train_steps", "lr", "iterations", "num_levels"}
    assert fldm.Config.from_dict(CFG.to_dict()) == CFG
    with pytest.raises(jmeshtex.ConfigError, match="steps"):
        fldm.Config.tiny(steps=0)


def test_public_api_is_documented_and_takes_keys_not_seeds():
    names = [n for n in dir(fldm) if not n.startswith("_")]
    assert fldm.TrainResult is jmeshtex.TrainResult
    for name in names:
        obj = getattr(fldm, name)
        if inspect.ismodule(obj) or not callable(obj):
            continue
        assert (obj.__doc__ or "").strip(), f"fldm.{name} has no docstring"
        if inspect.isfunction(obj):
            params = inspect.signature(obj).parameters
            assert "seed" not in params, f"fldm.{name} takes a seed; randomness is a key= argument"
            if "key" in params and name not in ("draw_sampling_noise", "init_denoiser"):
                assert params["key"].kind is inspect.Parameter.KEYWORD_ONLY, name
    for verb in ("train", "init", "build_dataset", "sample", "inpaint"):
        assert (
            inspect.signature(getattr(fldm, verb)).parameters["key"].default
            is inspect.Parameter.empty
        ), verb


def test_train_returns_a_train_result_of_a_model(data, result):
    assert isinstance(result, jmeshtex.TrainResult) and isinstance(result.model, fldm.Model)
    assert result.steps == CFG.steps and result.resumed_from is None and result.seconds > 0
    assert result.losses["loss"].shape == (CFG.steps,) and np.isfinite(result.losses["loss"]).all()
    assert result.model.config == CFG and np.array_equal(result.model.scale, data.scale)
    # the same key is the same run; another key another
    again = fldm.train(data, CFG, key=jax.random.key(1), progress=False)
    np.testing.assert_array_equal(again.losses["loss"], result.losses["loss"])
    other = fldm.train(data, CFG, key=jax.random.key(2), progress=False)
    assert not np.allclose(other.losses["loss"], result.losses["loss"])
    # init(key) is the model train(key) started from
    start = fldm.init(data, CFG, key=jax.random.key(1))
    moved = [
        not np.array_equal(a, b)
        for a, b in zip(
            jax.tree.leaves(start.params), jax.tree.leaves(result.model.params), strict=True
        )
    ]
    assert any(moved)
    first = fldm.train(data, CFG.replace(steps=1), key=jax.random.key(1), progress=False)
    assert first.losses["loss"][0] == result.losses["loss"][0]


def test_save_load_round_trip_gives_the_same_samples(tmp_path, mesh, result):
    model = result.model
    assert fldm.save(model, tmp_path / "model") == tmp_path / "model"
    loaded = fldm.load(tmp_path / "model")
    assert isinstance(loaded, fldm.Model) and loaded.config == model.config
    np.testing.assert_array_equal(loaded.scale, model.scale)
    for a, b in zip(jax.tree.leaves(loaded.params), jax.tree.leaves(model.params), strict=True):
        assert np.asarray(a).dtype == np.asarray(b).dtype
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    key = jax.random.key(3)
    before = fldm.sample(model, mesh, key=key, n=2, steps=3)
    after = fldm.sample(loaded, mesh, key=key, n=2, steps=3)
    assert before.shape == (2, mesh.num_vertices, CFG.latent_channels) and np.isfinite(before).all()
    np.testing.assert_array_equal(before, after)
    other = fldm.sample(loaded, mesh, key=jax.random.key(4), n=2, steps=3)
    assert not np.allclose(other, before)
    with pytest.raises(InputError, match="Model first"):
        fldm.save(tmp_path / "model", model)  # object first, path second
    with pytest.raises(jmeshtex.MeshIOError, match="no FLDM model"):
        fldm.load(tmp_path / "nowhere")


def test_task_verbs_take_a_mesh_or_a_pair_and_a_key(mesh, result):
    model = result.model
    pair = (mesh.vertices, mesh.faces)
    key = jax.random.key(5)
    np.testing.assert_array_equal(
        fldm.sample(model, pair, key=key, steps=2), fldm.sample(model, mesh, key=key, steps=2)
    )
    known = stripe_encoder(mesh)
    mask = mesh.vertices[:, 2] > 0
    a = fldm.inpaint(model, mesh, known, mask, key=key, method="ddim", steps=2)
    b = fldm.inpaint(model, pair, known, mask, key=key, method="ddim", steps=2)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(a[0][mask], known[mask], rtol=1e-6, atol=1e-6)
    geo = fldm.sampling_geometry(mesh, model)
    np.testing.assert_array_equal(
        geo.fine.index, fldm.denoiser_geometry(pair, knn=CFG.knn).fine.index
    )
    for bad in (mesh.vertices, "mesh.obj", None):
        with pytest.raises(InputError, match="Mesh"):
            fldm.sample(model, bad, key=key, steps=2)
    with pytest.raises(InputError, match="Mesh"):
        fldm.build_dataset(mesh.vertices, CFG, encode=stripe_encoder, key=key, progress=False)
    with pytest.raises(TypeError, match="key"):
        fldm.sample(model, mesh, steps=2)  # no default randomness


def test_the_dataset_is_a_function_of_its_key(mesh, data):
    same = fldm.build_dataset(
        mesh, CFG, encode=stripe_encoder, key=jax.random.key(0), progress=False
    )
    np.testing.assert_array_equal(same.latents, data.latents)
    other = fldm.build_dataset(
        mesh, CFG, encode=stripe_encoder, key=jax.random.key(7), progress=False
    )
    assert not np.array_equal(other.meshes[0].vertices, data.meshes[0].vertices)
    assert isinstance(data, fldm.Dataset) and data.num_copies == CFG.n_copies

"""FLDM pipeline: copies and their cache, padding to buckets, labels, resumable training, sampling
(reproducible, inpainting exact, label-guided, transfer to another mesh), save/load, and the CLI."""

from __future__ import annotations

import dataclasses
import json

import jax
import numpy as np
import pytest

from jmeshtex import CheckpointMismatchError, ConfigError, InputError, TrainResult
from jmeshtex.data import stripe_encoder, striped_sphere, torus
from jmeshtex.fldm import build_dataset, inpaint, load, sample, save, train
from jmeshtex.fldm._data import copy_mesh, transfer_labels
from tests.fldm.conftest import TINY_CLI_TRAIN, TINY_DATA_KEY, TINY_TRAIN, uses_tiny_data

#: trainings of 2-4 steps: their steps compile at the suite's quick XLA level (conftest.py)
pytestmark = pytest.mark.few_steps

CFG = TINY_TRAIN.replace(steps=4, checkpoint_every=2)
DATA_KEY = TINY_DATA_KEY
TRAIN_KEY = jax.random.key(1)


@pytest.fixture(scope="module")
def sphere(tiny_sphere):
    return tiny_sphere  # striped_sphere(subdivisions=2)


@pytest.fixture(scope="module")
def data(tiny_data):
    """``build_dataset(sphere, CFG, encode=stripe_encoder, key=DATA_KEY)``, built once per session."""
    assert uses_tiny_data(CFG)
    return tiny_data


@pytest.fixture(scope="module")
def trained(data):
    return train(data, CFG, key=TRAIN_KEY, progress=False)


def test_copies_are_distinct_retriangulations_padded_to_one_bucket(sphere, data):
    assert data.latents.shape == (3, 96, 2)  # 80 vertices → bucket of 32
    assert data.num_vertices.tolist() == [80, 80, 80]
    assert not np.array_equal(data.meshes[0].vertices, data.meshes[1].vertices)
    vm = data.geometry.fine.vertex_mask
    assert vm.shape == (3, 96) and vm[:, :80].all() and not vm[:, 80:].any()
    assert np.all(data.latents[:, 80:] == 0)
    # latents are the encoder's on each copy; the scale gives unit mean |z|² (eq. 38–39)
    np.testing.assert_allclose(data.latents[1, :80], stripe_encoder(data.meshes[1]), rtol=1e-12)
    np.testing.assert_allclose(
        (np.abs(data.latents[:, :80] * data.scale) ** 2).mean((0, 1)), 1.0, rtol=1e-10
    )
    # copies are deterministic in (key, index), and another key gives other copies
    assert np.array_equal(copy_mesh(sphere, CFG, 1, key=DATA_KEY).faces, data.meshes[1].faces)
    assert not np.array_equal(
        copy_mesh(sphere, CFG, 1, key=jax.random.key(5)).vertices, data.meshes[1].vertices
    )


def test_cache_is_reused_and_invalidated(tmp_path, sphere):
    calls = []

    def enc(m):
        calls.append(1)
        return stripe_encoder(m)

    enc.identity = "counting"
    a = build_dataset(sphere, CFG, encode=enc, key=DATA_KEY, cache_dir=tmp_path, progress=False)
    b = build_dataset(sphere, CFG, encode=enc, key=DATA_KEY, cache_dir=tmp_path, progress=False)
    assert len(calls) == 3 and np.array_equal(a.latents, b.latents)
    assert sorted(p.name for p in tmp_path.glob("copy_*.npz")) == [
        "copy_0000.npz",
        "copy_0001.npz",
        "copy_0002.npz",
    ]
    other = jax.random.key(5)
    build_dataset(sphere, CFG, encode=enc, key=other, cache_dir=tmp_path, progress=False)
    assert len(calls) == 6  # another key: rebuilt
    assert (
        json.loads((tmp_path / "data.json").read_text())["key"]
        == jax.random.key_data(other).tolist()
    )
    with pytest.raises(ConfigError, match="encode must be a callable"):
        build_dataset(sphere, CFG, encode=None, key=other, cache_dir=tmp_path, progress=False)
    assert len(list(tmp_path.glob("copy_*.npz"))) == 3  # a bad call leaves the cache as it was


def test_labels_are_carried_to_the_copies(sphere):
    labels = (sphere.vertices[:, 2] > 0).astype(np.int64)
    copy = copy_mesh(sphere, CFG, 0, key=DATA_KEY)
    got = transfer_labels(sphere, labels, copy)
    far = np.abs(copy.vertices[:, 2]) > 0.3  # away from the label boundary: exact
    assert np.array_equal(got[far], (copy.vertices[far, 2] > 0).astype(np.int32))
    with pytest.raises(ConfigError, match="num_labels"):
        build_dataset(
            sphere, CFG, encode=stripe_encoder, key=DATA_KEY, labels=labels, progress=False
        )
    with pytest.raises(ConfigError, match="no labels"):
        build_dataset(
            sphere, CFG.replace(num_labels=2), encode=stripe_encoder, key=DATA_KEY, progress=False
        )
    with pytest.raises(ConfigError, match="latent_channels"):
        build_dataset(
            sphere,
            CFG.replace(latent_channels=3),
            encode=stripe_encoder,
            key=DATA_KEY,
            progress=False,
        )


def test_training_resumes_exactly_as_an_uninterrupted_run(tmp_path, data, trained):
    assert isinstance(trained, TrainResult) and trained.steps == 4 and trained.resumed_from is None
    assert trained.losses["loss"].shape == (4,) and np.isfinite(trained.losses["loss"]).all()
    ckpt = tmp_path / "ckpt"
    part = train(data, CFG, key=TRAIN_KEY, checkpoint_dir=ckpt, progress=False, stop_after=1)
    assert part.steps == 1 and part.resumed_from is None
    part = train(data, CFG, key=TRAIN_KEY, checkpoint_dir=ckpt, progress=False, stop_after=2)
    assert (
        part.steps == 3 and part.resumed_from == 1
    )  # off the checkpoint_every grid: the last step is kept
    rest = train(data, CFG, key=TRAIN_KEY, checkpoint_dir=ckpt, progress=False)
    assert rest.steps == 4 and rest.resumed_from == 3
    # bit-identical: the same step function on the same state, batches and noise from (key, step)
    np.testing.assert_array_equal(rest.losses["loss"], trained.losses["loss"])
    for a, b in zip(
        jax.tree.leaves(rest.model.params), jax.tree.leaves(trained.model.params), strict=True
    ):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    again = train(
        data, CFG, key=TRAIN_KEY, checkpoint_dir=ckpt, progress=False
    )  # done: nothing more to do
    assert again.steps == 4 and again.resumed_from == 4
    np.testing.assert_array_equal(again.losses["loss"], trained.losses["loss"])
    # a folder of another run is never resumed by mistake
    with pytest.raises(CheckpointMismatchError, match="config"):
        train(data, CFG.replace(hdim=5), key=TRAIN_KEY, checkpoint_dir=ckpt, progress=False)
    with pytest.raises(CheckpointMismatchError, match="key"):
        train(data, CFG, key=jax.random.key(9), checkpoint_dir=ckpt, progress=False)
    # another key is another run
    other = train(data, CFG, key=jax.random.key(9), progress=False)
    assert not np.allclose(other.losses["loss"], trained.losses["loss"])
    save(rest.model, tmp_path / "model")
    loaded = load(tmp_path / "model")
    assert loaded.config == CFG and np.array_equal(loaded.scale, data.scale)


def test_v_prediction_is_trained_saved_and_sampled_through(tmp_path, data, trained):
    """prediction="v" changes the training target (same init, batches and noise as the ε run, other
    losses), survives save/load, and the sampler reads the output through it."""
    cfg = CFG.replace(prediction="v")
    res = train(data, cfg, key=TRAIN_KEY, progress=False)
    loss, eps_loss = res.losses["loss"], trained.losses["loss"]
    assert np.isfinite(loss).all() and not np.allclose(loss, eps_loss)
    model = load(save(res.model, tmp_path))
    assert model.config.prediction == "v"
    mesh = data.meshes[0]
    as_v = sample(model, mesh, key=jax.random.key(0), num_samples=1, steps=5).latents
    as_eps = sample(
        dataclasses.replace(model, config=cfg.replace(prediction="epsilon")),
        mesh,
        key=jax.random.key(0),
        num_samples=1,
        steps=5,
    ).latents
    assert np.isfinite(as_v).all() and not np.allclose(as_v, as_eps)
    with pytest.raises(ConfigError, match="prediction"):
        CFG.replace(prediction="x0")


def test_sampling_reproducible_inpainting_exact_and_transfer(data, trained):
    model = trained.model
    mesh = data.meshes[0]
    a = sample(model, mesh, key=jax.random.key(0), num_samples=2, steps=5).latents
    b = sample(
        model, (mesh.vertices, mesh.faces), key=jax.random.key(0), num_samples=2, steps=5
    ).latents  # a (V, F) pair works too
    c = sample(model, mesh, key=jax.random.key(1), num_samples=1, steps=5).latents
    assert a.shape == (2, 80, 2) and np.array_equal(a, b) and not np.allclose(a[0], c[0])
    assert not np.allclose(a[0], a[1])
    known = stripe_encoder(mesh)
    mask = mesh.vertices[:, 2] > 0
    z = inpaint(model, mesh, known, mask, key=jax.random.key(2), method="ddim", steps=5).latents
    # exact up to the float32 round trip of the scale
    np.testing.assert_allclose(z[0][mask], known[mask], rtol=1e-6, atol=1e-6)
    assert not np.allclose(z[0][~mask], known[~mask], atol=1e-2)
    # inpainting samples with ancestral DDPM (all T steps) unless told otherwise
    z_default = inpaint(model, mesh, known, mask, key=jax.random.key(2)).latents
    z_ddpm = sample(
        model, mesh, key=jax.random.key(2), known=known, mask=mask, method="ddpm"
    ).latents
    np.testing.assert_array_equal(z_default, z_ddpm)
    assert not np.allclose(z_default, z)
    # generative transfer: any mesh, any size
    t = sample(
        model, torus(12, 6), key=jax.random.key(3), num_samples=1, steps=5, method="ddim"
    ).latents
    assert t.shape == (1, 72, 2) and np.isfinite(t).all()
    with pytest.raises(InputError, match="unconditional"):
        sample(model, mesh, key=jax.random.key(0), labels=np.zeros(80, int))
    with pytest.raises(InputError, match="both"):
        sample(model, mesh, key=jax.random.key(0), known=known)
    with pytest.raises(InputError, match="target must be a jmeshtex.Mesh"):
        sample(model, "sphere.obj", key=jax.random.key(0))
    for eta in (float("nan"), -1.0, 2.0, "0.5", True):
        with pytest.raises(InputError, match="eta must be a number in"):
            sample(model, mesh, key=jax.random.key(0), eta=eta)


@pytest.mark.slow
def test_label_guided_training_and_sampling(sphere):
    cfg = CFG.replace(num_labels=2, n_copies=2, steps=2)
    labels = (sphere.vertices[:, 2] > 0).astype(np.int64)
    data = build_dataset(
        sphere, cfg, encode=stripe_encoder, key=DATA_KEY, labels=labels, progress=False
    )
    assert data.labels.shape == (2, 96) and set(np.unique(data.labels[:, :80])) == {0, 1}
    model = train(data, cfg, key=TRAIN_KEY, progress=False).model
    mesh = data.meshes[0]
    key = jax.random.key(0)
    z0 = sample(model, mesh, key=key, steps=3, labels=np.zeros(80, int)).latents
    z1 = sample(model, mesh, key=key, steps=3, labels=np.ones(80, int)).latents
    assert not np.allclose(z0, z1)  # the label map reaches the filters
    with pytest.raises(InputError, match="label-guided"):
        sample(model, mesh, key=key, steps=3)


def _cli_train(mesh: str, out, *flags: str) -> int:
    """``jmeshtex fldm train`` on the tiny preset with the stripe codec, into ``out``."""
    from jmeshtex.cli._main import main

    args = [*TINY_CLI_TRAIN, "--mesh", mesh, "--codec", "stripes", *flags]
    return main([*args, "--out", str(out), "--quiet"])


def _cli_inpaint(model, mask, out, *flags: str) -> int:
    from jmeshtex.cli._main import main

    args = ["fldm", "inpaint", "--model", str(model), "--mask", str(mask), *flags]
    return main([*args, "--out", str(out), "--quiet"])


@pytest.mark.slow
def test_cli_train_sample_inpaint(tmp_path):
    from jmeshtex.cli._main import main

    out = tmp_path / "model"
    rc = _cli_train("icosphere:2", out)
    assert rc == 2  # icosphere has no colours to read: a clear error, no traceback
    rc = _cli_train("striped-sphere", out, "--prediction", "v")
    assert rc == 0 and (out / "model.npz").exists() and (out / "data" / "copy_0001.npz").exists()
    assert load(out).config.prediction == "v"  # the tiny preset's own is epsilon
    rc = main(
        [
            "fldm",
            "sample",
            "--model",
            str(out),
            "--vertices",
            "70",
            "--steps",
            "3",
            "--num-samples",
            "2",
            "--out",
            str(tmp_path / "s"),
            "--quiet",
        ]
    )
    assert rc == 0 and len(list((tmp_path / "s").glob("sample_*.png"))) == 2
    assert np.load(tmp_path / "s" / "latents.npz")["latents"].shape == (2, 70, 2)
    mesh = striped_sphere(subdivisions=3)
    np.save(tmp_path / "mask.npy", mesh.vertices[:, 2] > 0)
    rc = _cli_inpaint(out, tmp_path / "mask.npy", tmp_path / "i", "--steps", "3", "--n", "1")
    assert rc == 0 and len(list((tmp_path / "i").glob("inpaint_*.png"))) == 1
    masked = tmp_path / "masked"
    rc = _cli_train("striped-sphere", masked, "--mask-conditioning")
    assert rc == 0 and load(masked).config.mask_conditioning
    rc = _cli_inpaint(masked, tmp_path / "mask.npy", tmp_path / "mi", "--steps", "3", "--n", "1")
    assert rc == 0 and len(list((tmp_path / "mi").glob("inpaint_*.png"))) == 1
    np.save(tmp_path / "bad.npy", np.ones(5, bool))
    rc = _cli_inpaint(out, tmp_path / "bad.npy", tmp_path / "j")
    assert rc == 2

"""Every FLDM cache is keyed by what it depends on (issue 57, root cause 3): the copies' latents by the
input's colours, and a checkpoint folder by the latents themselves."""

from __future__ import annotations

import dataclasses
import json

import jax
import numpy as np
import pytest

from jmeshtex import CheckpointMismatchError, Mesh, fl, fldm
from jmeshtex.cli import main
from jmeshtex.data import icosphere
from jmeshtex.io import save_mesh
from tests.fldm.conftest import TINY_CLI_TRAIN

#: trainings of 1-2 steps: their steps compile at the suite's quick XLA level (conftest.py)
pytestmark = pytest.mark.few_steps

CFG = fldm.Config.tiny(
    latent_channels=8, n_copies=2, copy_vertices=60, bucket=32, steps=2, checkpoint_every=1
)


def _colored(colors: np.ndarray) -> Mesh:
    m = icosphere(2)
    return Mesh(m.vertices, m.faces, vertex_colors=np.broadcast_to(colors, (m.num_vertices, 3)))


def _bright(m: Mesh) -> np.ndarray:
    return np.where(m.vertices[:, :1] > 0, [0.9, 0.2, 0.1], [0.1, 0.3, 0.9])


@pytest.fixture(scope="module")
def vae():
    return fl.load_pretrained()


def _data(vae, mesh, cache):
    enc = fldm.fl_vae_encoder(vae, mesh, key=jax.random.key(1))
    return fldm.build_dataset(
        mesh, CFG, encode=enc, key=jax.random.key(0), cache_dir=cache, progress=False
    )


def test_new_colours_rebuild_the_copies_and_refuse_the_old_run(vae, tmp_path):
    """The issue's reproducer: same geometry, new colours, same folder."""
    grey = _colored(np.full(3, 0.5))
    a = _data(vae, grey, tmp_path / "data")
    fldm.train(a, CFG, key=jax.random.key(2), checkpoint_dir=tmp_path / "ckpt", progress=False)
    again = _data(vae, grey, tmp_path / "data")  # same input: the cache is reused, bit for bit
    np.testing.assert_array_equal(again.latents, a.latents)
    assert fldm.core.data_digest(again) == fldm.core.data_digest(a)

    m = icosphere(2)
    painted = Mesh(m.vertices, m.faces, vertex_colors=_bright(m))
    b = _data(vae, painted, tmp_path / "data")
    assert not np.allclose(b.latents, a.latents)  # new latents, not the old cache
    with pytest.raises(CheckpointMismatchError):  # never "trained 0 steps" on the old run
        fldm.train(b, CFG, key=jax.random.key(2), checkpoint_dir=tmp_path / "ckpt", progress=False)


def test_same_shape_and_scale_other_latents_are_another_run(tmp_path):
    """Latents with the same shapes and the same scale (a permutation) still fingerprint apart."""
    cfg = fldm.Config.tiny(latent_channels=1, n_copies=1, copy_vertices=40, bucket=32, steps=1)
    d = fldm.build_dataset(
        icosphere(1),
        cfg,
        encode=lambda m: m.vertices[:, :1] + 0j,
        key=jax.random.key(0),
        progress=False,
    )
    lat = d.latents.copy()
    n = int(d.num_vertices[0])
    lat[0, :n] = lat[0, :n][::-1]
    e = d._replace(latents=lat)
    np.testing.assert_allclose(fldm.core.latent_scale(e.latents[:, :n]), d.scale)
    fldm.train(d, cfg, key=jax.random.key(1), checkpoint_dir=tmp_path, progress=False)
    with pytest.raises(CheckpointMismatchError):
        fldm.train(e, cfg, key=jax.random.key(1), checkpoint_dir=tmp_path, progress=False)


@pytest.mark.parametrize("field, value", [("phase_sync", "all"), ("latent_scaling", "released")])
def test_settings_that_change_the_data_rebuild_it(tmp_path, field, value):
    mesh = _colored(np.full(3, 0.5))
    cfg = fldm.Config.tiny(latent_channels=1, n_copies=1, copy_vertices=40, bucket=32)
    enc = lambda m: np.exp(1j * m.vertices[:, :1])  # noqa: E731
    enc.identity = "test"
    kw = dict(encode=enc, key=jax.random.key(0), cache_dir=tmp_path, progress=False)
    fldm.build_dataset(mesh, cfg, **kw)
    before = json.loads((tmp_path / "data.json").read_text())
    fldm.build_dataset(mesh, cfg.replace(**{field: value}), **kw)
    after = json.loads((tmp_path / "data.json").read_text())
    if field == "phase_sync":  # changes the stored latents: part of the cache key
        assert after != before
    else:  # the scale is computed after the cache, from the latents: the key stays
        assert after == before


def test_cli_retrain_with_new_colours_is_not_a_resume(tmp_path, capsys):
    """``fldm train`` twice into one folder, the second time with new colours on the same mesh."""
    m = icosphere(2)
    save_mesh(
        Mesh(m.vertices, m.faces, vertex_colors=np.full((m.num_vertices, 3), 0.5)),
        tmp_path / "a.ply",
    )
    save_mesh(Mesh(m.vertices, m.faces, vertex_colors=_bright(m)), tmp_path / "b.ply")
    args = list(TINY_CLI_TRAIN)
    out = tmp_path / "run"
    assert main([*args, "--mesh", str(tmp_path / "a.ply"), "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    rc = main([*args, "--mesh", str(tmp_path / "b.ply"), "--out", str(out), "--quiet"])
    text = capsys.readouterr()
    assert rc != 0 and "trained 0 steps" not in text.out, text


def test_released_noise_scale():
    """``sigma = sqrt(2) mean|mu|`` per real noise component on raw latents = unit complex noise on
    ``mu / (sqrt(2) sigma)``: one scale ``1 / (2 mean|mu|)``."""
    mu = np.array([[2.0 + 0j, 1j], [2j, -1.0 + 0j]])
    np.testing.assert_allclose(fldm.core.latent_scale(mu, released=True), [1 / 3, 1 / 3])
    mask = np.array([True, False])
    np.testing.assert_allclose(fldm.core.latent_scale(mu, mask, released=True), [1 / 3, 1 / 3])


def test_the_cache_is_keyed_by_the_encoder_not_the_decoder(vae):
    """A decoder fine-tuned later leaves the latents as they were, so the copies stay valid; any
    change to the encoder's weights makes another cache."""
    mesh = _colored(np.full(3, 0.5))

    def identity(model):
        return fldm.fl_vae_encoder(model, mesh, key=jax.random.key(1)).identity

    def nudged(params):
        return jax.tree.map(lambda a: a * 1.001, params)

    new_decoder = dataclasses.replace(
        vae, params=vae.params._replace(decoder=nudged(vae.params.decoder))
    )
    new_encoder = dataclasses.replace(
        vae, params=vae.params._replace(encoder=nudged(vae.params.encoder))
    )
    assert identity(new_decoder) == identity(vae)
    assert identity(new_encoder) != identity(vae)

"""FLDM training options of issue 35: gradient accumulation, the L1 loss, global latent scaling,
collapsed channels, several encodings per copy, and the decoder-free statistics logged at every
checkpoint (resumed with the run, written into the model card)."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import ConfigError
from jmeshtex.data import icosphere
from jmeshtex.fldm import Config, build_dataset, load, save, train
from jmeshtex.fldm._model import model_card
from jmeshtex.fldm._train import _device_resident, channel_weights
from jmeshtex.fldm.core import (
    epsilon_loss,
    init_denoiser,
    latent_scale,
    make_train_step,
    optimizer,
    training_batch,
)


def _encoder(seed=0, weights=(1.0, 0.5)):
    rng = np.random.default_rng(seed)

    def encode(m):
        x = np.asarray(m.vertices)
        phase = np.exp(1j * rng.uniform(0, 2 * np.pi, (len(x), 1)))  # a fresh draw per call
        return np.stack([1.5 + x[:, 0], 1.2 + x[:, 1]], 1) * np.asarray(weights) * phase

    encode.identity = f"test-encoder:{weights}"  # a cache built with it may be reused
    return encode


#: every training here runs at most 4 steps: its steps compile at the suite's quick level (conftest.py)
pytestmark = pytest.mark.few_steps

CFG = Config.tiny(
    latent_channels=2, n_copies=3, copy_vertices=60, bucket=32, widths=(6, 8), diffusion_steps=50
)


@pytest.fixture(scope="module")
def data():
    return build_dataset(
        icosphere(2), CFG, encode=_encoder(), key=jax.random.key(0), progress=False
    )


def test_gradient_accumulation_equals_the_whole_batch(data):
    cfg = CFG.replace(batch_size=4)
    params = init_denoiser(jax.random.key(1), cfg, dtype=jnp.complex128)
    z0, geo, labels = training_batch(data, 0, 4, key=jax.random.key(2), dtype=jnp.complex128)
    out = {}
    for a in (1, 2, 4):
        c = cfg.replace(accumulate=a)
        out[a] = make_train_step(c)(
            params, optimizer(c).init(params), z0, geo, labels, jax.random.key(3)
        )
    for a in (2, 4):
        assert abs(float(out[a][2]) - float(out[1][2])) < 1e-10
        for x, y in zip(jax.tree.leaves(out[a][0]), jax.tree.leaves(out[1][0]), strict=True):
            np.testing.assert_allclose(np.asarray(x), np.asarray(y), atol=1e-8)


def test_l1_loss_and_channel_weights():
    pred = jnp.array([[3 + 4j, 1.0]], jnp.complex64)
    eps = jnp.zeros((1, 2), jnp.complex64)
    assert float(epsilon_loss(pred, eps, kind="l1")) == pytest.approx(3.0)  # (5 + 1) / 2
    assert float(epsilon_loss(pred, eps)) == pytest.approx(13.0)  # (25 + 1) / 2
    w = jnp.array([0.0, 1.0])
    assert float(epsilon_loss(pred, eps, kind="l1", channel_weight=w)) == pytest.approx(0.5)
    with pytest.raises(ConfigError, match="kind"):
        epsilon_loss(pred, eps, kind="l3")


def test_global_latent_scale():
    mu = np.array([[2.0 + 0j, 1j], [2j, -1.0 + 0j]])
    np.testing.assert_allclose(latent_scale(mu), [0.5, 1.0])
    s = latent_scale(mu, per_channel=False)
    np.testing.assert_allclose(s, [1 / np.sqrt(2.5)] * 2)  # mean power over channels 2.5
    d = build_dataset(
        icosphere(1),
        CFG.replace(latent_scaling="global", n_copies=1),
        encode=_encoder(),
        key=jax.random.key(0),
        progress=False,
    )
    assert d.scale[0] == d.scale[1]


def test_collapsed_channels(data):
    enc = _encoder(weights=(1.0, 0.01))
    d = build_dataset(icosphere(1), CFG, encode=enc, key=jax.random.key(0), progress=False)
    w, keep = channel_weights(d, CFG)
    assert w.tolist() == [1.0, 1.0] and keep.all()
    w, keep = channel_weights(d, CFG.replace(collapsed_channels="downweight"))
    assert w[0] == 1.0 and 0 < w[1] < 1e-3 and keep.all()
    w, keep = channel_weights(d, CFG.replace(collapsed_channels="drop"))
    assert keep.tolist() == [True, False]
    # the data set's own channels are not collapsed: every option leaves them alone
    for option in ("downweight", "drop"):
        w, keep = channel_weights(data, CFG.replace(collapsed_channels=option))
        assert w.tolist() == [1.0, 1.0] and keep.all()


def test_encodings_per_copy_are_all_drawn(tmp_path):
    cfg = CFG.replace(encodings_per_copy=3, n_copies=2)
    d = build_dataset(
        icosphere(1), cfg, encode=_encoder(), key=jax.random.key(0), cache_dir=tmp_path
    )
    assert d.encodings.shape == (2, 2, d.latents.shape[1], 2)
    again = build_dataset(
        icosphere(1), cfg, encode=_encoder(seed=9), key=jax.random.key(0), cache_dir=tmp_path
    )
    assert again.encodings is not None and np.array_equal(again.encodings, d.encodings)
    seen = set()
    for step in range(30):
        z0, _, _ = training_batch(d, step, 2, key=jax.random.key(1))
        for b in range(2):
            for i in range(2):
                options = [d.latents[i]] + list(d.encodings[i])
                for k, o in enumerate(options):
                    if np.allclose(z0[b], o * d.scale, atol=1e-5):
                        seen.add((i, k))
    assert seen == {(i, k) for i in range(2) for k in range(3)}
    # on an accelerator the data set is sent to the device once and batches are gathered there
    resident = _device_resident(d, jnp.complex64)
    assert isinstance(resident.encodings, jax.Array)
    for step in range(4):
        host = training_batch(d, step, 2, key=jax.random.key(1))
        device = training_batch(resident, step, 2, key=jax.random.key(1))
        np.testing.assert_allclose(np.asarray(device[0]), host[0], rtol=1e-6, atol=1e-7)
        for a, b in zip(jax.tree.leaves(device[1]), jax.tree.leaves(host[1]), strict=True):
            np.testing.assert_allclose(np.asarray(a), b, rtol=1e-6, atol=1e-7)


def test_statistics_logged_at_checkpoints_resumed_and_carded(data, tmp_path):
    cfg = CFG.replace(steps=4, checkpoint_every=2, stats_samples=1, stats_ddim_steps=2)
    first = train(
        data, cfg, key=jax.random.key(5), progress=False, checkpoint_dir=tmp_path, stop_after=2
    )
    assert [r["step"] for r in first.extra["statistics"]] == [2]
    # the statistics settings are not part of the run's fingerprint: a resume may change them
    rest = train(
        data,
        cfg.replace(stats_samples=2),
        key=jax.random.key(5),
        progress=False,
        checkpoint_dir=tmp_path,
    )
    hist = rest.extra["statistics"]
    assert rest.resumed_from == 2 and [r["step"] for r in hist] == [2, 4]
    assert "data" in hist[0] and hist[0]["data"]["concentration"] > 0.99
    for r in hist:
        assert {"concentration", "energy_correlation", "phase_coherence", "rms"} <= set(r)
        assert all(np.isfinite(r[k]) for k in ("concentration", "energy_correlation"))
    folder = save(rest.model, tmp_path / "model", card=model_card(rest))
    card = json.loads((folder / "card.json").read_text())
    assert card["steps"] == 4 and [r["step"] for r in card["statistics"]] == [2, 4]
    assert load(folder).config == cfg.replace(stats_samples=2)


def test_new_config_rules():
    with pytest.raises(ConfigError, match="multiple of accumulate"):
        Config(batch_size=4, accumulate=3)
    for field, bad in (
        ("loss", "l3"),
        ("latent_scaling", "none"),
        ("collapsed_channels", "zero"),
        ("collapsed_below", 1.5),
        ("encodings_per_copy", 0),
        ("stats_samples", -1),
        ("stats_ddim_steps", 0),
    ):
        with pytest.raises(ConfigError, match=field):
            Config.from_dict({field: bad})
    p = Config.paper()
    assert (p.schedule, p.batch_size // p.accumulate, p.loss, p.latent_scaling) == (
        "cosine",
        4,
        "l1",
        "released",
    )


def test_training_on_an_accelerator_gathers_on_the_device_and_trains_the_same(data, monkeypatch):
    """CI has no GPU: the accelerator branch of ``train`` (data sent to the device once, batches
    gathered by one compiled call) is taken by faking the backend's name, and must give the host
    branch's losses and weights up to complex64 round-off."""
    from jmeshtex.fldm import _train

    cfg = CFG.replace(steps=4, encodings_per_copy=1, ema_decay=0.0)
    host = train(data, cfg, key=jax.random.key(3), progress=False)
    sent = []
    real = _train._device_resident
    monkeypatch.setattr(_train, "_device_resident", lambda *a: sent.append(1) or real(*a))
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    device = train(data, cfg, key=jax.random.key(3), progress=False)
    assert sent == [1]  # the accelerator branch ran, once per call
    np.testing.assert_allclose(device.losses["loss"], host.losses["loss"], rtol=1e-5)
    for a, b in zip(
        jax.tree.leaves(device.model.params), jax.tree.leaves(host.model.params), strict=True
    ):
        np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-5)  # Adam scales round-off up

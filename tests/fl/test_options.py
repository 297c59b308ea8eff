"""The FL-VAE's reference options: the centre token, the blended log objective, KL control, boundary
rings, the per-channel norm and the attention's linear path; old configs keep the old behaviour."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import ConfigError, InputError
from jmeshtex.data import grid
from jmeshtex.fl import Config, init, load, load_pretrained
from jmeshtex.fl._decoder import blend_log_predictions
from jmeshtex.fl._train import boundary_vertices
from jmeshtex.fl.core import (
    batch_loss,
    encode_one_rings,
    encode_samples,
    make_train_step,
    mesh_batch,
    one_ring_samples,
    optimizer,
    planar_mesh,
    vae_loss,
)
from tests._presets import FL_MICRO

TINY = FL_MICRO.replace(latent_dim=3, num_samples=6)


def _batch(config, seed=0, n=2):
    rng = np.random.default_rng(seed)
    meshes = [planar_mesh(rng.random((12, 12, 3)), 20, rng=rng) for _ in range(n)]
    return mesh_batch(meshes, config, rng, num_vertices=20 * n + 3), meshes


def test_centre_column_is_the_vertex_itself():
    v, f = grid(3)
    s = one_ring_samples(v, f, 5, rng=np.random.default_rng(0), center=True)
    plain = one_ring_samples(v, f, 5, rng=np.random.default_rng(0))
    assert s.centered and not plain.centered and s.log.shape == (len(v), 6)
    np.testing.assert_array_equal(s.log[:, 0], 0)
    np.testing.assert_array_equal(s.log[:, 1:], plain.log)  # the same draws behind the centre
    point = np.einsum("vk,vkd->vd", s.bary[:, 0], np.asarray(v)[np.asarray(f)[s.face[:, 0]]])
    np.testing.assert_allclose(point, v, atol=1e-12)


def test_the_centre_token_reads_the_centre_colour_and_the_ring_mean_token_does_not():
    c = TINY
    params = init(c, key=jax.random.key(0)).params
    legacy = c.replace(token="ring_mean")
    rng = np.random.default_rng(1)
    log = jnp.asarray(np.exp(1j * rng.uniform(0, 6, (4, 7))) * rng.uniform(0.2, 1, (4, 7)))
    log = log.at[:, 0].set(0).astype(jnp.complex64)
    rgb = jnp.asarray(rng.random((4, 7, 3)), jnp.float32)
    mask = jnp.ones((4, 7), bool)
    other = rgb.at[:, 0].set(1.0 - rgb[:, 0])
    enc = jax.jit(encode_samples, static_argnums=1)
    assert (
        float(
            jnp.abs(enc(params, c, log, other, mask).mu - enc(params, c, log, rgb, mask).mu).max()
        )
        > 1e-3
    )
    # the ring-mean token of a ring whose column 0 has log 0: its colour enters only the mean
    a, b = enc(params, legacy, log, rgb, mask).mu, enc(params, legacy, log, other, mask).mu
    assert float(jnp.abs(a - b).max()) > 1e-4
    # gauge equivariance holds with the centre token
    turn = jnp.exp(-0.7j).astype(jnp.complex64)
    np.testing.assert_allclose(
        enc(params, c, log * turn, rgb, mask).mu,
        enc(params, c, log, rgb, mask).mu * turn,
        atol=1e-5,
    )


def test_encode_one_rings_refuses_samples_drawn_for_the_other_token():
    model = init(TINY, key=jax.random.key(0))
    s = one_ring_samples(*grid(2), 4, rng=np.random.default_rng(0))
    with pytest.raises(InputError, match="center=True"):
        encode_one_rings(model, s, np.full((*s.log.shape, 3), 0.5))


def test_corner_logs_of_the_own_corner_are_the_ring_logs():
    batch, meshes = _batch(TINY)
    corners, logs = batch["corners"], batch["corner_logs"]
    own = corners == np.arange(len(corners))[:, None, None]  # [N, S, 3]
    real = batch["mask"]
    assert (own.sum(-1)[real] == 1).all()
    got = (logs * own).sum(-1)
    np.testing.assert_allclose(got[real], batch["log"][real], atol=1e-5)


def test_the_blended_objective_decodes_each_sample_from_its_three_corners():
    c = TINY
    params = init(c, key=jax.random.key(0)).params
    batch, _ = _batch(c)
    b = {k: jnp.asarray(v) for k, v in batch.items()}
    tiny_sigma = params._replace(
        encoder=params.encoder._replace(
            sigma=(params.encoder.sigma[0] * 0, params.encoder.sigma[1] * 0 - 30.0)
        )
    )  # σ = e^-30: the draw is the mean
    loss, aux = vae_loss(
        tiny_sigma, c, b["log"], b["rgb"], b["mask"], key=jax.random.key(1),
        corners=b["corners"], bary=b["bary"], vertex_mask=b["vertex_mask"],
        corner_logs=b["corner_logs"],
    )  # fmt: skip
    mu = encode_samples(tiny_sigma, c, b["log"], b["rgb"], b["mask"]).mu
    n, s = b["log"].shape
    pred = blend_log_predictions(
        tiny_sigma.decoder, c, mu, b["corners"].reshape(-1, 3), b["corner_logs"].reshape(-1, 3),
        b["bary"].reshape(-1, 3),
    ).reshape(n, s, 3)  # fmt: skip
    m = (b["mask"] & b["vertex_mask"][:, None]).astype(jnp.float32)
    expected = jnp.sum(jnp.abs(pred - b["rgb"]).sum(-1) * m) / (3 * m.sum())
    np.testing.assert_allclose(aux["l1"], expected, rtol=1e-5)
    vertex = vae_loss(
        tiny_sigma, c.replace(log_objective="vertex"), b["log"], b["rgb"], b["mask"],
        key=jax.random.key(1), vertex_mask=b["vertex_mask"],
    )[1]["l1"]  # fmt: skip
    assert abs(float(vertex) - float(aux["l1"])) > 1e-4  # the two objectives differ
    with pytest.raises(InputError, match="corner_logs"):
        vae_loss(params, c, b["log"], b["rgb"], b["mask"], key=jax.random.key(1))


def _loss(config, batch, params, scale=1.0):
    b = {k: jnp.asarray(v) for k, v in batch.items()}
    return batch_loss(params, config, b, key=jax.random.key(1), kl_scale=scale)


def test_free_bits_floor_each_channel_and_the_warm_up_scales_the_kl():
    c = TINY.replace(loss_normalization="paper")
    params = init(c, key=jax.random.key(0)).params
    batch, _ = _batch(c)
    loss, aux = _loss(c, batch, params)
    channels = np.asarray(aux["kl_channels"])
    assert channels.shape == (3,)
    np.testing.assert_allclose(aux["kl"], channels.sum(), rtol=1e-6)
    np.testing.assert_allclose(loss, aux["l1"] + c.kl_weight * channels.sum(), rtol=1e-6)
    tau = float(channels.max()) + 1.0
    floored, aux_f = _loss(c.replace(free_bits=tau), batch, params)
    np.testing.assert_allclose(floored, aux_f["l1"] + c.kl_weight * 3 * tau, rtol=1e-6)
    # every channel under the floor: the KL term has no gradient left
    g = jax.grad(lambda p: _loss(c.replace(free_bits=tau, kl_weight=1.0), batch, p)[0])(params)
    g0 = jax.grad(lambda p: _loss(c.replace(kl_weight=0.0), batch, p)[0])(params)
    for a, b in zip(jax.tree.leaves(g), jax.tree.leaves(g0), strict=True):
        np.testing.assert_allclose(a, b, atol=1e-6)
    half, aux_h = _loss(c, batch, params, scale=0.5)
    np.testing.assert_allclose(half, aux_h["l1"] + 0.5 * c.kl_weight * channels.sum(), rtol=1e-5)


def test_warm_up_in_the_train_step_follows_the_step_index():
    c = TINY.replace(kl_warmup_steps=10, kl_weight=1.0)
    params = init(c, key=jax.random.key(0)).params
    batch, _ = _batch(c)
    step = make_train_step(c)
    state = optimizer(c).init(params)
    early = step(params, state, batch, jax.random.key(1), np.int32(0))
    late = step(params, state, batch, jax.random.key(1), np.int32(50))
    for out, scale in ((early, 0.1), (late, 1.0)):
        aux = out[3]
        np.testing.assert_allclose(out[2], aux["l1"] + scale * aux["kl"], rtol=1e-5)
        assert {f"kl{i}" for i in range(3)} <= set(aux)


def test_dropping_boundary_rings_masks_exactly_the_boundary_vertices():
    c = TINY.replace(boundary_in_loss=False)
    batch, meshes = _batch(c, n=1)
    bnd = boundary_vertices(meshes[0].faces, meshes[0].num_vertices)
    assert 0 < bnd.sum() < len(bnd)
    np.testing.assert_array_equal(batch["vertex_mask"][: len(bnd)], ~bnd)
    assert not batch["vertex_mask"][len(bnd) :].any()


def test_per_channel_norm_and_linear_path_keep_gauge_equivariance_and_add_parameters():
    base = TINY.replace(token="centre")
    c = base.replace(vn_norm="channel", attention_linear=True)
    params = init(c, key=jax.random.key(0)).params
    assert params.encoder.blocks[0].attention.linear.shape == (8, 8)
    assert init(base, key=jax.random.key(0)).params.encoder.blocks[0].attention.linear is None
    batch, _ = _batch(c)
    log, rgb, mask = (jnp.asarray(batch[k]) for k in ("log", "rgb", "mask"))
    turn = jnp.exp(0.4j).astype(jnp.complex64)
    enc = jax.jit(encode_samples, static_argnums=1)
    np.testing.assert_allclose(
        enc(params, c, log * turn, rgb, mask).mu,
        enc(params, c, log, rgb, mask).mu * turn,
        atol=1e-4,
    )
    # padded vertices (no valid sample) do not enter the per-channel statistic
    pad = jnp.concatenate([log, jnp.full((5, log.shape[1]), 3.0 + 1j, log.dtype)])
    padded = enc(params, c, pad, jnp.concatenate([rgb, jnp.ones((5, *rgb.shape[1:]), rgb.dtype)]),
                 jnp.concatenate([mask, jnp.zeros((5, mask.shape[1]), bool)]))  # fmt: skip
    np.testing.assert_allclose(padded.mu[: len(log)], enc(params, c, log, rgb, mask).mu, atol=1e-5)


def test_a_model_file_of_another_version_or_lacking_fields_is_refused_by_name(tmp_path):
    from jmeshtex import CorruptModelError
    from jmeshtex.fl._io import FORMAT_VERSION, MODEL_KIND
    from jmeshtex.io import save_model

    model = init(TINY, key=jax.random.key(0))
    params = jax.tree.map(np.asarray, model.params)
    # a file of format version 1 (before every config field was stored): refused, naming it
    save_model(tmp_path / "v1.npz", kind=MODEL_KIND, params=params, config=TINY.to_dict(),
               format_version=1)  # fmt: skip
    with pytest.raises(CorruptModelError, match="format version 1; this jmeshtex reads 2"):
        load(tmp_path / "v1.npz")
    # the current version with fields missing: refused, naming them (never filled with defaults)
    stored = {k: v for k, v in TINY.to_dict().items() if k not in ("token", "log_objective")}
    save_model(tmp_path / "v2.npz", kind=MODEL_KIND, params=params, config=stored,
               format_version=FORMAT_VERSION)  # fmt: skip
    with pytest.raises(CorruptModelError, match=r"lacks fields \['log_objective', 'token'\]"):
        load(tmp_path / "v2.npz")
    # a complete file reads back as written; the shipped models were converted to it
    save_model(tmp_path / "ok.npz", kind=MODEL_KIND, params=params, config=TINY.to_dict(),
               format_version=FORMAT_VERSION)  # fmt: skip
    assert load(tmp_path / "ok.npz").config == TINY
    for name in ("log", "barycentric"):
        assert load_pretrained(decoder=name).config.experimental.token == "centre"


@pytest.mark.parametrize(
    "changes",
    [
        {"token": "mean"},
        {"log_objective": "corner"},
        {"vn_norm": "batch"},
        {"kl_warmup_steps": -1},
        {"free_bits": -0.1},
        {"attention_linear": 1},
        {"boundary_in_loss": "no"},
        {"log_sigma_init": 3.0},
        {"extra_images": "yes"},
        {"log_sigma_init": -21.0},
    ],
)
def test_new_fields_are_validated(changes):
    with pytest.raises(ConfigError):
        Config.from_dict(changes)


def test_extra_images_are_matplotlib_sample_data_never_a_held_out_one():
    from jmeshtex.fl import training_images
    from jmeshtex.fl._textures import HELD_OUT_MATPLOTLIB_IMAGES, MATPLOTLIB_IMAGES

    assert not set(HELD_OUT_MATPLOTLIB_IMAGES) & set(MATPLOTLIB_IMAGES)
    base = training_images(max_size=48)
    more = training_images(max_size=48, extra=True)
    assert len(more) == len(base) + len(MATPLOTLIB_IMAGES)
    for im in more[len(base) :]:
        assert im.ndim == 3 and im.shape[2] == 3 and max(im.shape[:2]) <= 48
        assert 0 <= im.min() and im.max() <= 1 and np.ptp(im) > 0.3  # not blank

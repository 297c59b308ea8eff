"""Stream-mode training data: textures from a key, meshes at a pixel density, the held-out images,
the presets, the paper's loss by hand, and resumable stream-mode training."""

from __future__ import annotations

import hashlib
import shutil

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import InputError
from jmeshtex.fl import Config, held_out_images, init, train
from jmeshtex.fl._textures import image_levels
from jmeshtex.fl._train import _load_images
from jmeshtex.fl.core import (
    HELD_OUT_IMAGES,
    PROCEDURAL_KINDS,
    TRAINING_IMAGES,
    augmented_crop,
    decode_points,
    density_mesh,
    encode_samples,
    procedural_texture,
    sample_latents,
    training_meshes,
    training_texture,
    vae_loss,
)
from tests._presets import FL_MICRO, FL_SHORT_RUN, FL_SMALL

STREAM = FL_MICRO.replace(
    pixels_per_vertex=8.0,
    density_spread=1.3,
    texture_size=16,
    procedural_fraction=1.0,
    loss_normalization="paper",
    **FL_SHORT_RUN,
)


def _digest(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a, np.float64).tobytes()).hexdigest()


def test_procedural_textures_are_functions_of_the_key():
    for kind in PROCEDURAL_KINDS:
        a = procedural_texture(jax.random.key(1), 32, kind=kind)
        assert a.shape == (32, 32, 3) and a.min() >= 0 and a.max() <= 1
        np.testing.assert_array_equal(a, procedural_texture(jax.random.key(1), 32, kind=kind))
        assert not np.array_equal(a, procedural_texture(jax.random.key(2), 32, kind=kind))
        assert a.std() > 0.02, kind  # not a flat colour
    with pytest.raises(InputError, match="kind"):
        procedural_texture(jax.random.key(0), 32, kind="plaid")
    with pytest.raises(InputError, match="key"):
        procedural_texture(3, 32)


def test_hundreds_of_distinct_textures_from_images_and_procedures():
    img = np.random.default_rng(0).random((96, 80, 3))
    crops = [augmented_crop(img, jax.random.key(i), 16) for i in range(3)]
    np.testing.assert_array_equal(crops[0], augmented_crop(img, jax.random.key(0), 16))
    assert all(c.shape == (16, 16, 3) and 0 <= c.min() and c.max() <= 1 for c in crops)
    textures = [
        training_texture(jax.random.key(i), [img], size=12, procedural_fraction=0.5)
        for i in range(300)
    ]
    assert len({_digest(t) for t in textures}) == 300
    with pytest.raises(InputError, match="no images"):
        training_texture(jax.random.key(0), [], size=12, procedural_fraction=0.5)


def test_meshes_have_the_requested_pixels_per_vertex():
    """Measured, not assumed: the texels a mesh's triangles cover (uv areas × texture size) per vertex."""
    for ppv in (26.0, 18.0):
        cfg = Config.small(
            pixels_per_vertex=ppv, density_spread=1.0, texture_size=48, procedural_fraction=1.0
        )
        meshes = training_meshes(jax.random.key(0), cfg, images=[])
        assert len(meshes) == cfg.batch_size
        for m in meshes:
            h, w = m.texture.shape[:2]
            e1, e2 = m.uv[:, 1] - m.uv[:, 0], m.uv[:, 2] - m.uv[:, 0]
            texels = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum() * h * w
            assert texels / m.num_vertices == pytest.approx(ppv, rel=0.01)
    # density_spread: densities drawn in [ppv / s, ppv · s], not all equal
    cfg = Config.small(texture_size=48, procedural_fraction=1.0, batch_size=12, density_spread=1.5)
    v = np.array([m.num_vertices for m in training_meshes(jax.random.key(1), cfg, images=[])])
    ppv = 48 * 48 / v
    assert ppv.min() >= 26 / 1.5 - 0.5 and ppv.max() <= 26 * 1.5 + 0.5 and np.ptp(v) > 10
    # the same key, the same meshes
    a = training_meshes(jax.random.key(2), STREAM, images=[])
    b = training_meshes(jax.random.key(2), STREAM, images=[])
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.vertices, y.vertices)
        np.testing.assert_array_equal(x.texture, y.texture)
    with pytest.raises(InputError):
        density_mesh(np.zeros((8, 8, 3)), 0.0, rng=np.random.default_rng(0))


def test_held_out_images_are_never_training_images():
    assert (
        not set(HELD_OUT_IMAGES) & set(TRAINING_IMAGES) and "cat" not in TRAINING_IMAGES
    )  # cat is chelsea
    held = {_digest(im) for im in held_out_images(max_size=64)}
    # what train() loads by default in the stream mode
    loaded = _load_images(None, 64, stream=True)
    assert len(loaded) == len(TRAINING_IMAGES)
    assert not held & {_digest(im) for im in loaded}
    # and no pyramid level of a training image is a held-out image either
    assert not held & {_digest(lv) for im in loaded for lv in image_levels(im)}


def test_presets():
    p, s = Config.paper(), Config.small()
    assert (p.features, p.num_blocks, p.num_heads, p.decoder_features, p.decoder_layers) == (
        128,
        8,
        8,
        512,
        5,
    )
    assert p.kl_weight == 0.01 and s.kl_weight == 1e-3  # small: no KL collapse (fl_vae_curve_kl)
    for c in (p, s):
        assert c.loss_normalization == "paper" and c.latent_dim == 8
        assert c.learning_rate == 1e-3 and c.learning_rate * c.final_lr_fraction == pytest.approx(
            1e-5
        )
        assert 20 <= c.pixels_per_vertex <= 30
    assert Config.small(steps=5).steps == 5
    assert Config().loss_normalization == "mean"  # the shipped model's recipe stays the default


def test_loss_is_the_papers_equation_by_hand():
    """Eq. 26–28: mean over samples of the RGB L1 norm, plus λ times the KL summed over the d channels
    (KL of N(μ, σ²I₂) to N(0, I₂) from the general Gaussian formula), averaged over real vertices."""
    # each ring from its own latent (the blended one: test_options)
    c = FL_SMALL.replace(kl_weight=0.37, log_objective="vertex")
    params = init(c, key=jax.random.key(0), dtype=jnp.float64).params
    rng = np.random.default_rng(0)
    v, s = 3, 5
    log = jnp.asarray(rng.normal(size=(v, s)) + 1j * rng.normal(size=(v, s)))
    rgb = jnp.asarray(rng.random((v, s, 3)))
    mask = np.ones((v, s), bool)
    mask[1, 3:] = False
    vmask = np.array([True, True, False])
    key = jax.random.key(4)
    lat = jax.jit(encode_samples, static_argnums=1)(params, c, log, rgb, jnp.asarray(mask))
    z = sample_latents(lat, key=key)
    pred = np.asarray(jax.jit(decode_points, static_argnums=1)(params, c, z, log))
    mu, sigma = np.asarray(lat.mu), np.exp(np.asarray(lat.log_sigma))
    l1 = sum(
        np.abs(pred[p, i] - np.asarray(rgb)[p, i]).sum()
        for p in range(v)
        for i in range(s)
        if mask[p, i] and vmask[p]  # vertex_mask: the rings that enter the loss
    )
    l1 /= (mask & vmask[:, None]).sum()
    kl = 0.0
    for p in np.flatnonzero(vmask):
        for ch in range(c.latent_dim):
            cov = sigma[p, ch] ** 2 * np.eye(2)
            m = np.array([mu[p, ch].real, mu[p, ch].imag])
            kl += 0.5 * (np.trace(cov) + m @ m - 2 - np.log(np.linalg.det(cov)))
    kl /= vmask.sum()
    for norm, want_l1, want_kl in (("paper", l1, kl), ("mean", l1 / 3, kl / c.latent_dim)):
        cfg = c.replace(loss_normalization=norm)
        loss, aux = jax.jit(vae_loss, static_argnums=1)(
            params, cfg, log, rgb, jnp.asarray(mask), key=key, vertex_mask=jnp.asarray(vmask)
        )
        np.testing.assert_allclose(float(aux["l1"]), want_l1, rtol=1e-10)
        np.testing.assert_allclose(float(aux["kl"]), want_kl, rtol=1e-10)
        np.testing.assert_allclose(float(loss), want_l1 + 0.37 * want_kl, rtol=1e-10)


@pytest.mark.few_steps  # 4 steps: compiled at the suite's quick XLA level (conftest.py)
def test_stream_training_resumes_exactly_and_draws_a_loss_curve(tmp_path):
    key = jax.random.key(3)
    curve = tmp_path / "loss.png"
    full = train([], STREAM, key=key, progress=False, loss_curve=curve)  # no checkpoints: no resume
    assert full.steps == 4 and np.isfinite(full.losses["loss"]).all()
    assert curve.read_bytes()[:4] == b"\x89PNG"
    part = train([], STREAM, key=key, progress=False, checkpoint_dir=tmp_path / "b", stop_after=3)
    np.testing.assert_array_equal(part.losses["loss"], full.losses["loss"][:3])
    shutil.rmtree(tmp_path / "b" / "3")  # killed after step 3, before its end-of-call save
    resumed = train([], STREAM, key=key, progress=False, checkpoint_dir=tmp_path / "b")
    assert resumed.resumed_from == 2 and resumed.steps == 4
    np.testing.assert_array_equal(resumed.losses["loss"], full.losses["loss"])
    for x, y in zip(
        jax.tree.leaves(full.model.params), jax.tree.leaves(resumed.model.params), strict=True
    ):
        np.testing.assert_array_equal(x, y)
    with pytest.raises(InputError, match="no images"):
        train([], STREAM.replace(procedural_fraction=0.5), key=key, progress=False)

"""Planar training data, the training loop (resumable through jmeshtex.io.Checkpoints), and a learning
check that can fail."""

from __future__ import annotations

import shutil

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import CheckpointMismatchError, ConfigError, InputError, TrainResult, metrics
from jmeshtex.fl import Config, Model, train
from jmeshtex.fl._planar import farthest_points
from jmeshtex.fl.core import (
    builtin_images,
    decode_points,
    encode_samples,
    mesh_batch,
    one_ring_samples,
    planar_mesh,
    surface_colors,
)
from tests._presets import FL_SHORT_RUN

TINY = Config(
    features=16,
    num_heads=2,
    num_blocks=1,
    num_samples=24,
    decoder_features=32,
    min_vertices=24,
    max_vertices=36,
    meshes_per_image=3,
    max_image_size=32,
    **FL_SHORT_RUN,
)


def procedural_images(rng: np.random.Generator, n: int = 6, size: int = 32) -> list[np.ndarray]:
    """Stripes, checkers and colour blobs with features a few one-rings wide."""
    y, x = np.mgrid[0:size, 0:size] / size
    out = []
    for i in range(n):
        c0, c1 = rng.random(3), rng.random(3)
        kind = i % 3
        if kind == 0:
            t = np.cos(2 * np.pi * (rng.uniform(1, 2.5) * (np.cos(i) * x + np.sin(i) * y)))
        elif kind == 1:
            t = np.sign(np.sin(2 * np.pi * 1.5 * x) * np.sin(2 * np.pi * 1.5 * y))
        else:
            cx, cy = rng.random(2)
            t = 2 * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / 0.05) - 1
        w = (0.5 + 0.5 * t)[..., None]
        out.append(w * c0 + (1 - w) * c1)
    return out


def test_planar_meshes_are_ccw_delaunay_over_the_image(rng):
    img = rng.random((20, 40, 3))
    m = planar_mesh(img, 50, rng=rng)
    assert m.num_vertices == 50 and m.texture.shape == (20, 40, 3)
    e1 = m.vertices[m.faces[:, 1]] - m.vertices[m.faces[:, 0]]
    e2 = m.vertices[m.faces[:, 2]] - m.vertices[m.faces[:, 0]]
    assert (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] > 0).all()  # counter-clockwise, +z
    np.testing.assert_allclose(
        m.uv[..., 0] * 2.0, m.vertices[m.faces][..., 0], atol=1e-12
    )  # aspect 2
    # the colours read on the mesh are the image's (texel centres map to themselves)
    sc = surface_colors(m)
    assert sc.source == "texture"
    with pytest.raises(InputError):
        planar_mesh(img, 3, rng=rng)


def test_farthest_points_spread_out(rng):
    pts = rng.random((500, 2))
    idx = farthest_points(pts, 20, first=np.array([0]))
    chosen = pts[idx]
    d = np.linalg.norm(chosen[:, None] - chosen[None], axis=-1) + np.eye(20) * 9
    # greedy FPS is a 2-approximation of the best packing: no two points much closer than random
    assert d.min() > 0.05 and len(set(idx.tolist())) == 20


def test_builtin_images_are_rgb_in_unit_range():
    imgs = builtin_images(max_size=32, names=("brick", "astronaut"))
    assert [im.shape for im in imgs] == [(32, 32, 3), (32, 32, 3)]
    assert all(im.min() >= 0 and im.max() <= 1 for im in imgs)


def test_batch_concatenates_meshes_with_global_corner_ids(rng):
    meshes = [planar_mesh(rng.random((8, 8, 3)), 10, rng=rng) for _ in range(2)]
    b = mesh_batch(meshes, TINY, rng, num_vertices=25)
    # the ring's centre (TINY.experimental.token == "centre") and the samples
    assert b["log"].shape == (25, TINY.num_samples + 1) and b["vertex_mask"].sum() == 20
    assert b["corners"][:10].max() < 10 and b["corners"][10:20].min() >= 10
    assert not b["mask"][20:].any()


@pytest.mark.few_steps  # 4 steps: compiled at the suite's quick XLA level (conftest.py)
def test_resumed_training_equals_uninterrupted_training(tmp_path):
    imgs = procedural_images(np.random.default_rng(0), 2)
    key = jax.random.key(5)
    full = train(imgs, TINY, key=key, progress=False, checkpoint_dir=tmp_path / "a")
    assert (
        isinstance(full, TrainResult)
        and isinstance(full.model, Model)
        and full.model.config == TINY
    )
    assert full.steps == 4 and full.resumed_from is None and full.losses["loss"].shape == (4,)
    part = train(imgs, TINY, key=key, progress=False, checkpoint_dir=tmp_path / "b", stop_after=3)
    assert part.steps == 3 and len(part.losses["loss"]) == 3
    np.testing.assert_array_equal(part.losses["loss"], full.losses["loss"][:3])
    # a run killed after step 3 but before its end-of-call save: only the periodic step-2 checkpoint
    shutil.copytree(tmp_path / "b", tmp_path / "c")
    shutil.rmtree(tmp_path / "c" / "3")
    for folder, start in (("b", 3), ("c", 2)):
        resumed = train(imgs, TINY, key=key, progress=False, checkpoint_dir=tmp_path / folder)
        assert resumed.resumed_from == start and resumed.steps == 4
        for name in ("loss", "l1"):
            np.testing.assert_array_equal(resumed.losses[name], full.losses[name])
        for x, y in zip(
            jax.tree.leaves(full.model.params), jax.tree.leaves(resumed.model.params), strict=True
        ):
            np.testing.assert_array_equal(x, y)
    done = train(
        imgs, TINY, key=key, progress=False, checkpoint_dir=tmp_path / "b"
    )  # nothing left to do
    assert done.resumed_from == 4 and done.steps == 4
    # a folder written for another run is not resumed by mistake
    with pytest.raises(CheckpointMismatchError, match="config"):
        train(
            imgs,
            TINY.replace(features=8, num_heads=2),
            key=key,
            progress=False,
            checkpoint_dir=tmp_path / "b",
        )
    with pytest.raises(CheckpointMismatchError, match="key"):
        train(imgs, TINY, key=jax.random.key(6), progress=False, checkpoint_dir=tmp_path / "b")
    with pytest.raises(CheckpointMismatchError, match="images"):
        train(imgs[:1], TINY, key=key, progress=False, checkpoint_dir=tmp_path / "b")
    with pytest.raises(ConfigError, match="must be a jmeshtex.fl.Config"):
        train(imgs, {"steps": 1}, key=key)


def smooth_images(rng: np.random.Generator, n: int, size: int = 32) -> list[np.ndarray]:
    """Random low-frequency colour fields (two plane waves per channel around a random mean)."""
    y, x = np.mgrid[0:size, 0:size] / size
    out = []
    for _ in range(n):
        img = np.zeros((size, size, 3))
        for c in range(3):
            for _ in range(2):
                k = rng.normal(size=2) * 4
                img[..., c] += rng.uniform(0.1, 0.25) * np.cos(
                    k[0] * x + k[1] * y + rng.uniform(0, 2 * np.pi)
                )
        out.append(np.clip(img + rng.uniform(0.3, 0.7, 3), 0, 1))
    return out


def test_short_training_reconstructs_well_above_a_constant_colour():
    """Learning check (can fail): after 150 steps on procedural colour fields, one-ring reconstructions
    from the latent means — on a new triangulation of a training texture and on an unseen texture —
    beat the best constant colour by more than 3 dB and 2 dB (measured: +5.1 and +3.5 dB; a model that
    ignores the latent can at best match the constant)."""
    rng = np.random.default_rng(0)
    cfg = TINY.replace(
        steps=150,
        warmup_steps=10,
        checkpoint_every=1000,
        learning_rate=5e-3,
        min_vertices=50,
        max_vertices=70,
    )
    images = smooth_images(rng, 6)
    result = train(images, cfg, key=jax.random.key(0), progress=False)
    l1 = result.losses["l1"]
    assert l1[-20:].mean() < 0.75 * l1[:5].mean()
    params = result.model.params
    enc = jax.jit(encode_samples, static_argnums=1)
    dec = jax.jit(decode_points, static_argnums=1)
    for image, margin in ((images[0], 3.0), (smooth_images(np.random.default_rng(7), 1)[0], 2.0)):
        mesh = planar_mesh(image, 60, rng=rng)
        s = one_ring_samples(mesh.vertices, mesh.faces, cfg.num_samples, rng=rng)
        rgb = surface_colors(mesh).at_barycentric(s.face, s.bary)
        log = jnp.asarray(s.log, jnp.complex64)
        lat = enc(params, cfg, log, jnp.asarray(rgb, jnp.float32), jnp.asarray(s.mask))
        pred = np.clip(np.asarray(dec(params, cfg, lat.mu, log)), 0, 1)
        model = metrics.psnr(pred, rgb)
        constant = metrics.psnr(np.broadcast_to(rgb.reshape(-1, 3).mean(0), rgb.shape), rgb)
        print(f"learning check: model {model:.2f} dB, constant colour {constant:.2f} dB")
        assert model > constant + margin


@pytest.mark.few_steps  # 4 steps: compiled at the suite's quick XLA level (conftest.py)
def test_the_weight_average_is_the_model_its_recurrence_and_resumes(tmp_path):
    """``ema_decay > 0``: the model is ``optim.ema_update`` applied to the very weights the plain run
    trains (the average never feeds back), and a resumed run continues the average exactly."""
    from jmeshtex.optim import ema_update

    imgs = procedural_images(np.random.default_rng(0), 2)
    key = jax.random.key(5)
    averaged = TINY.replace(ema_decay=0.9)
    weights = train(imgs, TINY, key=key, progress=False).model.params  # after step 4
    part = train(imgs, averaged, key=key, progress=False, checkpoint_dir=tmp_path, stop_after=3)
    full = train(imgs, averaged, key=key, progress=False, checkpoint_dir=tmp_path)
    assert full.resumed_from == 3 and full.model.config.ema_decay == 0.9
    expected = ema_update(part.model.params, weights, 3, decay=0.9)  # d = min(0.9, 4/13)
    gap = [
        float(jnp.max(jnp.abs(a - b)))
        for a, b in zip(*map(jax.tree.leaves, (full.model.params, weights)), strict=True)
    ]
    assert max(gap) > 1e-4  # the average is not the last weights
    for x, y in zip(jax.tree.leaves(expected), jax.tree.leaves(full.model.params), strict=True):
        np.testing.assert_allclose(x, y, rtol=1e-5, atol=1e-6)

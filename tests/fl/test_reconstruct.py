"""Atlas reconstruction: agreement with decode_texture, re-triangulated latent meshes, metrics, renders."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import InputError, Mesh
from jmeshtex.data import grid
from jmeshtex.fl import decode_texture, init, reconstruct
from jmeshtex.fl.core import atlas_metrics, side_by_side
from tests._presets import FL_MICRO

SMALL = FL_MICRO.replace(latent_dim=3, encode_chunk=64)


def _sheet():
    v, f = grid(5)
    yy, xx = np.mgrid[0:16, 0:16] / 16
    tex = np.stack([xx, yy, 0.5 + 0.0 * xx], -1).astype(np.float32)
    return Mesh(v, f, uv=v[f][..., :2], texture=tex)


def test_reconstruction_on_the_mesh_itself_is_decode_texture(key):
    mesh = _sheet()
    model = init(SMALL, key=key)
    r = reconstruct(model, mesh, key=jax.random.key(0), lpips=False)
    tex, valid = decode_texture(model, mesh, r.latents.mu, size=16)
    np.testing.assert_array_equal(valid, r.valid)
    np.testing.assert_allclose(tex, r.texture, atol=1e-6)
    # the target is the original texture at the texel centres (the atlas has the texture's size)
    np.testing.assert_allclose(r.target, mesh.texture, atol=1e-6)
    expected = -10 * np.log10(np.mean((r.texture - r.target)[r.valid] ** 2))
    assert r.metrics["psnr"] == pytest.approx(expected, rel=1e-9)


def test_latents_on_a_retriangulated_copy(key):
    mesh = _sheet()
    v, f = grid(7)  # another triangulation of the same square
    latent = Mesh(v, f)
    model = init(SMALL, key=key)
    r = reconstruct(model, mesh, key=jax.random.key(0), latent_mesh=latent, size=16, lpips=False)
    assert r.latents.mu.shape == (64, 3) and r.latent_mesh is latent
    assert r.valid.all() and np.isfinite(r.texture).all()
    with pytest.raises(InputError, match="textured reference"):
        reconstruct(model, latent, key=jax.random.key(0))


def test_metrics_and_render(tmp_path):
    a = np.random.default_rng(0).random((32, 32, 3))
    valid = np.zeros((32, 32), bool)
    valid[4:28, 4:28] = True
    same = atlas_metrics(a, a, valid, lpips=False)
    assert same["psnr"] == np.inf and same["dssim"] == pytest.approx(0.0, abs=1e-12)
    worse = atlas_metrics(a, np.clip(a + 0.1, 0, 1), valid, lpips=False)
    assert 15 < worse["psnr"] < 25 and worse["dssim"] > 0
    mesh = _sheet()
    model = init(SMALL, key=jax.random.key(0))
    r = reconstruct(model, mesh, key=jax.random.key(0), lpips=False)
    img = side_by_side(mesh, r, tmp_path / "sbs.png", y_up=False, size=(64, 64))
    assert img.shape[1] == 128 and (tmp_path / "sbs.png").exists()
    assert jnp.iscomplexobj(r.latents.mu)

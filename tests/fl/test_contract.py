"""The method contract for `jmeshtex.fl`: Config, Model, train(key=) -> TrainResult, save/load, task verbs
on a Mesh with key=, the same key giving the same result."""

from __future__ import annotations

import dataclasses

import jax
import numpy as np
import pytest

from jmeshtex import ConfigError, Mesh, TrainResult, fl
from jmeshtex.data import grid

TINY = fl.Config(
    latent_dim=2,
    features=8,
    num_heads=2,
    num_blocks=1,
    num_samples=8,
    decoder_features=16,
    min_vertices=10,
    max_vertices=12,
    meshes_per_image=1,
    batch_size=1,
    max_image_size=16,
    steps=2,
    warmup_steps=0,
)


def _images():
    rng = np.random.default_rng(0)
    return [rng.random((16, 16, 3)) for _ in range(2)]


def _sheet() -> Mesh:
    v, f = grid(3)
    yy, xx = np.mgrid[0:8, 0:8] / 8
    return Mesh(
        v, f, uv=v[f][..., :2], texture=np.stack([xx, yy, 0.5 + 0 * xx], -1).astype(np.float32)
    )


def _leaves_equal(a, b) -> bool:
    return all(
        x.dtype == y.dtype and np.array_equal(x, y)
        for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True)
    )


def test_config_uses_the_shared_field_names():
    names = {f.name for f in dataclasses.fields(fl.Config)}
    assert {"steps", "learning_rate", "batch_size"} <= names
    assert not names & {"seed", "lr", "batch_meshes", "iterations", "num_levels"}
    with pytest.raises(ConfigError, match="unknown fields \\['lr'\\]"):
        fl.Config.from_dict({"lr": 0.1})


def test_train_save_load_and_the_task_verbs_round_trip(tmp_path):
    result = fl.train(TINY, key=jax.random.key(0), images=_images(), progress=False)
    assert isinstance(result, TrainResult) and isinstance(result.model, fl.Model)
    assert result.steps == 2 and result.resumed_from is None and np.isfinite(result.final_loss())
    model = result.model
    assert model.config == TINY

    path = fl.save(model, tmp_path / "model.npz")
    loaded = fl.load(path)
    assert isinstance(loaded, fl.Model) and loaded.config == model.config
    assert _leaves_equal(model.params, loaded.params)

    mesh = _sheet()
    key = jax.random.key(7)
    lat = fl.encode(model, mesh, key=key)
    lat_loaded = fl.encode(loaded, mesh, key=key)
    np.testing.assert_array_equal(lat.mu, lat_loaded.mu)
    np.testing.assert_array_equal(lat.log_sigma, lat_loaded.log_sigma)
    tex, valid = fl.decode_texture(model, mesh, lat, size=8)
    tex_loaded, valid_loaded = fl.decode_texture(loaded, mesh, lat_loaded, size=8)
    np.testing.assert_array_equal(tex, tex_loaded)
    np.testing.assert_array_equal(valid, valid_loaded)
    np.testing.assert_array_equal(
        fl.decode_vertex_colors(model, mesh, lat), fl.decode_vertex_colors(loaded, mesh, lat_loaded)
    )
    r = fl.reconstruct(model, mesh, key=key, lpips=False)
    r_loaded = fl.reconstruct(loaded, mesh, key=key, lpips=False)
    np.testing.assert_array_equal(r.texture, r_loaded.texture)
    assert r.metrics == r_loaded.metrics
    np.testing.assert_array_equal(r.latents.mu, lat.mu)  # reconstruct encodes with the same key

    # a (V, F) pair is accepted where a mesh is expected
    coloured = Mesh(mesh.vertices, mesh.faces, vertex_colors=np.full((mesh.num_vertices, 3), 0.5))
    np.testing.assert_array_equal(
        fl.decode_vertex_colors(model, (mesh.vertices, mesh.faces), lat),
        fl.decode_vertex_colors(model, coloured, lat),
    )


def test_the_same_key_gives_the_same_result_and_another_key_another():
    images = _images()
    a = fl.train(TINY, key=jax.random.key(1), images=images, progress=False)
    b = fl.train(TINY, key=jax.random.key(1), images=images, progress=False)
    c = fl.train(TINY, key=jax.random.key(2), images=images, progress=False)
    assert _leaves_equal(a.model.params, b.model.params)
    np.testing.assert_array_equal(a.losses["loss"], b.losses["loss"])
    assert not _leaves_equal(a.model.params, c.model.params)

    mesh = _sheet()
    x = fl.encode(a.model, mesh, key=jax.random.key(3))
    y = fl.encode(a.model, mesh, key=jax.random.key(3))
    z = fl.encode(a.model, mesh, key=jax.random.key(4))
    np.testing.assert_array_equal(x.mu, y.mu)
    assert not np.array_equal(x.mu, z.mu)  # other one-ring samples


def test_model_is_a_pytree_with_a_static_config():
    model = fl.init(TINY, key=jax.random.key(0))
    assert _leaves_equal(jax.tree.leaves(model), jax.tree.leaves(model.params))
    doubled = jax.tree.map(lambda x: 2 * x, model)
    assert isinstance(doubled, fl.Model) and doubled.config is model.config

    @jax.jit
    def vertex_colours(m, mu):
        return fl.decode_vertex_colors_from_latents(m.params, m.config, mu)

    mu = np.ones((3, TINY.latent_dim), np.complex64)
    np.testing.assert_allclose(
        vertex_colours(model, mu),
        fl.decode_vertex_colors_from_latents(model.params, model.config, mu),
        atol=1e-6,
    )
    with pytest.raises(ConfigError, match="Model.config must be"):
        fl.Model(model.params, TINY.to_dict())

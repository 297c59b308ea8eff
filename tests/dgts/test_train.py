"""WGAN-GP training: frozen earlier levels, warm starts, checkpoints that resume exactly."""

from __future__ import annotations

import json

import jax
import numpy as np
import pytest

from jmeshtex import ConfigError, MeshIOError
from jmeshtex.dgts import load_model, train
from tests.dgts.conftest import TINY


def _leaves(tree):
    return [np.asarray(x) for x in jax.tree.leaves(tree)]


def test_levels_train_and_earlier_generators_stay_frozen(tiny_meshes, tiny_model):
    level0_only, reports = train(tiny_meshes, TINY, num_levels=1, progress=False)
    assert [r.level for r in reports] == [0]
    # level 1 training must not touch generator 0 (stop_gradient + separate optimiser)
    for a, b in zip(_leaves(level0_only.generators[0]), _leaves(tiny_model.generators[0]), strict=True):
        np.testing.assert_array_equal(a, b)
    # equal widths: level 1 starts from level 0's weights and moves away from them
    assert TINY.level_features(1, generator=True) == TINY.level_features(0, generator=True)
    moved = [np.abs(a - b).max() for a, b in zip(_leaves(tiny_model.generators[1]), _leaves(tiny_model.generators[0]), strict=True)]
    assert 0 < max(moved) < 0.1  # two small Adam steps away from the warm start
    assert all(np.isfinite(x).all() for x in _leaves(tiny_model.generators))


def test_resume_after_the_last_complete_level_is_exact(tmp_path, tiny_meshes, tiny_model):
    out = tmp_path / "run"
    _, first = train(tiny_meshes, TINY, out_dir=out, num_levels=1, progress=False)
    state = json.loads((out / "state.json").read_text())
    assert state["completed_levels"] == 1 and (out / "level_00.npz").exists()
    resumed, second = train(tiny_meshes, TINY, out_dir=out, progress=False)
    assert [r.level for r in first] == [0] and [r.level for r in second] == [1]
    for a, b in zip(_leaves(resumed.generators), _leaves(tiny_model.generators), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7)
    loaded = load_model(out)
    assert loaded.num_levels == 2 and loaded.config == TINY
    np.testing.assert_array_equal(loaded.z_star, tiny_model.z_star)
    assert json.loads((out / "state.json").read_text())["completed_levels"] == 2
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # atomic writes left no temporaries


def test_resume_with_another_config_is_refused(tmp_path, tiny_meshes):
    out = tmp_path / "run"
    train(tiny_meshes, TINY, out_dir=out, num_levels=1, progress=False)
    with pytest.raises(ConfigError, match="different config"):
        train(tiny_meshes, TINY.replace(lr=1e-3), out_dir=out, progress=False)


def test_errors(tmp_path, tiny_meshes):
    with pytest.raises(MeshIOError, match="state.json"):
        load_model(tmp_path)
    with pytest.raises(ConfigError, match="num_levels"):
        train(tiny_meshes, TINY, num_levels=3, progress=False)


def test_padded_levels_share_one_compiled_step(tiny_model):
    """TINY pads level 0 to level 1's size (shared_levels=2): both levels run one compiled step."""
    from jmeshtex.dgts import _train

    steps = [k for k in _train._COMPILED if k[0] is _train.train_chunk and dict(k[1])["config"] == TINY]
    assert len(steps) == 1
    assert tiny_model.num_levels == 2


def test_pad_level_changes_no_loss_and_no_update(tiny_meshes):
    """The padding contract in float64: masked faces and vertices change no loss and no parameter."""
    import jax.numpy as jnp

    from jmeshtex.dgts import hierarchy_geometry, init_level
    from jmeshtex.dgts._train import _Opt, _optimizer, level_batch, pad_level, train_chunk

    cfg = TINY.replace(shared_levels=0)
    geos, _ = hierarchy_geometry(tiny_meshes.faces[0], len(tiny_meshes.template), 1)
    g = init_level(jax.random.key(0), cfg, 0, generator=True, dtype=jnp.float64)
    d = init_level(jax.random.key(1), cfg, 0, generator=False, dtype=jnp.float64)
    opt = _Opt(_optimizer(cfg, cfg.generator_steps).init(g), _optimizer(cfg, cfg.discriminator_steps).init(d))
    template = jnp.asarray(tiny_meshes.template)
    real = jnp.asarray(tiny_meshes.vertices[0])
    batch = level_batch((), geos, template, 0.1 * template, jax.random.key(2), config=cfg, chunk=1)
    nb = geos[0].nbhd
    size = {"F": nb.faces.shape[0] + 7, "V": real.shape[0] + 5, "M": nb.vertex_faces.shape[1] + 2}
    plain = train_chunk(g, d, opt, nb, real, batch, jnp.int32(1), config=cfg)
    padded = train_chunk(g, d, opt, *pad_level(nb, real, batch, size), jnp.int32(1), config=cfg)
    for k in plain[3]:
        assert float(padded[3][k]) == pytest.approx(float(plain[3][k]), rel=1e-10, abs=1e-12), k
    for a, b in zip(_leaves(plain[:2]), _leaves(padded[:2]), strict=True):
        # Adam divides by |g| + 1e-8: gradient entries near 1e-8 turn float64 rounding (other summation
        # order) into parameter differences of a few 1e-9 (lr 5e-4); the losses above agree to 1e-10
        np.testing.assert_allclose(a, b, rtol=0, atol=5e-8)

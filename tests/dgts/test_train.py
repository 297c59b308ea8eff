"""WGAN-GP training: frozen earlier levels, warm starts, checkpoints that resume exactly."""

from __future__ import annotations

import shutil

import jax
import numpy as np
import pytest

from jmeshtex import CheckpointMismatchError, ConfigError, MeshIOError, TrainResult
from jmeshtex.dgts import LevelReport, Model, load, save, train
from jmeshtex.dgts.core import LOSS_NAMES
from jmeshtex.io import Checkpoints
from tests.dgts.conftest import TINY, TINY_KEY


def _leaves(tree):
    return [np.asarray(x) for x in jax.tree.leaves(tree)]


def _assert_same_model(a: Model, b: Model):
    assert a.num_levels == b.num_levels and a.config == b.config
    for x, y in zip(_leaves(a), _leaves(b), strict=True):
        np.testing.assert_array_equal(x, y)


def _assert_resumes_after_level_0(meshes, cfg, key, folder, whole: Model):
    """Training level 0 into ``folder``, then all levels from it, gives ``whole``."""
    train(meshes, cfg, key=key, checkpoint_dir=folder, levels=1, progress=False)
    resumed = train(meshes, cfg, key=key, checkpoint_dir=folder, progress=False)
    assert resumed.resumed_from == cfg.steps
    _assert_same_model(resumed.model, whole)


def test_train_returns_a_train_result_with_per_step_losses(tiny_result):
    r = tiny_result
    assert isinstance(r, TrainResult) and isinstance(r.model, Model)
    assert r.steps == 2 * TINY.steps and r.resumed_from is None and r.seconds > 0
    assert set(r.losses) == set(LOSS_NAMES)
    for name, values in r.losses.items():
        assert values.shape == (2 * TINY.steps,) and np.isfinite(values).all(), name
    reports = r.extra["levels"]
    assert [type(x) for x in reports] == [LevelReport, LevelReport]
    assert [x.level for x in reports] == [0, 1] and [x.faces for x in reports] == [20, 80]
    # each level's report ends with the last of its steps in the history
    for x in reports:
        end = (x.level + 1) * TINY.steps - 1
        assert x.losses == {k: float(v[end]) for k, v in r.losses.items()}
    assert r.final_loss("g_rec") == r.losses["g_rec"][-1]


def test_levels_train_and_earlier_generators_stay_frozen(tiny_meshes, tiny_model):
    level0_only = train(tiny_meshes, TINY, key=jax.random.key(TINY_KEY), levels=1, progress=False)
    assert [r.level for r in level0_only.extra["levels"]] == [0]
    # level 1 training must not touch generator 0 (stop_gradient + separate optimiser)
    for a, b in zip(
        _leaves(level0_only.model.generators[0]), _leaves(tiny_model.generators[0]), strict=True
    ):
        np.testing.assert_array_equal(a, b)
    # equal widths: level 1 starts from level 0's weights and moves away from them
    assert TINY.level_features(1, generator=True) == TINY.level_features(0, generator=True)
    moved = [
        np.abs(a - b).max()
        for a, b in zip(
            _leaves(tiny_model.generators[1]), _leaves(tiny_model.generators[0]), strict=True
        )
    ]
    assert 0 < max(moved) < 0.1  # two small Adam steps away from the warm start
    assert all(np.isfinite(x).all() for x in _leaves(tiny_model.generators))


def _train_tiny(meshes, checkpoint_dir, **kwargs):
    """``train`` with the tiny fixtures' configuration and key, checkpointing to ``checkpoint_dir``."""
    return train(
        meshes,
        TINY,
        key=jax.random.key(TINY_KEY),
        checkpoint_dir=checkpoint_dir,
        progress=False,
        **kwargs,
    )


def test_resume_after_the_last_complete_level_is_exact(tmp_path, tiny_meshes, tiny_result):
    out = tmp_path / "run"
    first = _train_tiny(tiny_meshes, out, levels=1)
    assert Checkpoints(out).steps() == [TINY.steps]  # one level done
    resumed = _train_tiny(tiny_meshes, out)
    assert first.resumed_from is None and resumed.resumed_from == TINY.steps
    assert [r.level for r in first.extra["levels"]] == [0] and [
        r.level for r in resumed.extra["levels"]
    ] == [0, 1]
    _assert_same_model(resumed.model, tiny_result.model)
    np.testing.assert_array_equal(resumed.model.z_star, tiny_result.model.z_star)
    for name in LOSS_NAMES:
        np.testing.assert_array_equal(resumed.losses[name], tiny_result.losses[name])
    assert resumed.steps == tiny_result.steps
    assert Checkpoints(out).steps() == [TINY.steps, 2 * TINY.steps]
    assert not [p for p in out.rglob("*") if "tmp" in p.name]  # atomic writes left no temporaries


def test_resume_within_a_level_is_exact(tmp_path, tiny_meshes):
    """Checkpoints every chunk: an interrupted level resumes from its last chunk, bit for bit."""
    from jmeshtex.dgts._train import CHUNK

    cfg = TINY.replace(steps=3 * CHUNK, checkpoint_every=CHUNK)
    key = jax.random.key(7)
    whole = train(
        tiny_meshes, cfg, key=key, progress=False
    )  # checkpoint_every: no folder, no effect
    out = tmp_path / "run"
    train(tiny_meshes, cfg, key=key, checkpoint_dir=out, levels=1, progress=False)
    # keep only the mid-level checkpoint of level 0 (step 2·CHUNK), as if the run had stopped there
    assert Checkpoints(out).steps() == [2 * CHUNK, 3 * CHUNK]
    shutil.rmtree(out / str(3 * CHUNK))
    resumed = train(tiny_meshes, cfg, key=key, checkpoint_dir=out, progress=False)
    assert resumed.resumed_from == 2 * CHUNK
    _assert_same_model(resumed.model, whole.model)
    for name in LOSS_NAMES:
        np.testing.assert_array_equal(resumed.losses[name], whole.losses[name])
    # time-boxed calls (stop_after) that stop within a level and at a level's end continue exactly
    boxed = tmp_path / "boxed"
    part = train(tiny_meshes, cfg, key=key, checkpoint_dir=boxed, stop_after=CHUNK, progress=False)
    assert part.steps == CHUNK and part.model.num_levels == 0
    assert Checkpoints(boxed).steps() == [CHUNK]  # saved where it stopped
    part = train(
        tiny_meshes, cfg, key=key, checkpoint_dir=boxed, stop_after=2 * CHUNK, progress=False
    )
    assert part.resumed_from == CHUNK and part.steps == 3 * CHUNK and part.model.num_levels == 1
    rest = train(tiny_meshes, cfg, key=key, checkpoint_dir=boxed, progress=False)
    assert rest.resumed_from == 3 * CHUNK and rest.steps == whole.steps
    _assert_same_model(rest.model, whole.model)
    for name in LOSS_NAMES:
        np.testing.assert_array_equal(rest.losses[name], whole.losses[name])


def test_resume_with_another_config_or_key_is_refused(tmp_path, tiny_meshes):
    out = tmp_path / "run"
    _train_tiny(tiny_meshes, out, levels=1)
    with pytest.raises(CheckpointMismatchError, match="config"):
        train(
            tiny_meshes,
            TINY.replace(learning_rate=1e-3),
            key=jax.random.key(TINY_KEY),
            checkpoint_dir=out,
            progress=False,
        )
    with pytest.raises(CheckpointMismatchError, match="key"):
        train(
            tiny_meshes, TINY, key=jax.random.key(TINY_KEY + 1), checkpoint_dir=out, progress=False
        )


def test_save_load_round_trip(tmp_path, tiny_model):
    folder = save(tiny_model, tmp_path / "model")
    back = load(folder)
    _assert_same_model(back, tiny_model)
    np.testing.assert_array_equal(back.z_star, tiny_model.z_star)
    save(tiny_model, folder)  # saving again replaces the model
    _assert_same_model(load(folder), tiny_model)


def test_a_model_file_stores_every_config_field_and_an_older_one_is_refused(tmp_path, tiny_model):
    """Format 2 stores every config field; a version-1 file, or one lacking fields, is refused
    with the fields named (never filled with defaults; studies/convert_to_format_2.py converts)."""
    from jmeshtex import CorruptModelError
    from jmeshtex.dgts._model import FORMAT_VERSION, MODEL_KIND
    from jmeshtex.io import read_arrays, save_model
    from jmeshtex.io._model_file import HEADER

    arrays = read_arrays(save(tiny_model, tmp_path / "model") / "model.npz")
    arrays.pop(HEADER)
    config = tiny_model.config.to_dict()
    save_model(tmp_path / "v1.npz", kind=MODEL_KIND, params=arrays, config=config,
               format_version=1)  # fmt: skip
    with pytest.raises(CorruptModelError, match="format version 1; this jmeshtex reads 2"):
        load(tmp_path / "v1.npz")
    lacking = {k: v for k, v in config.items() if k not in ("checkpoint_every", "fake_inputs")}
    save_model(tmp_path / "v2.npz", kind=MODEL_KIND, params=arrays, config=lacking,
               format_version=FORMAT_VERSION)  # fmt: skip
    with pytest.raises(
        CorruptModelError, match=r"lacks fields \['checkpoint_every', 'fake_inputs'\]"
    ):
        load(tmp_path / "v2.npz")
    save_model(tmp_path / "v2_whole.npz", kind=MODEL_KIND, params=arrays, config=config,
               format_version=FORMAT_VERSION)  # fmt: skip
    _assert_same_model(load(tmp_path / "v2_whole.npz"), tiny_model)


def test_errors(tmp_path, tiny_meshes):
    with pytest.raises(MeshIOError, match="holds no DGTS model"):
        load(tmp_path)
    train(
        tiny_meshes,
        TINY,
        key=jax.random.key(TINY_KEY),
        checkpoint_dir=tmp_path / "ckpt",
        levels=1,
        progress=False,
    )
    with pytest.raises(MeshIOError, match="not a DGTS model"):
        load(tmp_path / "ckpt")  # a training checkpoint folder is not a model folder
    with pytest.raises(ConfigError, match="levels"):
        train(tiny_meshes, TINY, key=jax.random.key(0), levels=3, progress=False)
    with pytest.raises(ConfigError, match="checkpoint_every"):
        TINY.replace(checkpoint_every=0)
    with pytest.raises(ConfigError, match="stop_after"):
        train(tiny_meshes, TINY, key=jax.random.key(0), stop_after=-1, progress=False)
    with pytest.raises(TypeError, match="config"):
        train(tiny_meshes, key=jax.random.key(0), progress=False)  # no default config


def test_padded_levels_share_one_compiled_step(tiny_result, tiny_meshes):
    """TINY pads level 0 to level 1's size (shared_levels=2): both levels run one compiled step."""
    assert tiny_result.model.num_levels == 2 and tiny_result.extra["compiled_steps"] == 1
    unpadded = train(
        tiny_meshes, TINY.replace(shared_levels=0), key=jax.random.key(TINY_KEY), progress=False
    )
    assert unpadded.extra["compiled_steps"] == 2


def test_pad_level_changes_no_loss_and_no_update(tiny_meshes):
    """The padding contract in float64: masked faces and vertices change no loss and no parameter."""
    import jax.numpy as jnp

    from jmeshtex.dgts._train import _Opt, _optimizer, level_batch, pad_level, train_chunk
    from jmeshtex.dgts.core import hierarchy_geometry, init_level

    cfg = TINY.replace(shared_levels=0)
    geos, _ = hierarchy_geometry(tiny_meshes.faces[0], len(tiny_meshes.template), 1)
    g = init_level(cfg, 0, generator=True, key=jax.random.key(0), dtype=jnp.float64)
    d = init_level(cfg, 0, generator=False, key=jax.random.key(1), dtype=jnp.float64)
    opt = _Opt(
        _optimizer(cfg, cfg.generator_steps).init(g),
        _optimizer(cfg, cfg.discriminator_steps).init(d),
    )
    template = jnp.asarray(tiny_meshes.template)[None]
    real = jnp.asarray(tiny_meshes.vertices[0])[None]
    batch = level_batch(
        (), geos, template, 0.1 * template, real, jax.random.key(2), config=cfg, chunk=1
    )
    nb = geos[0].nbhd
    size = {"F": nb.faces.shape[0] + 7, "V": real.shape[1] + 5, "M": nb.vertex_faces.shape[1] + 2}
    plain = train_chunk(g, d, opt, nb, batch, jnp.int32(1), config=cfg)
    padded = train_chunk(g, d, opt, *pad_level(nb, batch, size), jnp.int32(1), config=cfg)
    assert set(plain[3]) == set(LOSS_NAMES)
    for k in plain[3]:
        np.testing.assert_allclose(
            np.asarray(padded[3][k]), np.asarray(plain[3][k]), rtol=1e-10, atol=1e-12, err_msg=k
        )
    for a, b in zip(_leaves(plain[:2]), _leaves(padded[:2]), strict=True):
        # Adam divides by |g| + 1e-8: gradient entries near 1e-8 turn float64 rounding (other summation
        # order) into parameter differences of a few 1e-9 (lr 5e-4); the losses above agree to 1e-10
        np.testing.assert_allclose(a, b, rtol=0, atol=5e-8)


def test_divergence_raises_naming_the_step_and_saves_no_nan_model(tiny_meshes, tmp_path):
    """Finite or nothing: an absurd learning rate makes the losses NaN within a step or two."""
    from jmeshtex import TrainingDivergedError

    with jax.debug_nans(False), pytest.raises(TrainingDivergedError, match="at step") as err:
        train(
            tiny_meshes,
            TINY.replace(learning_rate=1e30),
            key=jax.random.key(TINY_KEY),
            checkpoint_dir=tmp_path / "ckpt",
            progress=False,
        )
    assert 0 <= err.value.step < 2 * TINY.steps
    assert Checkpoints(tmp_path / "ckpt").steps() == []  # nothing was saved


@pytest.mark.parametrize("fake_inputs", ["sampled", "reconstructed"])
def test_fake_inputs_choose_what_the_frozen_levels_make_the_fakes_from(
    tiny_meshes, tiny_model, fake_inputs
):
    """``"reconstructed"``: every fake of level 1 starts from the reconstruction's level-0 output
    (``z*``), only level 1's own noise is fresh; ``"sampled"`` (the reference's): the fakes' coarse
    shapes differ from draw to draw."""
    import jax.numpy as jnp

    from jmeshtex.dgts._train import level_batch
    from jmeshtex.dgts.core import hierarchy_geometry

    cfg = TINY.replace(shared_levels=0, fake_inputs=fake_inputs)
    geos, _ = hierarchy_geometry(tiny_meshes.faces[0], len(tiny_meshes.template), 2)
    template = jnp.asarray(tiny_meshes.template)[None]
    z_star = jnp.asarray(tiny_model.z_star)[None]
    real = jnp.asarray(tiny_meshes.vertices[1])[None]
    batch = level_batch(
        tiny_model.generators[:1],
        geos,
        template,
        z_star,
        real,
        jax.random.key(2),
        config=cfg,
        chunk=2,
    )
    fakes = np.asarray(batch.fake_base).reshape(-1, *batch.fake_base.shape[-2:])
    rec = np.asarray(batch.rec_base)[0, 0]
    spread = np.abs(fakes - rec).max(axis=(1, 2))
    if fake_inputs == "reconstructed":
        np.testing.assert_allclose(spread, 0, atol=1e-6)
    else:
        assert spread.min() > 1e-3
    noise = np.asarray(batch.fake_noise).reshape(len(fakes), -1)
    assert np.abs(noise[0] - noise[1]).max() > 1e-3  # level 1's own noise stays fresh
    with pytest.raises(ConfigError, match="fake_inputs"):
        TINY.replace(fake_inputs="ground truth")


def test_several_references_draw_one_per_step_with_its_own_real_mesh_and_reconstruction(
    tiny_meshes, tiny_remeshed
):
    """Each step of a level batch uses one reference throughout: its real mesh, and (from
    ``reconstruction_start`` on) its own reconstruction from its own ``z*``; both are drawn."""
    import jax.numpy as jnp

    from jmeshtex.dgts._train import level_batch
    from jmeshtex.dgts.core import hierarchy_geometry, init_level

    refs = (tiny_meshes, tiny_remeshed)
    cfg = TINY.replace(shared_levels=0)
    geos, _ = hierarchy_geometry(tiny_meshes.faces[0], len(tiny_meshes.template), 2)
    templates = jnp.asarray(np.stack([m.template for m in refs]), jnp.float32)
    z_stars = 0.1 * jax.random.normal(jax.random.key(5), templates.shape)
    reals = jnp.asarray(np.stack([m.vertices[1] for m in refs]), jnp.float32)
    g0 = init_level(cfg, 0, generator=True, key=jax.random.key(0))
    chunk = 16
    batch = level_batch(
        (g0,), geos, templates, z_stars, reals, jax.random.key(2), config=cfg, chunk=chunk
    )
    real = np.asarray(batch.real)
    which = [
        int(np.argmin(np.abs(real[i] - np.asarray(reals)).max(axis=(1, 2)))) for i in range(chunk)
    ]
    assert set(which) == {0, 1}  # both drawn in 16 steps
    for i in range(chunk):
        np.testing.assert_array_equal(real[i], np.asarray(reals)[which[i]])
    rec = np.asarray(batch.rec_base)[:, 0]
    for i in range(chunk):  # the same reconstruction for the same reference, another for the other
        for j in range(chunk):
            same = np.allclose(rec[i], rec[j], atol=1e-6)
            assert same == (which[i] == which[j]), (i, j)
    single = level_batch(
        (g0,), geos, templates[:1], z_stars[:1], reals[:1], jax.random.key(2), config=cfg,
        chunk=chunk,
    )  # fmt: skip
    for i in np.flatnonzero(np.asarray(which) == 0):  # reference 0's reconstruction as if alone
        np.testing.assert_allclose(rec[i], np.asarray(single.rec_base)[0, 0], atol=1e-6)


def test_training_on_several_references(tmp_path, tiny_meshes, tiny_remeshed, tiny_result):
    """One reference in a list trains the same model as alone; two train, resume exactly and are
    tied to their checkpoint folder; references of other faces are refused."""
    from jmeshtex import InputError
    from jmeshtex.data import icosphere
    from jmeshtex.dgts import PrepareConfig, training_meshes

    key = jax.random.key(TINY_KEY)
    alone = train([tiny_meshes], TINY, key=key, progress=False)
    _assert_same_model(alone.model, tiny_result.model)
    refs = [tiny_meshes, tiny_remeshed]
    whole = train(refs, TINY, key=key, progress=False)
    np.testing.assert_array_equal(whole.model.z_star, tiny_result.model.z_star)  # the first's
    assert all(np.isfinite(v).all() for v in whole.losses.values())
    assert not np.array_equal(whole.losses["g_rec"], tiny_result.losses["g_rec"])
    out = tmp_path / "run"
    _assert_resumes_after_level_0(refs, TINY, key, out, whole.model)
    with pytest.raises(CheckpointMismatchError, match="meshes"):
        train(refs[::-1], TINY, key=key, checkpoint_dir=out, progress=False)
    other = training_meshes(
        icosphere(2), icosphere(1), config=PrepareConfig(levels=2, steps=0), key=key,
        progress=False,
    )  # fmt: skip
    with pytest.raises(InputError, match="do not share the levels and faces"):
        train([tiny_meshes, other], TINY, key=key, progress=False)
    with pytest.raises(InputError, match="non-empty sequence"):
        train([], TINY, key=key, progress=False)


def test_fixed_noise_levels_reconstruct_every_fixed_level_from_noise_kept_in_the_model(
    tmp_path, tiny_meshes, tiny_result
):
    """``fixed_noise_levels=2``: level 1's reconstruction runs on a fixed draw of its own (not
    zero), kept in the model, saved, restored on resume and used by ``reconstruct``; the default
    (1, the reference's) is untouched."""
    from jmeshtex.dgts import reconstruct

    assert tiny_result.model.z_star_finer == ()
    cfg = TINY.replace(fixed_noise_levels=2)
    key = jax.random.key(TINY_KEY)
    whole = train(tiny_meshes, cfg, key=key, progress=False)
    (z1,) = whole.model.z_star_finer
    assert z1.shape == tiny_meshes.vertices[1].shape and 0.05 < z1.std() < 0.2
    np.testing.assert_array_equal(whole.model.z_star, tiny_result.model.z_star)
    S = TINY.steps  # level 0 trains as before; level 1 reconstructs from z1, not from zero
    np.testing.assert_array_equal(whole.losses["g_rec"][:S], tiny_result.losses["g_rec"][:S])
    assert not np.array_equal(whole.losses["g_rec"][S:], tiny_result.losses["g_rec"][S:])
    noise = whole.model.reconstruction_noise([len(v) for v in tiny_meshes.vertices])
    np.testing.assert_array_equal(noise[1], z1)
    # the level-1 reconstruction the generator was trained on is the one reconstruct() gives
    rec = reconstruct(whole.model, (tiny_meshes.template, tiny_meshes.faces[0]))
    zero = whole.model.replace(z_star_finer=(np.zeros_like(z1),), config=TINY)
    rec0 = reconstruct(zero, (tiny_meshes.template, tiny_meshes.faces[0]))
    assert np.abs(rec.level_vertices[1] - rec0.level_vertices[1]).max() > 1e-4
    np.testing.assert_array_equal(rec.level_vertices[0], rec0.level_vertices[0])
    # saved and loaded; resumed from the level-0 checkpoint to the same model
    back = load(save(whole.model, tmp_path / "model"))
    _assert_same_model(back, whole.model)
    _assert_resumes_after_level_0(tiny_meshes, cfg, key, tmp_path / "run", whole.model)
    with pytest.raises(ConfigError, match="fixed_noise_levels"):
        TINY.replace(fixed_noise_levels=0)
    from jmeshtex import InputError

    with pytest.raises(InputError, match="fixed noise"):
        whole.model.replace(z_star_finer=()).reconstruction_noise([12, 42])


def test_a_one_device_mesh_trains_as_the_default_and_a_larger_one_is_refused(
    tiny_meshes, tiny_result
):
    from jax.sharding import Mesh

    one = Mesh(np.array(jax.devices()[:1]), ("data",))
    result = train(tiny_meshes, TINY, key=jax.random.key(TINY_KEY), progress=False, device_mesh=one)
    _assert_same_model(result.model, tiny_result.model)
    with pytest.raises(ConfigError, match="device_mesh must be a jax.sharding.Mesh"):
        train(tiny_meshes, TINY, key=jax.random.key(TINY_KEY), progress=False, device_mesh="cpu")
    two = Mesh(np.array(jax.devices()[:1] * 2), ("data",))
    with pytest.raises(ConfigError, match="2 devices has no batch to split"):
        train(tiny_meshes, TINY, key=jax.random.key(TINY_KEY), progress=False, device_mesh=two)

"""Gram-matching synthesis: a check that can fail (loss drops ≥ 10×, colours move to the exemplar)."""

import jax
import numpy as np
import pytest
import skimage.data
import skimage.transform

from jmeshtex import CheckpointMismatchError, ConfigError, InputError, Mesh
from jmeshtex.data import icosphere
from jmeshtex.surfacecnn import Config, prepare_surface, stylize, synthesize, unwrap_uv

LAYERS = ("relu1_1", "relu1_2", "pool1", "relu2_1")


def _histogram(colors, bins=8):
    h = np.stack([np.histogram(colors[:, c], bins=bins, range=(0, 1))[0] for c in range(3)]).astype(
        float
    )
    return h / h.sum(axis=1, keepdims=True)


@pytest.fixture(scope="module")
def exemplar():
    return skimage.transform.resize(
        skimage.data.chelsea()[100:260, 150:310], (48, 48), anti_aliasing=True
    )


@pytest.fixture(scope="module")
def sphere():
    v, f = icosphere(2)
    return Mesh(v, f, uv=unwrap_uv(v, f))


def test_gram_loss_drops_and_colours_move_to_the_exemplar(sphere, exemplar, key):
    config = Config(size=32, steps=60)
    result = synthesize(sphere, exemplar, config, key=key, layers=LAYERS, progress=False)
    assert result.losses.shape == (60,) and np.all(np.isfinite(result.losses))
    assert result.losses[0] / result.final_loss >= 10.0, (result.losses[0], result.final_loss)
    init = np.asarray(jax.random.uniform(key, result.colors.shape, minval=0.0, maxval=0.2))
    target = _histogram(exemplar.reshape(-1, 3))
    before = np.abs(_histogram(init) - target).sum()
    after = np.abs(_histogram(result.colors) - target).sum()
    assert after < 0.5 * before, (before, after)
    np.testing.assert_allclose(result.colors.mean(0), exemplar.reshape(-1, 3).mean(0), atol=0.1)
    assert result.colors.min() >= 0 and result.colors.max() <= 1
    assert result.texture.shape == (32, 32, 3) and result.texture.dtype == np.float32
    assert result.mesh.texture is result.texture or np.array_equal(
        result.mesh.texture, result.texture
    )
    np.testing.assert_array_equal(result.mesh.uv, sphere.uv)


def test_learning_rate_schedule_and_config_errors():
    c = Config()
    assert [c.learning_rate_at(s) for s in (0, 199, 200, 399, 400, 499)] == [
        0.1,
        0.1,
        0.05,
        0.05,
        0.025,
        0.025,
    ]
    assert (c.steps, c.init_low, c.init_high, c.pool) == (500, 0.0, 0.2, "mean")
    for bad in (
        {"size": 2},
        {"steps": -1},
        {"learning_rate": 0.0},
        {"pool": "sum"},
        {"boundary": "wrap"},
        {"init_low": 0.5, "init_high": 0.1},
        {"layers": ()},
        {"dtype": "float16"},
        {"frame_smoothing": -1.0},
        {"frame_smoothing": float("nan")},
    ):
        with pytest.raises(ConfigError):
            Config(**bad)


def test_stylize_keeps_content_and_bad_inputs(sphere, exemplar):
    config = Config(
        size=32, steps=8, learning_rate=0.02, content_layer="relu1_2", content_weight=10.0
    )
    surface = prepare_surface(sphere, size=32, levels=0)
    content = np.zeros((32, 32, 3))
    content[:, :16] = [0.9, 0.1, 0.1]
    content[:, 16:] = [0.1, 0.1, 0.9]
    result = stylize(
        sphere, content, exemplar, config, layers=("relu1_1",), surface=surface, progress=False
    )
    # the content term keeps the left/right colour split
    col = surface.atlas.rows_cols()[1]
    left, right = result.colors[col < 14].mean(0), result.colors[col >= 18].mean(0)
    assert left[0] > right[0] and right[2] > left[2]
    assert result.final_loss < result.losses[0]
    with pytest.raises(InputError, match="no UVs"):
        stylize((sphere.vertices, sphere.faces), content, exemplar, config, progress=False)
    with pytest.raises(InputError, match="exemplar"):
        synthesize(sphere, np.zeros((4, 4, 5)), config, key=jax.random.key(0), progress=False)
    with pytest.raises(InputError, match="surface was prepared"):
        synthesize(
            sphere,
            exemplar,
            Config(size=64),
            key=jax.random.key(0),
            surface=surface,
            layers=("relu1_1",),
            progress=False,
        )


def test_checkpoint_resume_reproduces_an_uninterrupted_run(tmp_path, monkeypatch):
    from jmeshtex.data import grid
    from jmeshtex.io import Checkpoints

    v, f = grid(2)
    mesh = Mesh(v, f, uv=v[f][..., :2])
    ex = np.random.default_rng(0).uniform(size=(16, 16, 3))
    kw = dict(key=jax.random.key(3), layers=("relu1_1",), progress=False)
    full = synthesize(mesh, ex, Config(size=16, steps=10), **kw)
    # a shorter run, then a longer one continuing from its last checkpoint
    ckpt = tmp_path / "ckpt"
    synthesize(mesh, ex, Config(size=16, steps=6), checkpoint_dir=ckpt, **kw)
    resumed = synthesize(
        mesh, ex, Config(size=16, steps=10, checkpoint_every=3), checkpoint_dir=ckpt, **kw
    )
    assert resumed.stats["resumed_at"] == 6
    np.testing.assert_array_equal(resumed.losses, full.losses)
    np.testing.assert_array_equal(resumed.colors, full.colors)
    assert Checkpoints(ckpt).steps() == [9, 10]
    # a run killed right after its step-4 checkpoint resumes from step 4
    killed = tmp_path / "killed"
    save = Checkpoints.save

    def save_then_die(self, step, state, **meta):
        save(self, step, state, **meta)
        raise KeyboardInterrupt

    monkeypatch.setattr(Checkpoints, "save", save_then_die)
    with pytest.raises(KeyboardInterrupt):
        synthesize(
            mesh, ex, Config(size=16, steps=10, checkpoint_every=4), checkpoint_dir=killed, **kw
        )
    monkeypatch.setattr(Checkpoints, "save", save)
    assert Checkpoints(killed).steps() == [4]
    again = synthesize(
        mesh, ex, Config(size=16, steps=10, checkpoint_every=4), checkpoint_dir=killed, **kw
    )
    assert again.stats["resumed_at"] == 4
    np.testing.assert_array_equal(again.losses, full.losses)
    np.testing.assert_array_equal(again.colors, full.colors)
    # a different run is refused: texels, exemplar, key
    with pytest.raises(CheckpointMismatchError, match="different run.*texels"):
        synthesize(mesh, ex, Config(size=8, steps=10), checkpoint_dir=ckpt, **kw)
    with pytest.raises(CheckpointMismatchError, match="data"):
        synthesize(mesh, ex[::-1], Config(size=16, steps=10), checkpoint_dir=ckpt, **kw)
    other_key = {**kw, "key": jax.random.key(4)}
    with pytest.raises(CheckpointMismatchError, match="key"):
        synthesize(mesh, ex, Config(size=16, steps=10), checkpoint_dir=ckpt, **other_key)
    with pytest.raises(InputError, match="past this run"):
        synthesize(mesh, ex, Config(size=16, steps=5), checkpoint_dir=ckpt, **kw)


def test_frame_smoothing_is_a_config_field_the_checkpoint_records(tmp_path):
    """The frames change the texture, so a checkpoint of other frames is refused, and so is one
    written before the field existed (its fingerprint lacks it: its frames are not known)."""
    from jmeshtex.data import grid
    from jmeshtex.io import Checkpoints
    from jmeshtex.surfacecnn.core import FRAME_SMOOTHING

    assert Config().frame_smoothing == FRAME_SMOOTHING == 4.0
    assert Config.from_dict({"size": 16}).frame_smoothing == FRAME_SMOOTHING  # older JSON loads
    assert Config().fingerprint()["frame_smoothing"] == FRAME_SMOOTHING
    assert Config(frame_smoothing=0).fingerprint()["frame_smoothing"] == 0
    assert Config(frame_smoothing=2.0).fingerprint() != Config().fingerprint()
    # the field reaches the frames: a folded sheet (a crease the smoothing bends the frames over)
    flat, f = grid(4)
    v = np.asarray(flat, np.float64).copy()
    v[:, 2] = np.maximum(v[:, 0] - 0.5, 0.0)  # fold along x = 0.5
    v[:, 0] = np.minimum(v[:, 0], 0.5)
    frame_vector = (1.0, 1.0, 0.0)
    mesh = Mesh(v, f, uv=np.asarray(flat)[f][..., :2])
    ex = np.random.default_rng(0).uniform(size=(16, 16, 3))
    kw = dict(key=jax.random.key(3), layers=("relu1_1",), progress=False)
    base = Config(size=16, steps=2, unwrap="mesh", frame_vector=frame_vector)
    runs = {
        s: synthesize(
            mesh, ex, base.replace(frame_smoothing=s), checkpoint_dir=tmp_path / str(s), **kw
        )
        for s in (0.0, FRAME_SMOOTHING)
    }
    t0, t4 = (runs[s].surface.atlas.frame[:, 0] for s in (0.0, FRAME_SMOOTHING))
    assert np.abs(t0 - t4).max() > 0.05
    # a checkpoint of other frames is refused (its config differs)
    with pytest.raises(CheckpointMismatchError, match="config"):
        synthesize(mesh, ex, base.replace(steps=4), checkpoint_dir=tmp_path / "0.0", **kw)
    # a checkpoint written before the field existed (no frame_smoothing in its fingerprint) is
    # refused, and the same frames resume
    fingerprint = Checkpoints(tmp_path / "4.0").read_meta()["fingerprint"]
    assert fingerprint["config"]["frame_smoothing"] == FRAME_SMOOTHING
    del fingerprint["config"]["frame_smoothing"]  # as written before the field existed
    old = tmp_path / "before the field"
    Checkpoints(old, fingerprint=fingerprint).save(2, {"texture": np.zeros(3)})
    with pytest.raises(CheckpointMismatchError, match="frame_smoothing"):
        synthesize(mesh, ex, base.replace(steps=4), checkpoint_dir=old, **kw)
    again = synthesize(mesh, ex, base.replace(steps=4), checkpoint_dir=tmp_path / "4.0", **kw)
    assert again.stats["resumed_at"] == 2


def test_uv_space_synthesis_resumes_from_its_checkpoint(tmp_path):
    """The 2D baseline of a protocol cell costs more than the surface run; it resumes the same way."""
    from jmeshtex.data import grid
    from jmeshtex.surfacecnn import prepare_surface, synthesize_uv

    v, f = grid(2)
    mesh = Mesh(v, f, uv=v[f][..., :2])
    ex = np.random.default_rng(0).uniform(size=(16, 16, 3))
    surface = prepare_surface(mesh, size=16, levels=0)
    kw = dict(key=jax.random.key(3), surface=surface, layers=("relu1_1",), progress=False)
    full = synthesize_uv(mesh, ex, Config(size=16, steps=8), **kw)
    ckpt = tmp_path / "uv"
    synthesize_uv(mesh, ex, Config(size=16, steps=5), checkpoint_dir=ckpt, **kw)
    resumed = synthesize_uv(mesh, ex, Config(size=16, steps=8), checkpoint_dir=ckpt, **kw)
    assert resumed.stats["resumed_at"] == 5
    np.testing.assert_array_equal(resumed.losses, full.losses)
    np.testing.assert_array_equal(resumed.colors, full.colors)
    other_key = {**kw, "key": jax.random.key(4)}
    with pytest.raises(CheckpointMismatchError, match="key"):
        synthesize_uv(mesh, ex, Config(size=16, steps=8), checkpoint_dir=ckpt, **other_key)
    # the image is the mesh's only through the atlas that reads it: another mesh's run resumes it
    v2, f2 = grid(3)
    other = Mesh(v2, f2, uv=0.6 * v2[f2][..., :2])  # covers a third of the image
    s2 = prepare_surface(other, size=16, levels=0)
    assert s2.atlas.num_texels != surface.atlas.num_texels
    kw2 = {**kw, "surface": s2}
    moved = synthesize_uv(other, ex, Config(size=16, steps=8), checkpoint_dir=ckpt, **kw2)
    assert moved.stats["resumed_at"] == 8
    np.testing.assert_array_equal(
        moved.colors, synthesize_uv(other, ex, Config(size=16, steps=8), **kw2).colors
    )


def test_synthesis_re_unwraps_by_default_and_keeps_the_mesh_uvs_on_request():
    """``Config.unwrap``: the reference re-unwraps every mesh with xatlas, so a texel covers about the
    same surface everywhere; ``"mesh"`` keeps a layout whose density varies (here 9× by design)."""
    from jmeshtex.data import grid
    from jmeshtex.surfacecnn.core import texel_density_spread

    v, f = grid(6)
    uv = v[f][..., :2]
    uv = np.stack([uv[..., 0] ** 3, uv[..., 1]], -1)  # x³: texels 9× wider at one end
    mesh = Mesh(v, f, uv=uv)
    ex = np.random.default_rng(0).uniform(size=(16, 16, 3))
    kw = dict(key=jax.random.key(0), layers=("relu1_1",), progress=False)
    own = synthesize(mesh, ex, Config(size=16, steps=1, unwrap="mesh"), **kw).mesh
    even = synthesize(mesh, ex, Config(size=16, steps=1), **kw).mesh
    np.testing.assert_allclose(own.uv, uv, atol=1e-6)
    spread = {
        n: texel_density_spread(m.vertices, m.faces, m.uv)["ratio_p95_p5"]
        for n, m in (("own", own), ("even", even))
    }
    assert spread["own"] > 3.0 and spread["even"] < 1.5, spread
    with pytest.raises(ConfigError, match="unwrap"):
        Config(unwrap="uv")

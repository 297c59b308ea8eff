"""Inference modes: face budget, zero noise above a level, conditional generation, per-level output."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jmeshtex import InputError, Mesh
from jmeshtex.data import icosahedron, icosphere, torus
from jmeshtex.dgts import (
    Config,
    FaceBudgetError,
    Model,
    conditional,
    interpolate,
    reconstruct,
    transfer,
)
from jmeshtex.dgts.core import choose_start_level, init_level, matching_level, output_faces


def test_start_level_follows_the_face_budget(tiny_model):
    target = torus(8, 6)  # 96 faces; two levels: 384 from level 0, 96 from level 1
    assert output_faces(tiny_model, 96, 0) == 384
    assert transfer(tiny_model, target, start_level=0, key=jax.random.key(0)).start_level == 0
    res = transfer(tiny_model, target, max_faces=383, key=jax.random.key(0))
    assert res.start_level == 1 and len(res.faces) == 96
    with pytest.raises(FaceBudgetError, match="max_faces"):
        transfer(tiny_model, target, max_faces=95, key=jax.random.key(0))
    with pytest.raises(FaceBudgetError, match="start_level=0"):
        transfer(tiny_model, target, start_level=0, max_faces=383, key=jax.random.key(0))
    assert (
        len(
            transfer(tiny_model, target, start_level=0, max_faces=None, key=jax.random.key(0)).faces
        )
        == 384
    )


def _model(levels: int, template_vertices: int) -> Model:
    c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
    gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(levels))
    return Model(c, gs, gs, np.zeros((template_vertices, 3), np.float32))


@pytest.mark.parametrize("template", [12, 42, 162], ids=["F0=20", "F0=80", "F0=320"])
def test_default_start_matches_the_target_resolution_and_skips_level_0(template):
    """The start level's training mesh has the target's face count (nearest power of 4); level 0
    only for a one-level model; the face budget raises it."""
    model = _model(5, template)
    f0 = 2 * template - 4  # a closed genus-0 template
    for level in range(1, 5):
        for factor in (0.7, 1.0, 1.4):  # within a factor 2 of F_level: that level
            assert matching_level(model, int(factor * f0 * 4**level)) == level
    assert matching_level(model, f0) == 1 and matching_level(model, 1) == 1  # not the coarsest
    assert matching_level(model, f0 * 4**9) == 4
    assert matching_level(_model(1, template), 10**6) == 0
    f = f0 * 4**2
    assert choose_start_level(model, f) == 2
    assert choose_start_level(model, f, max_faces=f * 4**2 - 1) == 3  # level 2's output is over
    assert choose_start_level(model, f, max_faces=f) == 4


def test_default_noise_is_on_the_first_two_levels_run_only():
    model = _model(4, 12)
    res = transfer(model, icosphere(2), key=jax.random.key(0))  # 320 faces: level 2 of 20 x 4^l
    assert res.start_level == 2
    assert [bool(np.any(z)) for z in res.noise[0]] == [True, True]
    target = icosahedron()
    res = transfer(model, target, start_level=0, key=jax.random.key(0))
    assert [bool(np.any(z)) for z in res.noise[0]] == [True, True, False, False]
    everywhere = transfer(model, target, start_level=0, zero_noise_from=4, key=jax.random.key(0))
    assert all(np.any(z) for z in everywhere.noise[0])
    frames = interpolate(model, target, start_level=0, num_frames=2, key=jax.random.key(0))
    assert [bool(np.any(z)) for z in frames.noise[0]] == [True, True, False, False]


def test_zero_noise_from_the_start_level_is_deterministic(tiny_model):
    target = icosphere(1)
    a = transfer(tiny_model, target, start_level=0, zero_noise_from=0, key=jax.random.key(0))
    b = transfer(tiny_model, target, start_level=0, zero_noise_from=0, key=jax.random.key(1))
    np.testing.assert_array_equal(a.vertices, b.vertices)
    assert all(not np.any(z) for z in a.noise[0])
    # zero noise above level 1 only: level 0 still draws noise, so keys differ, level-1 noise is 0
    c = transfer(tiny_model, target, start_level=0, zero_noise_from=1, key=jax.random.key(0))
    d = transfer(tiny_model, target, start_level=0, zero_noise_from=1, key=jax.random.key(1))
    assert not np.any(c.noise[0][1]) and np.any(c.noise[0][0])
    assert not np.allclose(c.vertices, d.vertices)


def test_per_level_output_grows_and_ends_in_the_result(tiny_model):
    res = transfer(
        tiny_model,
        icosphere(1),
        num_samples=2,
        per_level=True,
        start_level=0,
        key=jax.random.key(0),
    )
    assert [v.shape for v in res.level_vertices] == [(2, 42, 3), (2, 162, 3)]
    assert [len(f) for f in res.level_faces] == [80, 320]
    np.testing.assert_allclose(res.level_vertices[-1], res.vertices, rtol=0, atol=1e-12)
    # each level's output lies where the target lies (same coordinates, not the level's frame)
    for v in res.level_vertices:
        assert abs(np.linalg.norm(v[0], axis=1).mean() - 1.0) < 0.3


def test_conditional_generation_reproduces_the_reconstruction_below_its_level(
    tiny_model, tiny_meshes
):
    template = Mesh(tiny_meshes.template, tiny_meshes.faces[0])
    rec = reconstruct(tiny_model, template)
    cond = conditional(
        tiny_model, template, level=1, num_samples=2, per_level=True, key=jax.random.key(5)
    )
    for s in range(2):
        np.testing.assert_allclose(
            cond.level_vertices[0][s], rec.level_vertices[0][0], rtol=0, atol=1e-6
        )
    assert not np.allclose(
        cond.level_vertices[1][0], cond.level_vertices[1][1]
    )  # fresh noise at level 1
    full = conditional(tiny_model, template, level=tiny_model.num_levels, key=jax.random.key(9))
    np.testing.assert_allclose(full.vertices, rec.vertices, rtol=0, atol=1e-9)
    with pytest.raises(Exception, match="z\\*"):
        reconstruct(tiny_model, icosphere(1))


def test_training_snapshots_match_the_reconstruction(tiny_meshes):
    from jmeshtex.dgts import train
    from tests.dgts.conftest import TINY, TINY_KEY

    result = train(
        tiny_meshes, TINY, key=jax.random.key(TINY_KEY), progress=False, snapshot_every=1
    )
    snaps = result.extra["snapshots"]
    assert [(s["level"], s["step"]) for s in snaps] == [
        (0, 2),
        (1, 2),
    ]  # rounded up to a chunk: once per level
    assert [s["sample"].shape for s in snaps] == [(12, 3), (42, 3)]
    rec = reconstruct(result.model, Mesh(tiny_meshes.template, tiny_meshes.faces[0]))
    scale = TINY.scale_factor  # level 1's frame is the template's times 2
    np.testing.assert_allclose(
        snaps[1]["reconstruction"], scale * rec.level_vertices[1][0], rtol=0, atol=1e-4
    )
    with pytest.raises(Exception, match="snapshot_every"):
        train(tiny_meshes, TINY, key=jax.random.key(0), progress=False, snapshot_every=0)


def test_official_gen_levels_clip_as_the_official_trim():
    """``--gen-levels`` (default [1, 4]) through ``Mesh2Mesh.trim``: a stop past the last level (or
    below 0) becomes the last level, a start past the stop becomes the stop."""
    from jmeshtex.dgts import official_gen_levels
    from jmeshtex.dgts._transfer import OFFICIAL_GEN_LEVELS

    assert OFFICIAL_GEN_LEVELS == (1, 4)
    assert official_gen_levels(_model(5, 12)) == (1, 4)
    assert official_gen_levels(_model(7, 12)) == (1, 4)
    assert official_gen_levels(_model(3, 12)) == (1, 2)
    assert official_gen_levels(_model(1, 12)) == (0, 0)
    assert official_gen_levels(_model(5, 12), (3, -1)) == (3, 4)
    assert official_gen_levels(_model(5, 12), (4, 2)) == (2, 2)
    with pytest.raises(InputError, match="gen_levels"):
        official_gen_levels(_model(5, 12), (-1, 3))


def test_stop_level_runs_the_generators_start_to_stop_and_subdivides_between_only():
    """``start_level … stop_level``: ``stop − start`` subdivisions, the generators of those levels
    only (the same result as :func:`generate` on them with the returned noise), noise on the
    first two levels run."""
    from jmeshtex.dgts.core import generate, plan_transfer

    model = _model(5, 12)
    target = icosahedron()
    res = transfer(model, target, start_level=1, stop_level=3, key=jax.random.key(0))
    assert (res.start_level, res.stop_level) == (1, 3)
    assert len(res.faces) == 20 * 4**2 == output_faces(model, 20, 1, 3)
    assert [bool(np.any(z)) for z in res.noise[0]] == [True, True, False]
    plan = plan_transfer(model, target, start_level=1, stop_level=3)
    assert plan.stop_level == 3 and len(plan.sizes) == 3
    expected = generate(model.generators[1:4], plan.vertices, plan.geometry, res.noise[0])
    np.testing.assert_allclose(res.vertices[0], plan.to_target(expected), rtol=0, atol=1e-5)
    # the same levels with stop_level = the last one give one more level and its subdivision
    full = transfer(model, target, start_level=1, key=jax.random.key(0))
    assert full.stop_level == 4 and len(full.faces) == 20 * 4**3
    one = transfer(model, target, start_level=2, stop_level=2, key=jax.random.key(0))
    assert len(one.faces) == 20 and [bool(np.any(z)) for z in one.noise[0]] == [True]
    for bad in (0, 5, 1.5):
        with pytest.raises(InputError, match="stop_level"):
            transfer(model, target, start_level=1, stop_level=bad, key=jax.random.key(0))
    frames = interpolate(
        model, target, start_level=0, stop_level=1, num_frames=2, key=jax.random.key(1)
    )
    assert frames.stop_level == 1 and len(frames.faces) == 80
    # jmeshtex's default start (by face count) respects the stop level and its budget
    assert transfer(model, icosphere(3), stop_level=2, key=jax.random.key(0)).start_level == 2
    assert choose_start_level(model, 20 * 4**3, stop_level=2) == 2
    assert choose_start_level(model, 20, stop_level=3, max_faces=20 * 4) == 2


def test_the_official_default_levels_on_the_raw_target_scaled_to_unit_edge():
    """The official inference (``dgts_base.py`` ``animate``): the raw target to unit edge
    (``to_unit_edge``: minus the vertex mean, over the mean edge length), the generators
    ``--gen-levels`` 1 … 4, noise on the first two levels run (``zero_places = (0, 0, 1, 1, 1)``)."""
    from jmeshtex.dgts import official_gen_levels
    from jmeshtex.dgts.core import generate, plan_transfer

    model = _model(5, 12)
    v, f = icosahedron()
    raw = (np.asarray(v) * 3.7 + [1.0, -2.0, 0.5], f)  # any scale and placement
    start, stop = official_gen_levels(model)
    res = transfer(model, raw, start_level=start, stop_level=stop, key=jax.random.key(0))
    assert (res.start_level, res.stop_level) == (1, 4)
    assert [bool(np.any(z)) for z in res.noise[0]] == [True, True, False, False]
    plan = plan_transfer(model, raw, start_level=start, stop_level=stop)
    edges = np.unique(
        np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1), axis=0
    )
    ell = np.linalg.norm(raw[0][edges[:, 0]] - raw[0][edges[:, 1]], axis=1).mean()
    np.testing.assert_allclose(plan.vertices, (raw[0] - raw[0].mean(0)) / ell, rtol=0, atol=1e-6)
    out = generate(model.generators[1:5], plan.vertices, plan.geometry, res.noise[0])
    # the official output is in the unit-edge frame of the target (``export`` divides by 2^level);
    # jmeshtex maps it back to the target's own coordinates
    unit = np.asarray(out, np.float64) / 2.0 ** (stop - start)
    np.testing.assert_allclose(res.vertices[0], unit * ell + raw[0].mean(0), rtol=0, atol=1e-4)

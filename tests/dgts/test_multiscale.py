"""Multi-scale training meshes: frames, sampling, fitting, subdivision structure, files."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import ConfigError, InputError, Mesh, MeshError, MeshIOError
from jmeshtex.data import grid, icosahedron, icosphere
from jmeshtex.dgts import PrepareConfig, load_training_meshes, save_training_meshes, training_meshes
from jmeshtex.dgts._multiscale import normalize_pair
from jmeshtex.dgts.core import fit_level, sample_points
from jmeshtex.geometry import mean_edge_length, subdivide_midpoint, unique_edges


def test_unique_edges_counts_euler():
    v, f = icosphere(2)
    assert len(unique_edges(f)) == len(v) + len(f) - 2  # V - E + F = 2


def test_sample_points_are_on_the_surface_and_area_uniform(key):
    v, f = grid(4)  # unit square, z = 0
    p, n = sample_points(jnp.asarray(v), jnp.asarray(f), 20000, key=key)
    p = np.asarray(p)
    assert np.all((p[:, :2] >= -1e-12) & (p[:, :2] <= 1 + 1e-12)) and np.all(p[:, 2] == 0)
    np.testing.assert_allclose(np.abs(np.asarray(n)[:, 2]), 1.0)
    # area-uniform on [0,1]^2: mean 1/2, variance 1/12 per axis (5 sigma bounds for 20000 samples)
    np.testing.assert_allclose(p[:, :2].mean(0), 0.5, atol=5 * np.sqrt(1 / 12 / 20000))
    frac_left_quarter = np.mean(p[:, 0] < 0.25)
    assert abs(frac_left_quarter - 0.25) < 5 * np.sqrt(0.25 * 0.75 / 20000)


def test_sample_points_never_picks_a_zero_area_face(key):
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]])
    f = np.array([[0, 1, 2], [0, 1, 3]])  # the second face is degenerate (collinear)
    p, _ = sample_points(jnp.asarray(v), jnp.asarray(f), 2000, key=key)
    assert np.all(np.asarray(p)[:, 1] >= 0) and np.all(np.asarray(p)[:, 0] <= 1 + 1e-12)


def test_normalize_pair_gives_unit_template_edges_and_maps_reference_consistently():
    rv, _ = icosphere(2)
    rv = 3.0 * rv + np.array([1.0, -2.0, 5.0])
    tv, tf = icosahedron(0.7)
    r, t, s, c = normalize_pair(rv, tv, tf)
    assert mean_edge_length(t, tf) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(r, (rv - c) * s, atol=1e-12)
    np.testing.assert_allclose(
        r.max(0) - r.min(0), (t.max(0) - t.min(0)).max(), rtol=1e-12
    )  # both unit-cube fitted


def test_fit_level_pulls_a_small_sphere_onto_a_large_one():
    v, f = icosphere(1)
    target = icosphere(3)
    cfg = PrepareConfig(steps=200, learning_rate=2e-2, samples_per_level=500)
    out, terms = fit_level((0.6 * v, f), target, config=cfg, num_samples=500, key=jax.random.key(0))
    before = np.abs(np.linalg.norm(0.6 * v, axis=1) - 1).mean()
    after = np.abs(np.linalg.norm(out, axis=1) - 1).mean()
    assert before == pytest.approx(0.4)
    assert after < 0.15 * before  # residual: the Laplacian term pulls inwards, samples are discrete
    assert set(terms) == {
        "s2t",
        "t2s",
        "normal_s2t",
        "normal_t2s",
        "edge_std",
        "edge_local",
        "laplacian",
    }


def test_training_meshes_structure(tiny_meshes):
    tm = tiny_meshes
    assert tm.num_levels == 2 and len(tm.edge_vertices) == 1
    sub = subdivide_midpoint(tm.vertices[0], tm.faces[0])
    np.testing.assert_array_equal(sub.faces, tm.faces[1])
    np.testing.assert_array_equal(sub.edge_vertices, tm.edge_vertices[0])
    assert tm.scales[1] / tm.scales[0] == pytest.approx(2.0)
    assert mean_edge_length(tm.template, tm.faces[0]) == pytest.approx(1.0)
    for v, f in zip(
        tm.vertices, tm.faces, strict=True
    ):  # every level keeps a mean edge near 1 in its frame
        assert 0.7 < mean_edge_length(v, f) < 1.3


def test_training_meshes_take_a_mesh_or_a_pair_and_follow_their_key(tiny_meshes):
    cfg = PrepareConfig(levels=2, steps=20, samples_per_level=200)  # the fixture's settings
    reference, template = icosphere(2), icosahedron()
    assert isinstance(reference, Mesh) and isinstance(template, Mesh)
    calls = []
    from_mesh = training_meshes(
        reference, template, config=cfg, key=jax.random.key(0), progress=lambda *a: calls.append(a)
    )
    from_pair = training_meshes(
        (reference.vertices, reference.faces),
        (template.vertices, template.faces),
        config=cfg,
        key=jax.random.key(0),
        progress=False,
    )
    other_key = training_meshes(
        reference, template, config=cfg, key=jax.random.key(1), progress=False
    )
    for level in range(2):
        np.testing.assert_array_equal(from_mesh.vertices[level], from_pair.vertices[level])
        np.testing.assert_array_equal(from_mesh.vertices[level], tiny_meshes.vertices[level])
        assert isinstance(from_mesh.mesh(level), Mesh)
        np.testing.assert_array_equal(from_mesh.mesh(level).faces, from_mesh.faces[level])
    assert not np.allclose(
        other_key.vertices[1], from_mesh.vertices[1]
    )  # the key drives the sampling
    assert calls[-1] == ("level 1", 20, 20) and ("level 0", 20, 20) in calls


def test_save_load_round_trip(tmp_path, tiny_meshes):
    path = save_training_meshes(tiny_meshes, tmp_path / "t.npz")
    back = load_training_meshes(path)
    for a, b in zip(back, tiny_meshes, strict=True):
        for x, y in zip(
            a if isinstance(a, tuple) else (a,), b if isinstance(b, tuple) else (b,), strict=True
        ):
            np.testing.assert_array_equal(x, y)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left over


def test_errors(tmp_path):
    with pytest.raises(MeshIOError, match="no such file"):
        load_training_meshes(tmp_path / "missing.npz")
    v, f = icosahedron()
    with pytest.raises(MeshError):
        training_meshes(
            (v, f),
            (v, np.concatenate([f, f[:1]])),
            config=PrepareConfig(levels=1, steps=0),
            key=jax.random.key(0),
            progress=False,
        )
    with pytest.raises(InputError, match="reference"):
        training_meshes(v, (v, f), config=PrepareConfig(levels=1, steps=0), key=jax.random.key(0))


def test_coarse_levels_fit_the_coarse_reference_in_the_references_frame(tiny_meshes):
    cfg = PrepareConfig(levels=2, steps=20, samples_per_level=200)  # the fixture's settings
    reference, template = icosphere(2), icosahedron()
    same = training_meshes(
        reference, template, config=cfg, key=jax.random.key(0), progress=False,
        coarse_reference=reference, coarse_levels=1,
    )  # fmt: skip
    for level in range(2):  # the reference itself as the coarse one: the plain fit
        np.testing.assert_allclose(same.vertices[level], tiny_meshes.vertices[level], atol=1e-9)
    # a shrunken sphere in the reference's coordinates: level 0 follows it, level 1 the reference
    shrunk = Mesh(0.8 * np.asarray(reference.vertices), reference.faces)
    converged = cfg.replace(
        steps=60
    )  # fits close enough to read the radii (measured: 0.798, 1.000)
    plain, tm = (
        training_meshes(
            reference, template, config=converged, key=jax.random.key(0), progress=False, **extra
        )
        for extra in ({}, {"coarse_reference": shrunk, "coarse_levels": 1})
    )  # fmt: skip

    def radius(v):
        return float(np.linalg.norm(v - v.mean(0), axis=1).mean())

    ratio0 = radius(tm.vertices[0]) / radius(plain.vertices[0])
    ratio1 = radius(tm.vertices[1]) / radius(plain.vertices[1])
    assert abs(ratio0 - 0.8) < 0.02 and abs(ratio1 - 1.0) < 0.02, (ratio0, ratio1)
    with pytest.raises(ConfigError, match="needs a coarse_reference"):
        training_meshes(reference, template, config=cfg, key=jax.random.key(0), coarse_levels=1)
    with pytest.raises(ConfigError, match=r"coarse_levels must be an int in \[0, 2\)"):
        training_meshes(
            reference, template, config=cfg, key=jax.random.key(0), progress=False,
            coarse_reference=shrunk, coarse_levels=2,
        )  # fmt: skip


def test_a_rotation_remeshes_the_reference_from_the_rotated_template(tiny_meshes):
    """``rotation`` turns the normalised template before the fit: the template field is the turned
    one, and steps=0 levels are the turned plain levels (the fit is what differs, not the frame)."""
    cfg = PrepareConfig(levels=2, steps=0, samples_per_level=200)
    r = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    plain, turned = (
        training_meshes(
            icosphere(2), icosahedron(), config=cfg, key=jax.random.key(0), progress=False, **extra
        )
        for extra in ({}, {"rotation": r})
    )  # fmt: skip
    np.testing.assert_allclose(turned.template, plain.template @ r.T, atol=1e-12)
    for level in range(2):
        np.testing.assert_allclose(turned.vertices[level], plain.vertices[level] @ r.T, atol=1e-9)
    np.testing.assert_array_equal(turned.scales, plain.scales)
    for bad, match in ((np.eye(2), r"\[3, 3\]"), (np.diag([1.0, 1.0, -1.0]), "proper rotation")):
        with pytest.raises(ConfigError, match=match):
            training_meshes(
                icosphere(2), icosahedron(), config=cfg, key=jax.random.key(0), rotation=bad
            )


def test_a_checkpointed_fit_resumes_after_its_last_finished_level(tmp_path, tiny_meshes):
    cfg = PrepareConfig(levels=2, steps=20, samples_per_level=200)  # the fixture's settings
    path = tmp_path / "levels"
    fit = functools.partial(
        training_meshes, icosphere(2), icosahedron(), config=cfg, checkpoint_dir=path
    )

    class Stop(Exception):
        pass

    def stop_in_level_1(stage, done, total):
        if stage == "level 1":
            raise Stop

    with pytest.raises(Stop):
        fit(key=jax.random.key(0), progress=stop_in_level_1)
    assert (path / "levels.npz").is_file()  # level 0 was kept
    stages = []
    resumed = fit(key=jax.random.key(0), progress=lambda stage, *_: stages.append(stage))
    assert set(stages) == {"level 1"}  # level 0 came from the file, not fitted again
    for level in range(2):  # and the result is the uninterrupted one, bit for bit
        np.testing.assert_array_equal(resumed.vertices[level], tiny_meshes.vertices[level])
    again = fit(
        key=jax.random.key(0),
        progress=lambda *a: pytest.fail(f"a finished fit was fitted again: {a}"),
    )
    np.testing.assert_array_equal(again.vertices[1], tiny_meshes.vertices[1])
    with pytest.raises(ConfigError, match="other inputs"):  # never overwritten for other inputs
        fit(key=jax.random.key(1), progress=False)

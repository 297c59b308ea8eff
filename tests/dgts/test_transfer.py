"""Transfer to any mesh (open, closed, genus 1), samples, interpolation, heights."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jmeshtex import InputError, Mesh, MeshError
from jmeshtex.data import grid, icosahedron, icosphere, torus
from jmeshtex.dgts import Transfer, interpolate, transfer
from jmeshtex.dgts.core import normal_heights, plan_transfer, run_plan
from jmeshtex.geometry import subdivide_midpoint, vertex_normals


@pytest.mark.parametrize("mesh", [torus(8, 6), grid(5)], ids=["torus_genus1", "open_grid"])
def test_transfer_any_topology(tiny_model, mesh, key):
    v, f = mesh
    v = 3.0 * v + 7.0  # any scale and placement
    res = transfer(tiny_model, Mesh(v, f), num_samples=2, start_level=0, key=key)
    assert isinstance(res, Transfer)
    sub = subdivide_midpoint(v, f)
    np.testing.assert_array_equal(
        res.faces, sub.faces
    )  # no re-meshing: the target's own subdivision
    np.testing.assert_allclose(res.base, sub.vertices, atol=1e-9)
    assert res.vertices.shape == (2, len(sub.vertices), 3) and np.isfinite(res.vertices).all()
    assert not np.allclose(res.vertices[0], res.vertices[1])  # different noise, different samples
    edge = np.linalg.norm(
        sub.vertices[sub.faces[:, 0]] - sub.vertices[sub.faces[:, 1]], axis=1
    ).mean()
    assert np.abs(res.vertices - res.base).max() < 5 * edge  # displacements are texture-sized


def test_start_level_skips_coarse_generators(tiny_model, key):
    v, f = icosahedron()
    res = transfer(tiny_model, (v, f), start_level=1, key=key)
    assert res.faces.shape == f.shape  # the last level only: no subdivision
    with pytest.raises(InputError, match="start_level"):
        transfer(tiny_model, (v, f), start_level=2, key=key)
    with pytest.raises(InputError, match="num_samples"):
        transfer(tiny_model, (v, f), num_samples=0, key=key)
    with pytest.raises(MeshError):
        transfer(tiny_model, (v, np.concatenate([f, f[:1]])), key=key)
    with pytest.raises(InputError, match="target"):
        transfer(tiny_model, v, key=key)  # positions alone are not a mesh


def test_a_mesh_and_a_pair_give_the_same_transfer_and_the_key_decides(tiny_model):
    target = torus(8, 6)
    a = transfer(tiny_model, target, num_samples=2, key=jax.random.key(5))
    b = transfer(tiny_model, (target.vertices, target.faces), num_samples=2, key=jax.random.key(5))
    c = transfer(tiny_model, target, num_samples=2, key=jax.random.key(6))
    np.testing.assert_array_equal(a.vertices, b.vertices)
    assert not np.allclose(a.vertices, c.vertices)
    np.testing.assert_array_equal(a.mesh(1).vertices, a.vertices[1])
    np.testing.assert_array_equal(a.mesh(1).faces, a.faces)


def test_interpolation_end_frames_replay_their_noise(tiny_model, key):
    target = torus(8, 6)
    res = interpolate(tiny_model, target, num_frames=3, start_level=0, key=key)
    assert res.vertices.shape[0] == 3
    plan = plan_transfer(tiny_model, target)
    assert plan.sizes == tuple(len(z) for z in res.noise[0])
    for frame, noise in ((0, res.noise[0]), (2, res.noise[-1])):
        out = np.asarray(run_plan(tiny_model, plan, noise), np.float64)
        # the plan's frame: centred on the centroid, mean edge 1, then x2 per subdivision
        factor = 2.0 ** (len(plan.sizes) - 1) / np.mean(
            [
                np.linalg.norm(target.vertices[a] - target.vertices[b])
                for a, b in _edges(target.faces)
            ]
        )
        np.testing.assert_allclose(
            out / factor + target.vertices.mean(0), res.vertices[frame], atol=1e-5
        )
        np.testing.assert_allclose(plan.to_target(out), res.vertices[frame], atol=1e-12)
    mid = [0.5 * (a + b) for a, b in zip(res.noise[0], res.noise[-1], strict=True)]
    for a, b in zip(mid, res.noise[1], strict=True):
        np.testing.assert_allclose(a, b, atol=1e-6)


def test_normal_heights_of_a_single_bump():
    v, f = grid(12)
    flat = normal_heights((v, f))
    np.testing.assert_allclose(flat, 0.0, atol=1e-12)
    bump = v.copy()
    centre = np.argmin(np.linalg.norm(v[:, :2] - 0.5, axis=1))
    bump[centre, 2] = 0.05
    h = normal_heights((bump, f))
    assert np.argmax(h) == centre and h[centre] > 0.5 * 0.05 / (
        1 / 12
    )  # about the bump in mean edges
    sphere = icosphere(3)
    assert (
        np.abs(normal_heights(sphere)).max() < 0.05
    )  # Taubin smoothing does not shrink a sphere much


def test_vertex_normals_point_outwards_on_a_sphere():
    v, f = icosphere(2)
    n = vertex_normals(v, f)
    assert np.min(np.sum(n * v, axis=1)) > 0.99


def test_heights_are_displacements_along_the_base_normals(tiny_model, key):
    target = 5.0 * icosphere(1).vertices + 1.0, icosphere(1).faces
    res = transfer(tiny_model, target, start_level=0, key=key)
    factor = plan_transfer(
        tiny_model, target
    ).factor  # target coordinates -> the output's level frame
    n = vertex_normals(res.base, res.faces)
    expected = factor * np.einsum("vd,vd->v", res.vertices[0] - res.base, n)
    np.testing.assert_allclose(res.heights[0], expected, rtol=1e-9, atol=1e-10)
    assert np.abs(res.heights).max() > 1e-3  # the generators displaced something


def _edges(faces):
    from jmeshtex.geometry import unique_edges

    return unique_edges(faces)


def test_a_model_with_non_finite_parameters_is_refused_naming_the_level():
    from jmeshtex.dgts import Config, Model
    from jmeshtex.dgts.core import init_level

    c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
    gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(2))
    ok = Model(c, gs, gs, np.zeros((12, 3), np.float32))
    assert np.isfinite(
        transfer(ok, icosahedron(), key=jax.random.key(0), start_level=0).vertices
    ).all()
    nan_level = jax.tree.map(lambda x: np.full_like(np.asarray(x), np.nan), gs[1])
    bad = Model(c, (gs[0], nan_level), gs, np.zeros((12, 3), np.float32))
    with pytest.raises(InputError, match="generator at level 1 has non-finite parameters"):
        transfer(bad, icosahedron(), key=jax.random.key(0), start_level=0)

"""Transfer to any mesh (open, closed, genus 1), samples, interpolation, heights."""

from __future__ import annotations

import numpy as np
import pytest

from jmeshtex import InputError, MeshError
from jmeshtex.data import grid, icosahedron, icosphere, torus
from jmeshtex.dgts import interpolate, normal_heights, transfer, vertex_normals
from jmeshtex.geometry import subdivide_midpoint


@pytest.mark.parametrize("mesh", [torus(8, 6), grid(5)], ids=["torus_genus1", "open_grid"])
def test_transfer_any_topology(tiny_model, mesh, key):
    v, f = mesh
    v = 3.0 * v + 7.0  # any scale and placement
    res = transfer(tiny_model, v, f, num_samples=2, key=key)
    sub = subdivide_midpoint(v, f)
    np.testing.assert_array_equal(res.faces, sub.faces)  # no re-meshing: the target's own subdivision
    np.testing.assert_allclose(res.base, sub.vertices, atol=1e-9)
    assert res.vertices.shape == (2, len(sub.vertices), 3) and np.isfinite(res.vertices).all()
    assert not np.allclose(res.vertices[0], res.vertices[1])  # different noise, different samples
    edge = np.linalg.norm(sub.vertices[sub.faces[:, 0]] - sub.vertices[sub.faces[:, 1]], axis=1).mean()
    assert np.abs(res.vertices - res.base).max() < 5 * edge  # displacements are texture-sized


def test_start_level_skips_coarse_generators(tiny_model, key):
    v, f = icosahedron()
    res = transfer(tiny_model, v, f, start_level=1, key=key)
    assert res.faces.shape == f.shape  # the last level only: no subdivision
    with pytest.raises(InputError, match="start_level"):
        transfer(tiny_model, v, f, start_level=2, key=key)
    with pytest.raises(InputError, match="num_samples"):
        transfer(tiny_model, v, f, num_samples=0, key=key)
    with pytest.raises(MeshError):
        transfer(tiny_model, v, np.concatenate([f, f[:1]]), key=key)


def test_interpolation_end_frames_replay_their_noise(tiny_model, key):
    from jmeshtex.dgts._transfer import _prepare_target, _run_jit

    v, f = torus(8, 6)
    res = interpolate(tiny_model, v, f, num_frames=3, key=key)
    assert res.vertices.shape[0] == 3
    for frame, noise in ((0, res.noise[0]), (2, res.noise[-1])):
        v0, _, center, scale, n, geos, _, _ = _prepare_target(tiny_model, v, f, 0)
        out = np.asarray(_run_jit(tiny_model, v0.astype(np.float32), geos, tiny_model.generators, noise), np.float64)
        np.testing.assert_allclose(out / (scale * 2 ** (n - 1)) + center, res.vertices[frame], atol=1e-5)
    mid = [0.5 * (a + b) for a, b in zip(res.noise[0], res.noise[-1], strict=True)]
    for a, b in zip(mid, res.noise[1], strict=True):
        np.testing.assert_allclose(a, b, atol=1e-6)


def test_normal_heights_of_a_single_bump():
    v, f = grid(12)
    flat = normal_heights(v, f)
    np.testing.assert_allclose(flat, 0.0, atol=1e-12)
    bump = v.copy()
    centre = np.argmin(np.linalg.norm(v[:, :2] - 0.5, axis=1))
    bump[centre, 2] = 0.05
    h = normal_heights(bump, f)
    assert np.argmax(h) == centre and h[centre] > 0.5 * 0.05 / (1 / 12)  # about the bump in mean edges
    sphere = icosphere(3)
    assert np.abs(normal_heights(*sphere)).max() < 0.05  # Taubin smoothing does not shrink a sphere much


def test_vertex_normals_point_outwards_on_a_sphere():
    v, f = icosphere(2)
    n = vertex_normals(v, f)
    assert np.min(np.sum(n * v, axis=1)) > 0.99

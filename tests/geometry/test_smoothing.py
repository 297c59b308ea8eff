"""`geometry.taubin_smooth`: the one Taubin smoother, and the two callers built on it."""

from __future__ import annotations

import numpy as np
import pytest

from jmeshtex import InputError, dgts, meshmatch
from jmeshtex.data import icosphere
from jmeshtex.geometry import taubin_smooth, vertex_normals


def _bumpy_sphere(seed: int = 0):
    v, f = icosphere(3)
    rng = np.random.default_rng(seed)
    return v * (1 + 0.05 * rng.standard_normal((len(v), 1))), f


def _dense_taubin(v, f, steps, lam, mu):
    """The oracle: ``((I + μΔ)(I + λΔ))^steps v`` with a dense adjacency built face by face."""
    n = len(v)
    adj = np.zeros((n, n))
    for a, b in ((0, 1), (1, 2), (2, 0)):
        adj[f[:, a], f[:, b]] = adj[f[:, b], f[:, a]] = 1.0
    lap = adj / adj.sum(axis=1, keepdims=True) - np.eye(n)
    step = (np.eye(n) + mu * lap) @ (np.eye(n) + lam * lap)
    return np.linalg.matrix_power(step, steps) @ v


@pytest.mark.parametrize("steps, lam, mu", [(0, 0.5, -0.53), (1, 0.5, -0.53), (7, 0.33, -0.34)])
def test_matches_the_dense_formula(steps, lam, mu):
    v, f = _bumpy_sphere()
    got = taubin_smooth((v, f), steps=steps, lam=lam, mu=mu)
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, _dense_taubin(v, f, steps, lam, mu), rtol=0, atol=1e-12)


def test_keeps_a_sphere_s_size_and_removes_bumps():
    v, f = _bumpy_sphere()
    r = np.linalg.norm(taubin_smooth((v, f), steps=30), axis=1)
    # no shrinkage: the mean radius moves by about 1 % (the bumps' share), where plain Laplacian
    # smoothing with the same 30 steps of λ shrinks it by far more (checked below)
    assert abs(r.mean() - np.linalg.norm(v, axis=1).mean()) < 0.02
    shrunk = np.linalg.norm(_dense_taubin(v, f, 30, 0.5, 0.0), axis=1)
    assert np.linalg.norm(v, axis=1).mean() - shrunk.mean() > 0.05
    assert r.std() < 0.5 * np.linalg.norm(v, axis=1).std()  # the bumps are damped


def test_meshmatch_smooths_with_the_geometry_function():
    v, f = _bumpy_sphere(1)
    base = meshmatch.core.base_surface((v, f), smoothing_steps=5)
    np.testing.assert_allclose(base.vertices, _dense_taubin(v, f, 5, 0.5, -0.53), atol=1e-12)


def test_dgts_normal_heights_are_heights_over_the_smoothed_copy():
    v, f = _bumpy_sphere(2)
    smooth = _dense_taubin(v, f, 10, 0.5, -0.53)
    n = vertex_normals(smooth, f)
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    ell = np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1).mean()
    expected = np.einsum("vd,vd->v", v - smooth, n) / ell
    np.testing.assert_allclose(dgts.core.normal_heights((v, f)), expected, rtol=0, atol=1e-10)


@pytest.mark.parametrize("kwargs", [{"lam": 0.0}, {"lam": 1.0}, {"mu": -0.4}, {"steps": -1}])
def test_bad_arguments_are_input_errors(kwargs):
    with pytest.raises(InputError):
        taubin_smooth(icosphere(1), **kwargs)


def test_numpy_integer_steps_are_accepted():
    v, f = icosphere(1)
    np.testing.assert_array_equal(
        taubin_smooth((v, f), steps=np.int64(3)), taubin_smooth((v, f), steps=3)
    )

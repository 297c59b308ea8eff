"""The transform catalogue itself: each transform is what it claims to be."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from jmeshtex.data import icosphere
from jmeshtex.testing import CATALOGUE, Field, MeshState, random_rotation


def _edge_lengths(v, f):
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    return np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1)


@given(seed=st.integers(0, 2**31 - 1))
def test_random_rotation_is_a_rotation(seed):
    rng = np.random.default_rng(seed)
    R = random_rotation(rng)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    Q = random_rotation(rng, proper=False)
    assert np.linalg.det(Q) == pytest.approx(-1.0)


@pytest.mark.parametrize("name", ["fold", "folds", "hinge"])
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(6, 12))
def test_exact_isometries_keep_every_edge_length(name, seed, n):
    real = CATALOGUE[name].draw(np.random.default_rng(seed), resolution=n)
    a = _edge_lengths(real.source.vertices, real.source.faces)
    b = _edge_lengths(real.target.vertices, real.target.faces)
    np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-14)
    # and it is not a rigid motion: some distance between non-adjacent vertices changed
    d0 = np.linalg.norm(real.source.vertices[0] - real.source.vertices[-1])
    d1 = np.linalg.norm(real.target.vertices[0] - real.target.vertices[-1])
    assert abs(d0 - d1) > 1e-3


@pytest.mark.parametrize("name", ["cylinder", "cone", "catenoid"])
def test_smooth_isometries_converge_at_second_order(name):
    errs = []
    for n in (8, 16, 32, 64):
        real = CATALOGUE[name].draw(np.random.default_rng(0), resolution=n)
        a = _edge_lengths(real.source.vertices, real.source.faces)
        b = _edge_lengths(real.target.vertices, real.target.faces)
        errs.append(np.max(np.abs(b / a - 1)))
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    assert errs[0] > 1e-6  # a real deformation, not the identity
    assert np.all(ratios > 3.5), (errs, ratios)  # relative edge-length error O(h²)


def test_rigid_motion_maps_points_and_vectors():
    v, f = icosphere(1)
    s = MeshState(v, f)
    real = CATALOGUE["rigid"].draw(np.random.default_rng(1), s)
    np.testing.assert_allclose(real.map(Field("points", v)).value, real.target.vertices, atol=1e-12)
    x = np.random.default_rng(2).standard_normal((len(v), 2, 3))
    y = real.map(Field("vertex_vector", x)).value
    np.testing.assert_allclose(np.linalg.norm(y, axis=-1), np.linalg.norm(x, axis=-1), rtol=1e-12)


def test_relabellings_map_values_consistently():
    v, f = icosphere(1)
    s = MeshState(v, f)
    rng = np.random.default_rng(3)
    real = CATALOGUE["permute_vertices"].draw(rng, s)
    # positions carried as vertex scalars land on the target's positions
    np.testing.assert_array_equal(real.map(Field("vertex_scalar", v)).value, real.target.vertices)
    real = CATALOGUE["rotate_corners"].draw(rng, s)
    per_corner = v[f]  # [F, 3, 3]: corner positions are a face_edge-like value
    np.testing.assert_array_equal(
        real.map(Field("face_edge", per_corner)).value, real.target.vertices[real.target.faces]
    )
    real = CATALOGUE["permute_faces"].draw(rng, s)
    np.testing.assert_array_equal(real.map(Field("face_scalar", f)).value, real.target.faces)


def test_extrinsic_values_have_no_action_under_bending():
    real = CATALOGUE["fold"].draw(np.random.default_rng(0))
    with pytest.raises(ValueError, match="no action"):
        real.map(Field("vertex_vector", np.zeros((real.source.num_vertices, 1, 3))))

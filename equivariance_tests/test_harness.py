"""The harness can pass and can fail: its API, its negative controls and its property-based use."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from equivariance_tests._toy_operators import centroid_distance, height
from jmeshtex.data import icosphere
from jmeshtex.testing import (
    CATALOGUE,
    REGISTRY,
    Field,
    MeshState,
    _entries,  # noqa: F401
    assert_equivariant,
    check,
    convergence,
    equivariance_error,
    features,
    gauge_change,
    gauges,
    rigid_motion,
    rotations,
)


@given(R=rotations(), t=st.lists(st.floats(-10, 10), min_size=3, max_size=3))
def test_equivariant_operator_has_roundoff_error(R, t):
    v, f = icosphere(1)
    state = MeshState(v, f)
    x = Field("vertex_scalar", np.random.default_rng(0).standard_normal((len(v), 2)))
    errors = assert_equivariant(
        centroid_distance, 0, {"x": x}, transforms=[rigid_motion(state, R, np.array(t))]
    )
    assert errors["rigid"] < 1e-12


@given(R=rotations())
def test_non_equivariant_operator_is_flagged(R):
    v, f = icosphere(1)
    state = MeshState(v, f)
    x = Field("vertex_scalar", np.ones((len(v), 1)))
    real = rigid_motion(state, R)
    if abs(R[2, 2]) > 1 - 1e-6:  # a rotation about z leaves heights unchanged
        return
    assert equivariance_error(height, real, {"x": x}) > 1e-6
    with pytest.raises(
        AssertionError, match=r"not equivariant \(float64\):\n  rigid: relative error"
    ):
        assert_equivariant(height, 0, {"x": x}, transforms=[real])


@pytest.mark.parametrize(
    "name, transform",
    [
        ("negative.complex_bias", "gauge"),
        ("negative.extrinsic_log", "fold"),
        ("negative.extrinsic_log", "hinge"),
        ("negative.face_vertex_order", "rotate_corners"),
    ],
)
@pytest.mark.parametrize("dtype", [jnp.float64, jnp.float32])
def test_negative_controls_are_flagged(name, transform, dtype):
    entry = REGISTRY[name]
    result = check(entry, transform, dtype=dtype)
    tol = 1e-10 if dtype == jnp.float64 else 1e-5
    assert result.expect_fail and result.passed, result
    assert result.error > 100 * tol, result  # flagged by a wide margin, not by noise


def test_negative_controls_pass_where_they_should():
    """The broken operators are broken only in the way they are meant to be."""
    assert check(REGISTRY["negative.extrinsic_log"], "rigid").passed
    assert check(REGISTRY["negative.face_vertex_order"], "permute_faces").passed
    assert check(REGISTRY["negative.complex_bias"], "fold").passed


@settings(max_examples=10)
@given(data=st.data())
def test_transport_average_is_gauge_equivariant_for_any_gauge(data):
    v, f = icosphere(1)
    v = v * (1 + 0.1 * np.sin(3 * v[:, :1]))
    state = MeshState(v, f)
    alpha = data.draw(gauges(len(v)))
    x = data.draw(features("vertex_tangent", len(v), 3))
    fn = REGISTRY["geometry.one_ring.transport"].apply
    assert_equivariant(
        lambda s, x: fn(s, None, x), 0, {"x": x}, transforms=[gauge_change(state, alpha)]
    )


def test_convergence_measures_second_order_for_vertex_areas():
    entry = REGISTRY["geometry.vertex_area"]
    conv = convergence(
        lambda s: entry.apply(s, None),
        CATALOGUE["cylinder"],
        lambda s, rng: {},
        resolutions=(8, 16, 32, 64),
    )
    assert not conv.floor
    assert all(3.5 < r < 4.5 for r in conv.ratios), conv  # areas from chords: O(h²)
    assert conv.order == pytest.approx(2.0, abs=0.2)

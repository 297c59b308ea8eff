"""Lifting scalars to tangent features and reading invariants out: exact where they must be,
gauge-equivariant and intrinsic, finite at zero and in padded rows."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import InputError
from jmeshtex.data import grid
from jmeshtex.geometry import one_ring_neighborhood
from jmeshtex.ops import tangent_gradient, tangent_invariants
from jmeshtex.testing import EXACT, Field, assert_equivariant, pad_rows, pad_to_bucket


def _gradient(state, s):
    return Field("vertex_tangent", tangent_gradient(s, state.one_ring()))


def _invariants(state, x):
    return Field("vertex_scalar", tangent_invariants(x))


def test_the_gradient_of_a_linear_function_on_a_flat_irregular_sheet_is_exact():
    v, f = grid(6, 5, diagonals="alternate")
    v = v + 0.02 * np.random.default_rng(0).standard_normal(v.shape) * np.array([1, 1, 0])
    nb = one_ring_neighborhood(v, f, scale=None)  # mesh units: the slope per unit of x
    scalars = np.stack([3 * v[:, 0] - 2 * v[:, 1], v[:, 1]], axis=1)
    g = np.asarray(tangent_gradient(scalars, nb))
    # in each vertex's frame the gradient has the function's slope as its length
    np.testing.assert_allclose(np.abs(g[:, 0]), np.sqrt(13), rtol=1e-8)
    np.testing.assert_allclose(np.abs(g[:, 1]), 1.0, rtol=1e-8)
    # and the angle between the two gradients is the angle between (3, -2) and (0, 1)
    cos = np.real(g[:, 0] * np.conj(g[:, 1])) / (np.abs(g[:, 0]) * np.abs(g[:, 1]))
    np.testing.assert_allclose(cos, -2 / np.sqrt(13), atol=1e-8)


def test_the_gradient_is_gauge_equivariant_and_intrinsic():
    errors = assert_equivariant(
        _gradient, 0, {"s": ("vertex_scalar", 3)}, transforms=(*EXACT, "cylinder")
    )
    assert max(e for t, e in errors.items() if t != "cylinder") < 1e-10


def test_invariants_do_not_see_the_gauge_and_determine_the_features_up_to_it():
    errors = assert_equivariant(
        _invariants, 1, {"x": ("vertex_tangent", 4)}, transforms=("gauge", "permute_vertices")
    )
    assert max(errors.values()) < 1e-10
    x = np.array([[1 + 1j, 2 - 1j, 0.5j]])
    turned = x * np.exp(1.3j)
    np.testing.assert_allclose(tangent_invariants(turned), tangent_invariants(x), atol=1e-12)
    assert tangent_invariants(x).shape == (1, 3 + 3 * 2)
    # a reflection is not a rotation: it changes the sign of the relative phase
    assert not np.allclose(tangent_invariants(np.conj(x)), tangent_invariants(x))


def test_gradients_are_finite_at_zero_features_and_padded_rows_stay_zero():
    grads = jax.grad(lambda z: jnp.sum(tangent_invariants(z)))(jnp.zeros((3, 2), jnp.complex128))
    assert np.all(np.isfinite(np.asarray(grads)))
    v, f = grid(3, 3)
    nb = pad_to_bucket(one_ring_neighborhood(v, f))
    s = pad_rows(np.asarray(v[:, :2]), nb.index.shape[0])
    s[len(v) :] = 1e3  # garbage in padded rows
    g = np.asarray(tangent_gradient(s, nb))
    assert np.all(np.isfinite(g)) and not np.any(g[len(v) :])


@pytest.mark.unchecked  # ill-typed on purpose: the op's own errors, not jaxtyping's
def test_bad_inputs_are_typed_errors():
    v, f = grid(2, 2)
    nb = one_ring_neighborhood(v, f)
    with pytest.raises(InputError, match="must be real"):
        tangent_gradient(np.ones((len(v), 1), complex), nb)
    with pytest.raises(InputError, match="pad f to the neighbourhood"):
        tangent_gradient(np.ones((len(v) + 1, 1)), nb)
    with pytest.raises(InputError, match="complex tangent features"):
        tangent_invariants(np.ones((3, 2)))

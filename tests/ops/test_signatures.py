"""Signatures are checked at run time in the test suite (jaxtyping + beartype, pyproject's
``--jaxtyping-packages``): a wrong shape or a wrong pytree fails at the call, naming the argument.

Without the instrumentation these calls fail later, with other errors (the ops' own InputError, or an
AttributeError deep inside), so these tests also pin that the wiring is on.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import pytest
from jaxtyping import TypeCheckError

from jmeshtex.data import icosphere
from jmeshtex.geometry import one_ring_neighborhood
from jmeshtex.ops import complex_linear, field_conv, init_field_conv

MESH = icosphere(1)  # 42 vertices
NBHD = one_ring_neighborhood(*MESH)
PARAMS = init_field_conv(jax.random.key(0), 3, 5, hdim=4)


def test_a_wrong_shape_fails_naming_the_argument():
    x = jnp.zeros((42, 3, 1), jnp.complex64)  # [V, C, 1] where [V, C] is expected
    with pytest.raises(TypeCheckError, match=r"parameter 'x'"):
        field_conv(x, NBHD, PARAMS)


def test_inconsistent_sizes_across_arguments_name_the_argument():
    x = jnp.zeros((42, 3), jnp.complex64)
    w = jnp.zeros((4, 2), jnp.complex64)  # C = 4 rows, but x has C = 3 channels
    with pytest.raises(TypeCheckError, match=r"parameter 'w'"):
        complex_linear(x, w)


def test_a_mesh_where_a_neighbourhood_is_expected_names_the_argument():
    x = jnp.zeros((42, 3), jnp.complex64)
    with pytest.raises(TypeCheckError, match=r"parameter 'nbhd'"):
        field_conv(x, MESH, PARAMS)


def test_a_wrong_dtype_fails_naming_the_argument():
    x = jnp.zeros((42, 3), jnp.float32)  # real where complex tangent features are expected
    with pytest.raises(TypeCheckError, match=r"parameter 'x'"):
        field_conv(x, NBHD, PARAMS)

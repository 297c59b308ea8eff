"""Ops at their boundary: bad static arguments raise typed errors, and non-finite values in padded
slots reach neither outputs nor gradients."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import InputError, JmeshtexError, PoolingMap, ops
from jmeshtex.data import icosphere
from jmeshtex.geometry import to_jax, unique_edges

KEY = jax.random.key(0)

BAD_CALLS = {
    "complex_linear 0 inputs": (lambda: ops.init_complex_linear(KEY, 0, 3), "in_features"),
    "complex_linear negative": (lambda: ops.init_complex_linear(KEY, 2, -3), "out_features"),
    "complex_linear 1.5": (lambda: ops.init_complex_linear(KEY, 1.5, 3), "in_features"),
    "complex_linear int key": (lambda: ops.init_complex_linear(0, 2, 3), "PRNG key"),
    "vn 0 inputs": (lambda: ops.init_vn(KEY, 0), "in_features"),
    "vn negative": (lambda: ops.init_vn(KEY, -1, 2), "in_features"),
    "vn int key": (lambda: ops.init_vn(7, 3), "PRNG key"),
    "frn negative": (lambda: ops.init_frn(-1), "features"),
    "frn 0": (lambda: ops.init_frn(0), "features"),
    "frn eps nan": (lambda: ops.init_frn(3, eps=float("nan")), "eps"),
    "lecun fan_in 0": (lambda: ops.complex_lecun_normal(KEY, (2, 3), fan_in=0), "fan_in"),
    "lecun negative shape": (lambda: ops.complex_lecun_normal(KEY, (-2, 3), fan_in=2), "shape"),
    "lecun int key": (lambda: ops.complex_lecun_normal(1, (2, 3), fan_in=2), "PRNG key"),
    "face_conv int key": (lambda: ops.init_face_conv(0, 2, 3), "PRNG key"),
    "face_conv_stack int key": (lambda: ops.init_face_conv_stack(0, [4]), "PRNG key"),
    "tangent_noise int key": (lambda: ops.tangent_noise(0, (2, 2)), "PRNG key"),
    "field_conv hdim 0": (lambda: ops.init_field_conv(KEY, 2, 3, hdim=0), "fan_in"),
    "field_conv negative": (lambda: ops.init_field_conv(KEY, -1, 3), "shape"),
    "to_jax int32": (lambda: to_jax({"w": np.ones(3)}, jnp.int32), "real floating dtype"),
    "unique_edges count too small": (
        lambda: unique_edges(icosphere(1).faces, num_vertices=3),
        "num_vertices=3",
    ),
}


@pytest.mark.unchecked  # ill-typed on purpose: the functions' own typed errors are under test
@pytest.mark.parametrize("name", sorted(BAD_CALLS))
def test_bad_static_arguments_raise_a_typed_error_naming_them(name):
    call, words = BAD_CALLS[name]
    with pytest.raises(InputError, match=words) as info:
        call()
    assert isinstance(info.value, JmeshtexError)


def test_the_checks_accept_what_they_should():
    ops.init_complex_linear(jax.random.PRNGKey(0), 2, 3)  # a legacy raw key
    ops.init_vn(KEY, 3)
    assert len(unique_edges(icosphere(1).faces, num_vertices=42)) == 120
    assert to_jax({"w": np.ones(3)}, jnp.float64)["w"].dtype == jnp.float64
    # under jit and vmap the key is a tracer: the check is static, no host round trip
    w = jax.jit(lambda k: ops.init_complex_linear(k, 2, 3))(KEY)
    assert w.shape == (2, 3)
    assert jax.vmap(lambda k: ops.tangent_noise(k, (4,)))(jax.random.split(KEY, 2)).shape == (2, 4)


# ------------------------------------------------------------------- NaN in padded slots


@pytest.fixture
def no_debug_nans():
    """The inputs hold NaN on purpose (in padded slots); the outputs are checked instead."""
    with jax.debug_nans(False):
        yield


def _finite(tree) -> bool:
    return all(bool(jnp.isfinite(leaf).all()) for leaf in jax.tree.leaves(tree))


def test_masked_mean_ignores_non_finite_padded_rows_in_value_and_gradient(no_debug_nans):
    x = jnp.array([[1.0, 2.0], [3.0, 4.0], [jnp.nan, jnp.inf]])
    mask = jnp.array([True, True, False])
    out = ops.masked_mean(x, mask)
    grad = jax.grad(lambda x: ops.masked_mean(x, mask).sum())(x)
    assert out.tolist() == [2.0, 3.0]
    assert _finite(grad) and grad[2].tolist() == [0.0, 0.0] and grad[0].tolist() == [0.5, 0.5]


def test_gram_matrix_ignores_non_finite_padded_rows_in_value_and_gradient(no_debug_nans):
    x = jnp.array([[1.0, 2.0], [3.0, 4.0], [jnp.nan, -jnp.inf]])
    mask = jnp.array([True, True, False])
    g = ops.gram_matrix(x, mask)
    grad = jax.grad(lambda x: ops.gram_matrix(x, mask).sum())(x)
    assert g.tolist() == [[5.0, 7.0], [7.0, 10.0]]
    assert _finite(grad) and grad[2].tolist() == [0.0, 0.0]


def test_tangent_pool_ignores_non_finite_padded_slots_in_value_and_gradient(no_debug_nans):
    base = PoolingMap(
        parent=np.array([0, 0, 0]),
        to_parent=np.array([1, 1j, 1]),
        children=np.array([[0, 1, 2]]),
        children_mask=np.array([[True, True, False]]),
        children_weight=np.array([[1.0, 3.0, np.nan]]),
        children_transport=np.array([[1, 1j, np.nan]]),
    )
    x = jnp.array([[2 + 0j], [-1j], [complex(np.nan, np.inf)]])  # vertex 2: a padded row
    out = ops.tangent_pool(x, base)
    grad = jax.grad(lambda x: jnp.abs(ops.tangent_pool(x, base)).sum())(x)
    np.testing.assert_allclose(np.asarray(out), [[1.25 + 0j]], atol=1e-6)  # (1·2 + 3·1) / 4
    assert _finite(grad) and complex(grad[2, 0]) == 0
    # the same map without the padded column gives the same output
    trimmed = base._replace(
        **{
            k: getattr(base, k)[:, :2]
            for k in ("children", "children_mask", "children_weight", "children_transport")
        }
    )
    np.testing.assert_allclose(
        np.asarray(
            ops.tangent_pool(
                x[:2], trimmed._replace(parent=base.parent[:2], to_parent=base.to_parent[:2])
            )
        ),
        np.asarray(out),
        atol=1e-6,
    )

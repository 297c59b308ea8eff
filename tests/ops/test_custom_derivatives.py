"""Every op with a custom derivative composes with every JAX transformation in any order:
``elementwise_max`` (custom_jvp) and the fused filter-sum stage (custom_jvp); ``field_conv`` has
its own tests in ``test_field_conv_forward.py``."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jmeshtex.ops import FieldConvParams, FieldConvTerms, elementwise_max, field_conv_filter_sums


def _max_fn(x):  # ties broken away: the three inputs differ everywhere
    return elementwise_max((x, 0.5 * x[::-1] + 0.1, jnp.sin(x)))


def _sums_fn(x):
    v, k, c, h = 3, 2, 2, 3
    terms = FieldConvTerms(
        *(x[i * v * k * c : (i + 1) * v * k * c].reshape(v, k, c) for i in range(4))
    )
    params = FieldConvParams(
        filter_weight=jnp.cos(jnp.arange(2.0 * h)).reshape(2, h),
        filter_bias=jnp.linspace(-0.5, 0.5, h),
        mix=jnp.ones((c, h, 1), jnp.complex128),
    )
    s_r, s_i = field_conv_filter_sums(terms, params)
    return jnp.concatenate([s_r.ravel(), s_i.ravel()])


CASES = {
    "elementwise_max": (_max_fn, np.array([-1.3, -0.7, -0.2, 0.35, 0.8, 1.1, 1.9])),
    "field_conv_filter_sums": (_sums_fn, np.sin(np.arange(48.0) * 0.7)),
}


@pytest.mark.parametrize("name", list(CASES))
def test_every_transformation_in_any_order(name):
    fn, x0 = CASES[name]
    x = jnp.asarray(x0)
    t = jnp.cos(jnp.arange(x.size, dtype=x.dtype) * 1.3)
    check_grads(fn, (x,), order=2, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6)
    jac = jax.jacrev(fn)(x)
    want = jac @ t
    for label, value in {
        "jvp": jax.jvp(fn, (x,), (t,))[1],
        "linearize": jax.linearize(fn, x)[1](t),
        "jvp(jit)": jax.jvp(jax.jit(fn), (x,), (t,))[1],
        "jit(jvp)": jax.jit(lambda a, b: jax.jvp(fn, (a,), (b,))[1])(x, t),
        "jacfwd": jax.jacfwd(fn)(x) @ t,
    }.items():
        np.testing.assert_allclose(value, want, rtol=1e-10, atol=1e-12, err_msg=label)
    scalar = lambda a: jnp.sum(fn(a) ** 2)  # noqa: E731
    hess = jax.hessian(scalar)(x)
    np.testing.assert_allclose(jax.jacrev(jax.jacrev(scalar))(x), hess, rtol=1e-9, atol=1e-11)
    batch = jnp.stack([x, 0.5 * x + 0.2])
    for label, f in {"jvp": lambda a: jax.jvp(fn, (a,), (t,))[1], "jacrev": jax.jacrev(fn),
                     "hessian": jax.hessian(scalar)}.items():  # fmt: skip
        got = jax.vmap(f)(batch)
        for i in range(2):
            np.testing.assert_allclose(got[i], f(batch[i]), rtol=1e-10, atol=1e-12, err_msg=label)
    assert np.abs(np.asarray(jac)).max() > 0

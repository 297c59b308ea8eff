"""Gram matrices: loop reference, padding invariance, batching, dtypes, gradients."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jmeshtex import InputError
from jmeshtex.ops import gram_matrix

_gram = jax.jit(gram_matrix)


def _gram_ref(x, mask):
    C = x.shape[1]
    g = np.zeros((C, C))
    n = 0
    for row, m in zip(x, mask, strict=True):
        if m:
            g += np.outer(row, row)
            n += 1
    return g / max(n, 1)


def test_exact_and_loop_reference(rng):
    x = jnp.array([[1.0, 0.0], [0.0, 2.0], [1.0, 1.0]])
    np.testing.assert_allclose(
        _gram(x, jnp.ones(3, bool)), [[2 / 3, 1 / 3], [1 / 3, 5 / 3]], rtol=1e-15
    )
    y = rng.standard_normal((17, 5))
    mask = rng.random(17) < 0.6
    g = np.asarray(_gram(jnp.asarray(y), jnp.asarray(mask)))
    np.testing.assert_allclose(g, _gram_ref(y, mask), rtol=1e-12)
    # GEMM blocking may differ in the last bit; an entry near 0 carries the rounding of the large
    # products summed into it, so the bound is relative to the largest entry (seed 78 needs it)
    np.testing.assert_allclose(g, g.T, rtol=1e-14, atol=1e-14 * np.abs(g).max())
    assert np.linalg.eigvalsh(g).min() > -1e-12
    np.testing.assert_allclose(gram_matrix(jnp.asarray(y)), _gram_ref(y, np.ones(17)), rtol=1e-12)


def test_padding_invariance_and_empty_mask(rng):
    y = rng.standard_normal((10, 4))
    ref = _gram(jnp.asarray(y), jnp.ones(10, bool))
    padded = np.concatenate([y, 1e6 * rng.standard_normal((6, 4))])
    np.testing.assert_allclose(_gram(jnp.asarray(padded), jnp.arange(16) < 10), ref, rtol=1e-12)
    np.testing.assert_array_equal(_gram(jnp.asarray(padded), jnp.zeros(16, bool)), 0)


def test_jit_vmap_and_single_compilation(rng):
    traces = []

    def fn(x, m):
        traces.append(1)
        return gram_matrix(x, m)

    jitted = jax.jit(fn)
    xs = [rng.standard_normal((6, 3)), rng.standard_normal((9, 3))]
    X = jnp.stack([jnp.pad(jnp.asarray(x), ((0, 9 - len(x)), (0, 0))) for x in xs])
    M = jnp.stack([jnp.arange(9) < len(x) for x in xs])
    eager = fn(X[0], M[0])
    # compiled and eager sums may associate differently: an absolute part at the matrix's scale
    # keeps near-cancelling entries (|g_ij| ~ 1e-17) from failing a purely relative bound
    scale = float(jnp.abs(eager).max())
    np.testing.assert_allclose(jitted(X[0], M[0]), eager, rtol=1e-14, atol=1e-14 * scale)
    jitted(X[1], M[1])
    assert len(traces) == 2  # eager once, compiled once
    out = jax.jit(jax.vmap(gram_matrix))(X, M)
    for b, x in enumerate(xs):
        np.testing.assert_allclose(out[b], _gram_ref(x, np.ones(len(x))), rtol=1e-12)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_dtype_and_gradients(dtype, rng):
    x = jnp.asarray(rng.standard_normal((7, 3)), dtype)
    mask = jnp.arange(7) < 5
    assert _gram(x, mask).dtype == dtype
    if dtype == jnp.float64:
        check_grads(lambda x: _gram(x, mask), (x,), order=1, modes=["fwd", "rev"])
    g = jax.jit(jax.grad(lambda x: jnp.sum(gram_matrix(x, mask) ** 2)))(jnp.zeros((7, 3), dtype))
    assert np.isfinite(np.asarray(g)).all() and g.dtype == dtype


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_bad_input_raises_typed_errors():
    with pytest.raises(InputError, match=r"\[N, C\]"):
        gram_matrix(jnp.ones(3))
    with pytest.raises(InputError, match="mask"):
        gram_matrix(jnp.ones((3, 2)), jnp.ones(4, bool))

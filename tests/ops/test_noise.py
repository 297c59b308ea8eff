"""Tangent noise: dtype, determinism, moments of the variance convention, gauge invariance."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from jmeshtex import InputError
from jmeshtex.ops import tangent_noise

N = 200_000  # samples for the statistical checks; 5-sigma bounds below are ~5 / sqrt(N) ≈ 0.011
_noise = jax.jit(tangent_noise, static_argnums=(1,), static_argnames=("dtype",))


@pytest.mark.parametrize("dtype", [jnp.complex64, jnp.complex128])
def test_shape_dtype_and_determinism(dtype):
    a = _noise(jax.random.key(3), (7, 5), dtype=dtype)
    assert a.shape == (7, 5) and a.dtype == dtype
    np.testing.assert_array_equal(
        np.asarray(a), np.asarray(_noise(jax.random.key(3), (7, 5), dtype=dtype))
    )
    assert not np.allclose(
        np.asarray(a), np.asarray(_noise(jax.random.key(4), (7, 5), dtype=dtype))
    )


def test_variance_convention():
    # ε = (a + ib)/√2: E ε = 0, E|ε|² = 1, Var Re = Var Im = 1/2, Cov(Re, Im) = 0, E ε² = 0
    e = np.asarray(_noise(jax.random.key(0), (N // 4, 4), dtype=jnp.complex128)).ravel()
    bound = 5 / np.sqrt(N)
    assert abs(e.mean()) < bound
    assert abs(np.mean(np.abs(e) ** 2) - 1) < 2 * bound  # Var |ε|² = 1
    assert abs(e.real.var() - 0.5) < bound and abs(e.imag.var() - 0.5) < bound
    assert abs(np.mean(e.real * e.imag)) < bound
    assert abs(np.mean(e**2)) < 2 * bound
    assert stats.kstest(np.sqrt(2) * e.real, "norm").pvalue > 1e-4


def test_distribution_is_gauge_invariant():
    # rotating each vertex's noise by an arbitrary frame angle gives the same distribution: the real
    # part of ε e^{iα} is still N(0, 1/2), the phase uniform and independent of α
    e = np.asarray(_noise(jax.random.key(1), (N, 1), dtype=jnp.complex128))[:, 0]
    alpha = np.random.default_rng(0).uniform(-np.pi, np.pi, N)
    alpha[: N // 2] = 0.3  # half with a fixed large rotation
    r = e * np.exp(1j * alpha)
    assert stats.kstest(np.sqrt(2) * r.real, "norm").pvalue > 1e-4
    assert stats.kstest(np.angle(r), "uniform", args=(-np.pi, 2 * np.pi)).pvalue > 1e-4
    assert stats.ks_2samp(r.real[: N // 2], e.real[N // 2 :]).pvalue > 1e-4


def test_bad_dtype_raises():
    with pytest.raises(InputError, match="complex"):
        tangent_noise(jax.random.key(0), (3, 2), dtype=jnp.float32)
    with pytest.raises(InputError, match="non-negative"):
        tangent_noise(jax.random.key(0), (3, -2))

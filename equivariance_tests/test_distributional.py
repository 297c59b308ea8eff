"""Distributional equivariance: tangent noise (eq. 1) has the same law in every gauge.

A gauge change maps ε_p to ε_p e^{-iα_p}. Circular complex Gaussian noise is invariant in law: the
test compares moments and the angle distribution of ``tangent_noise`` samples with those of the
rotated samples, with bounds set by the sampling error (5 standard errors), and checks that a
non-circular noise (real part only) fails the same test.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from jmeshtex import ops

N = 200_000


def _law_check(eps: np.ndarray, alpha: np.ndarray) -> tuple[float, float, float]:
    """Return (|E ε² − E (εe^{-iα})²| / se, max |Δ E|ε|²| / se, KS p-value of the rotated angles)."""
    rot = eps * np.exp(-1j * alpha)
    se = 1.0 / np.sqrt(eps.size)
    pseudo = abs(np.mean(eps**2) - np.mean(rot**2)) / se
    power = abs(np.mean(np.abs(eps) ** 2) - np.mean(np.abs(rot) ** 2)) / se
    ks = stats.kstest((np.angle(rot).ravel() + np.pi) / (2 * np.pi), "uniform").pvalue
    return pseudo, power, ks


@pytest.mark.parametrize("dtype", [jnp.complex64, jnp.complex128])
def test_tangent_noise_is_gauge_invariant_in_law(key, dtype):
    eps = np.asarray(ops.tangent_noise(key, (N // 4, 4), dtype=dtype))
    assert eps.dtype == np.dtype(dtype)
    alpha = np.random.default_rng(0).uniform(-np.pi, np.pi, (N // 4, 1))
    pseudo, power, ks = _law_check(eps.astype(np.complex128), alpha)
    assert abs(np.mean(np.abs(eps) ** 2) - 1.0) < 5 * 2 / np.sqrt(eps.size)  # E|ε|² = 1
    assert pseudo < 5 and power < 5 and ks > 1e-4


def test_non_circular_noise_is_flagged(key):
    real_only = np.asarray(jax.random.normal(key, (N,))).astype(np.complex128)
    alpha = np.random.default_rng(0).uniform(-np.pi, np.pi, N)
    pseudo, _, ks = _law_check(real_only, alpha)
    assert pseudo > 5 or ks < 1e-4

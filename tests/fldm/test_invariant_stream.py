"""The denoiser's invariant stream (``Config.experimental.invariants``): its input features and old runs' resume."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jmeshtex import fldm
from jmeshtex.fldm.core import magnitude_context
from jmeshtex.geometry import VertexNeighborhood


def test_magnitude_context_is_normalised_power_and_its_neighbourhood_mean():
    # a path 0 - 1 - 2 plus a padding vertex 3; slot 0 is the vertex itself
    index = np.array([[0, 1, 0], [1, 0, 2], [2, 1, 0], [0, 0, 0]])
    mask = np.array([[1, 1, 0], [1, 1, 1], [1, 1, 0], [0, 0, 0]], bool)
    nb = VertexNeighborhood(
        index,
        mask,
        np.zeros((4, 3), complex),
        np.ones((4, 3), complex),
        mask.astype(float),
        np.ones(4),
        np.array([True, True, True, False]),
    )
    x = jnp.array([[1.0], [2j], [-3.0], [100.0]], jnp.complex128)  # the padding vertex is ignored
    power = np.array([1.0, 4.0, 9.0])
    s = np.log1p(power / power.mean())
    expected_around = np.array([(s[0] + s[1]) / 2, s.mean(), (s[2] + s[1]) / 2])
    out = np.asarray(magnitude_context(x, nb))
    np.testing.assert_allclose(out[:3, 0], s, rtol=1e-12)
    np.testing.assert_allclose(out[:3, 1], expected_around, rtol=1e-12)
    np.testing.assert_array_equal(out[3], 0.0)
    # gauge-invariant: turning each vertex's vector by its own angle changes nothing
    turned = x * jnp.asarray(np.exp(1j * np.array([[0.3], [2.0], [-1.1], [0.5]])))
    np.testing.assert_allclose(magnitude_context(turned, nb), out, rtol=1e-12, atol=1e-15)


def test_runs_with_and_without_the_option_do_not_mix():
    from jmeshtex.fldm._train import _fingerprint

    cfg = fldm.Config.tiny(latent_channels=2)

    class _Data:
        latents = np.zeros((2, 8, 2), np.complex64)
        scale = np.ones(2)

    off = _fingerprint(_Data, cfg, jax.random.key(0), jnp.complex64)
    on = _fingerprint(_Data, cfg.replace(invariants=True), jax.random.key(0), jnp.complex64)
    assert off["config"] == cfg.fingerprint()  # the one rule: every field but the resumable ones
    assert off["config"]["invariants"] is False
    assert on["config"]["invariants"] is True and on != off

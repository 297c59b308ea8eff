"""The decoder: gauge-invariant features, log and barycentric variants, blending at vertices."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jmeshtex.fl import init
from jmeshtex.fl.core import (
    decode_barycentric,
    decode_points,
    decode_vertex_colors_from_latents,
    decoder_features,
)
from tests._presets import FL_SMALL

LOG = FL_SMALL
BARY = LOG.replace(decoder="barycentric")


def _latents(rng, n, d=3):
    return jnp.asarray(rng.standard_normal((n, d)) + 1j * rng.standard_normal((n, d)))


def test_features_are_the_hermitian_invariants_and_positional_terms(rng):
    mu = _latents(rng, 1)[0]
    log = jnp.asarray(0.3 - 0.2j)
    f = np.asarray(decoder_features(LOG, mu, log))
    m = np.asarray(mu)
    expected_abs = np.abs(m) ** 2
    rows, cols = np.triu_indices(3, 1)
    outer = m[rows] * np.conj(m[cols])
    pos = complex(log) * np.conj(m)
    np.testing.assert_allclose(
        f, np.concatenate([expected_abs, outer.real, outer.imag, pos.real, pos.imag]), atol=1e-14
    )
    assert decoder_features(BARY, mu, None).shape == (9,)


def test_decoded_colours_are_invariant_to_a_gauge_change(key, rng):
    params = init(LOG, key=key, dtype=jnp.float64).params
    mu = _latents(rng, 6)
    log = _latents(rng, 6, 10)
    turn = jnp.asarray(np.exp(1j * rng.uniform(0, 2 * np.pi, 6)))[:, None]
    dec = jax.jit(decode_points, static_argnums=1)
    a = dec(params, LOG, mu, log)
    np.testing.assert_allclose(dec(params, LOG, mu * turn, log * turn), a, atol=1e-12)
    assert a.shape == (6, 10, 3) and a.dtype == jnp.float64
    # the positional features matter: turning only the points changes the colours
    assert not np.allclose(dec(params, LOG, mu, log * 1j), a)


def test_blending_at_a_corner_is_that_vertex_prediction(key, rng):
    params = init(LOG, key=key, dtype=jnp.float64).params
    mu = _latents(rng, 3)
    corners = jnp.asarray([[0, 1, 2]])
    logs = jnp.asarray([[0.0, 0.4 + 0.1j, -0.2 + 0.5j]])
    out = decode_barycentric(params, LOG, mu, corners, jnp.asarray([[1.0, 0.0, 0.0]]), logs)
    np.testing.assert_allclose(
        out[0], decode_vertex_colors_from_latents(params, LOG, mu)[0], atol=1e-12
    )
    # a mid-edge point is the mean of the two end predictions at their own log coordinates
    mid = decode_barycentric(params, LOG, mu, corners, jnp.asarray([[0.5, 0.5, 0.0]]), logs)
    p0 = decode_points(params, LOG, mu[:1], logs[:, :1])[0, 0]
    p1 = decode_points(params, LOG, mu[1:2], logs[:, 1:2])[0, 0]
    np.testing.assert_allclose(mid[0], 0.5 * (p0 + p1), atol=1e-12)


def test_barycentric_ablation_interpolates_invariants_not_colours(key, rng):
    params = init(BARY, key=key, dtype=jnp.float64).params
    mu = _latents(rng, 3)
    corners = jnp.asarray([[0, 1, 2]])
    at_vertex = decode_barycentric(params, BARY, mu, corners, jnp.asarray([[0.0, 1.0, 0.0]]))
    np.testing.assert_allclose(
        at_vertex[0], decode_vertex_colors_from_latents(params, BARY, mu)[1], atol=1e-12
    )
    mid = decode_barycentric(params, BARY, mu, corners, jnp.asarray([[0.5, 0.5, 0.0]]))
    inv = 0.5 * (decoder_features(BARY, mu[0], None) + decoder_features(BARY, mu[1], None))
    from jmeshtex.fl._decoder import apply_decoder

    np.testing.assert_allclose(mid[0], apply_decoder(params.decoder, inv), atol=1e-12)
    # the ablation ignores log coordinates in decode_points
    log = _latents(rng, 3, 4)
    np.testing.assert_allclose(
        decode_points(params, BARY, mu, log), decode_points(params, BARY, mu, log * 1j)
    )

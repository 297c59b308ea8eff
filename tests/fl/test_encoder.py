"""One-ring sampling (host) and the encoder (pure): log maps, equivariance, padding, set invariance."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex.data import grid, icosphere
from jmeshtex.fl import init
from jmeshtex.fl._encoder import corner_logs, ring_geometry
from jmeshtex.fl.core import encode_samples, one_ring_samples
from jmeshtex.geometry import one_ring_neighborhood
from tests._presets import FL_SMALL as SMALL

#: jitted once per test session (op-by-op dispatch under jax_debug_nans is ~50x slower)
encode = jax.jit(encode_samples, static_argnums=1)


def test_corner_logs_reproduce_the_one_ring_log_map_at_ring_vertices():
    v, f = icosphere(2)
    v = v * (1 + 0.1 * np.sin(3 * v[:, :1]))  # irregular
    nb = one_ring_neighborhood(v, f, scale=None)  # mesh units, as the encoder's radii
    g = ring_geometry(v, f)
    p, j = np.nonzero(g.wedge_mask)
    face = g.wedge_faces[p, j]
    corner = np.argmax(f[face] == p[:, None], axis=1)
    for k, slot in ((1, j), (2, (j + 1) % nb.mask.sum(1)[p])):
        bary = np.zeros((len(p), 3))
        bary[np.arange(len(p)), (corner + k) % 3] = 1.0
        log = corner_logs(g, face, corner, bary) * g.radius[p]
        np.testing.assert_allclose(log, nb.log[p, slot], atol=1e-12)


def test_on_a_flat_grid_the_log_map_is_the_euclidean_offset_in_the_frame(rng):
    v, f = grid(4)
    s = one_ring_samples(v, f, 32, rng=rng)
    nb = one_ring_neighborhood(v, f)
    g = ring_geometry(v, f)
    p = 12  # interior vertex of the 5×5 grid
    points = np.einsum("sk,skd->sd", s.bary[p], v[f[s.face[p]]])
    offset = (points[:, 0] - v[p, 0]) + 1j * (points[:, 1] - v[p, 1])
    ref = v[nb.index[p, 0]] - v[p]
    frame = (ref[0] + 1j * ref[1]) / abs(ref[0] + 1j * ref[1])
    np.testing.assert_allclose(s.log[p] * g.radius[p], offset / frame, atol=1e-12)


def test_samples_are_area_uniform_over_the_one_ring():
    v, f = grid(2)
    v = v.copy()
    v[4, :2] = [0.3, 0.4]  # move the centre: wedges of different areas
    s = one_ring_samples(v, f, 40000, rng=np.random.default_rng(0))
    p = 4
    e = v[f][:, 1:, :2] - v[f][:, :1, :2]
    area = 0.5 * np.abs(e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
    ring_faces = np.nonzero((f == p).any(1))[0]
    freq = np.array([(s.face[p] == k).mean() for k in ring_faces])
    np.testing.assert_allclose(freq, area[ring_faces] / area[ring_faces].sum(), atol=0.01)
    assert s.mask.all() and np.allclose(s.bary.sum(-1), 1.0)


def test_deterministic_rule_has_six_points_per_wedge():
    v, f = icosphere(1)
    s = one_ring_samples(v, f, 1, rng=None)
    degree = one_ring_neighborhood(v, f).mask.sum(1)
    assert s.log.shape[1] == 6 * degree.max()
    np.testing.assert_array_equal(s.mask.sum(1), 6 * degree)


def _inputs(rng, V=5, S=12):
    log = (rng.standard_normal((V, S)) + 1j * rng.standard_normal((V, S))) * 0.5
    return (
        jnp.asarray(log),
        jnp.asarray(rng.random((V, S, 3))),
        jnp.asarray(rng.random((V, S)) > 0.2),
    )


def test_mu_turns_with_the_gauge_and_sigma_is_invariant(key, rng):
    params = init(SMALL, key=key, dtype=jnp.float64).params
    log, rgb, mask = _inputs(rng)
    turn = jnp.asarray(np.exp(-1j * rng.uniform(0, 2 * np.pi, log.shape[0])))
    a = encode(params, SMALL, log, rgb, mask)
    b = encode(params, SMALL, log * turn[:, None], rgb, mask)
    np.testing.assert_allclose(b.mu, a.mu * turn[:, None], atol=1e-12)
    np.testing.assert_allclose(b.log_sigma, a.log_sigma, atol=1e-12)
    assert a.mu.dtype == jnp.complex128 and a.log_sigma.dtype == jnp.float64


@pytest.mark.parametrize("token", ["centre", "ring_mean"])
def test_samples_form_a_set_and_padding_changes_nothing(key, rng, token):
    config = SMALL.replace(token=token)
    params = init(config, key=key, dtype=jnp.float64).params
    log, rgb, mask = _inputs(rng)
    a = encode(params, config, log, rgb, mask)
    # with the centre token, column 0 is the centre and the set is the columns after it
    first = 1 if token == "centre" else 0
    perm = np.concatenate([np.arange(first), first + rng.permutation(log.shape[1] - first)])
    b = encode(params, config, log[:, perm], rgb[:, perm], mask[:, perm])
    np.testing.assert_allclose(b.mu, a.mu, atol=1e-12)

    def pad(x, val):
        return jnp.concatenate([x, jnp.full((x.shape[0], 4, *x.shape[2:]), val, x.dtype)], 1)

    c = encode(params, config, pad(log, 3 + 1j), pad(rgb, 0.9), pad(mask, False))
    np.testing.assert_allclose(c.mu, a.mu, atol=1e-12)
    np.testing.assert_allclose(c.log_sigma, a.log_sigma, atol=1e-12)
    # the colours matter: changing a valid sample changes the latent
    d = encode(params, config, log, rgb.at[0, jnp.argmax(mask[0])].set(0.0), mask)
    assert not np.allclose(d.mu[0], a.mu[0])


def test_jit_compiles_once_and_gradients_are_finite_at_zero(key):
    params = init(SMALL, key=key, dtype=jnp.float32).params
    f = jax.jit(lambda p, log, rgb, m: encode_samples(p, SMALL, log, rgb, m).mu)
    log = jnp.zeros((4, 6), jnp.complex64)
    rgb = jnp.zeros((4, 6, 3), jnp.float32)
    m = jnp.ones((4, 6), bool)
    f(params, log, rgb, m)
    f(params, log + 1, rgb, m)
    assert f._cache_size() == 1

    def energy(lg):
        mu = encode(params, SMALL, lg, rgb, m).mu
        return jnp.sum(mu.real * mu.real + mu.imag * mu.imag)

    g = jax.jit(jax.grad(energy))(log)
    assert np.isfinite(np.asarray(g)).all()


def test_bad_shapes_are_typed_errors(key):
    from jmeshtex import InputError

    params = init(SMALL, key=key).params
    with pytest.raises(InputError, match="log_q must be a complex"):
        encode(params, SMALL, jnp.zeros((2, 3)), jnp.zeros((2, 3, 3)), jnp.ones((2, 3), bool))
    with pytest.raises(InputError, match="rgb must have shape"):
        encode(
            params,
            SMALL,
            jnp.zeros((2, 3), jnp.complex64),
            jnp.zeros((2, 3)),
            jnp.ones((2, 3), bool),
        )
    with pytest.raises(InputError, match="num_samples"):
        one_ring_samples(*grid(1), 0, rng=np.random.default_rng(0))

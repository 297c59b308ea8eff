"""Decoder-free latent statistics: they separate a structured field from its shuffled and
random-phase versions, ignore padding and the per-vertex gauge, and agree with their definitions."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import InputError
from jmeshtex.data import icosphere
from jmeshtex.fldm import _statistics as st
from jmeshtex.fldm.core import denoiser_geometry


@pytest.fixture(scope="module")
def sphere():
    mesh = icosphere(3)  # 642 vertices
    return mesh, denoiser_geometry(mesh, knn=7).fine


def structured(mesh, seed=0):
    """Smooth, spatially varying magnitudes, fixed relative phases between channels, and a random
    common phase per vertex (the gauge / sampling noise the statistics must ignore)."""
    x = np.asarray(mesh.vertices)
    rng = np.random.default_rng(seed)
    mag = np.stack([1.5 + np.sin(3 * x[:, 0]), 1.5 + np.cos(2 * x[:, 1]), 1.2 + x[:, 2]], 1)
    rel = np.exp(1j * np.array([0.0, 1.0, 2.5]))
    common = np.exp(1j * rng.uniform(0, 2 * np.pi, (len(x), 1)))
    return jnp.asarray(mag * rel * common, jnp.complex64)


def gradient_field(mesh, nb, axis):
    """The tangent gradient of the coordinate ``x[axis]`` in every vertex's own frame (least squares
    over its neighbours' log maps): a smooth tangent field."""
    f = np.asarray(mesh.vertices)[:, axis]
    log = np.asarray(nb.log)
    out = np.zeros(len(f), complex)
    for p in range(len(f)):
        k = np.asarray(nb.mask[p]) & (np.asarray(nb.index[p]) != p)
        A = np.stack([log[p, k].real, log[p, k].imag], 1)
        g = np.linalg.lstsq(A, f[nb.index[p, k]] - f[p], rcond=None)[0]
        out[p] = g[0] + 1j * g[1]
    return out


def test_structured_field_against_its_baselines(sphere):
    mesh, nb = sphere
    z = structured(mesh)
    shuffled = st.shuffle_latents(z, key=jax.random.key(1))
    phased = st.random_channel_phases(z, key=jax.random.key(2))
    R = float(st.relative_phase_concentration(z))
    E = float(st.neighbour_energy_correlation(z, nb))
    assert R > 0.999 and E > 0.8
    # shuffling keeps the pointwise statistic and kills the spatial one
    assert abs(float(st.relative_phase_concentration(shuffled)) - R) < 1e-5
    assert abs(float(st.neighbour_energy_correlation(shuffled, nb))) < 0.08
    # a random phase per latent keeps the magnitudes (spatial statistic) and kills R
    assert float(st.relative_phase_concentration(phased)) < 0.15
    assert abs(float(st.neighbour_energy_correlation(phased, nb)) - E) < 1e-5


def test_gauge_invariance_and_pointwise_mean(sphere):
    mesh, nb = sphere
    z = structured(mesh)
    turn = np.exp(1j * np.random.default_rng(3).uniform(0, 2 * np.pi, (z.shape[0], 1)))
    z2 = z * jnp.asarray(turn, z.dtype)
    for f in (st.relative_phase_concentration, lambda a: st.neighbour_energy_correlation(a, nb)):
        assert abs(float(f(z2)) - float(f(z))) < 1e-5
    phased = st.random_channel_phases(z, key=jax.random.key(4))
    r = st.pointwise_concentration(phased)
    assert r.shape == (z.shape[0],)
    assert abs(float(r.mean()) - float(st.relative_phase_concentration(phased))) < 1e-5
    # against the structured field's own mean phasors, a random-phase field scores about 0
    ref = st.pair_mean_phasors(z)
    assert abs(float(st.pointwise_concentration(phased, reference=ref).mean())) < 0.1
    assert float(st.pointwise_concentration(z, reference=ref).mean()) > 0.999


def test_padding_is_ignored(sphere):
    mesh, nb = sphere
    z = structured(mesh)
    V, pad = z.shape[0], 40
    zp = jnp.concatenate([z, 50.0 * jnp.ones((pad, 3), z.dtype)])
    vm = jnp.arange(V + pad) < V
    nbp = nb._replace(
        index=np.pad(nb.index, ((0, pad), (0, 0))),
        mask=np.pad(nb.mask, ((0, pad), (0, 0))),
        transport=np.pad(nb.transport, ((0, pad), (0, 0)), constant_values=1),
        vertex_mask=np.asarray(vm),
    )
    a, b = st.latent_statistics(z, nb), st.latent_statistics(zp, nbp)
    for k in ("concentration", "energy_correlation", "phase_coherence", "rms"):
        assert abs(a[k] - b[k]) < 1e-5, k


def test_transported_coherence_and_energy_field_correlation(sphere):
    mesh, nb = sphere
    smooth = jnp.asarray(np.stack([gradient_field(mesh, nb, 0), gradient_field(mesh, nb, 1)], 1))
    noisy = st.random_channel_phases(smooth, key=jax.random.key(5))
    assert float(st.transported_phase_coherence(smooth, nb)) > 0.5
    assert abs(float(st.transported_phase_coherence(noisy, nb))) < 0.1
    z = structured(mesh)
    assert abs(float(st.energy_field_correlation(z, z)) - 1.0) < 1e-5
    sh = st.shuffle_latents(z, key=jax.random.key(6))
    assert abs(float(st.energy_field_correlation(z, sh))) < 0.15


def test_region_statistics():
    z = jnp.asarray(np.array([[1, 1], [1, 1], [1, -1], [1, 1j], [2, 2]], np.complex64))
    s = st.region_statistics(z, np.array([0, 0, 1, 1, 2]), 4)
    assert s["count"].tolist() == [2, 2, 1, 0]
    assert s["concentration"][0] == pytest.approx(1.0)
    assert s["concentration"][1] == pytest.approx(abs(-1 + -1j) / 2, abs=1e-6)
    assert np.isnan(s["concentration"][3])
    np.testing.assert_allclose(s["power"][2], [4.0, 4.0], rtol=1e-6)


def test_bad_input_raises(sphere):
    mesh, nb = sphere
    with pytest.raises(InputError, match="complex latents"):
        st.relative_phase_concentration(jnp.ones((4, 2)))
    with pytest.raises(InputError, match="d >= 2"):
        st.relative_phase_concentration(jnp.ones((4, 1), complex))
    with pytest.raises(InputError, match="neighborhood has"):
        st.neighbour_energy_correlation(jnp.ones((5, 2), complex), nb)
    with pytest.raises(InputError, match="regions must be"):
        st.region_statistics(jnp.ones((4, 2), complex), np.zeros(3, int), 2)

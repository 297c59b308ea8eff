"""FLDM denoiser: gauge agreement with the FL-VAE's one-ring frames, padding invariance, labels,
no recompilation, finite gradients, and the registered equivariance entries."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import ConfigError, InputError
from jmeshtex.data import grid, icosphere
from jmeshtex.fldm._config import Config
from jmeshtex.fldm._denoiser import (
    denoise,
    denoiser_flops,
    denoiser_geometry,
    geometry_sizes,
    init_denoiser,
    pad_geometry,
    timestep_embedding,
)
from jmeshtex.geometry import mean_edge_length, one_ring_neighborhood
from jmeshtex.ops import tangent_noise
from jmeshtex.testing import check
from jmeshtex.testing._methods import fldm as _fldm_equivariance
from tests._equivariance_checks import assert_flagged, assert_registry_asserts

CFG = Config.tiny(
    latent_channels=2, widths=(6, 8), hdim=4, knn=7, activation="silu", time_features=8
)


@pytest.fixture(scope="module")
def sphere():
    v, f = icosphere(2)
    return v, f, denoiser_geometry((v, f), knn=CFG.knn, pool_ratio=0.25)


@pytest.mark.parametrize(
    "make", [lambda: icosphere(2), lambda: grid(9, 7)], ids=["sphere", "open-grid"]
)
def test_fine_frames_are_the_one_ring_frames_of_the_fl_vae(make):
    """The FL-VAE puts latents in one_ring_neighborhood's frames (x-axis = first one-ring edge): in
    the denoiser's k-NN log map that first neighbour must be real-positive, and every one-ring
    neighbour must have the same direction as in the one-ring log map."""
    v, f = make()
    ring = one_ring_neighborhood(v, f, scale=None)  # mesh units
    geo = denoiser_geometry((v, f), knn=CFG.knn)
    h = mean_edge_length(v, f)
    V = len(v)
    first = ring.index[:, 0]
    log0 = ring.log[:, 0]
    assert np.all(log0.real > 0) and np.allclose(log0.imag, 0, atol=1e-12)
    hits = 0
    for p in range(V):  # a loop over vertices as the reference check (small meshes)
        for j in np.nonzero(ring.mask[p])[0]:
            slot = np.nonzero((geo.fine.index[p] == ring.index[p, j]) & geo.fine.mask[p])[0]
            if slot.size:
                np.testing.assert_allclose(
                    geo.fine.log[p, slot[0]] * h, ring.log[p, j], rtol=1e-10, atol=1e-12
                )
                hits += 1
        s0 = np.nonzero((geo.fine.index[p] == first[p]) & geo.fine.mask[p])[0]
        if s0.size:
            assert geo.fine.log[p, s0[0]].real > 0 and abs(geo.fine.log[p, s0[0]].imag) < 1e-12
    assert hits > 3 * V  # most one-ring neighbours are among the k nearest


def test_padding_leaves_real_outputs_unchanged(sphere):
    v, f, geo = sphere
    params = init_denoiser(jax.random.key(0), CFG, geo, dtype=jnp.complex128)
    sizes = geometry_sizes(geo)
    z = tangent_noise(jax.random.key(1), (len(v), 2), dtype=jnp.complex128)
    out = denoise(params, CFG, z, jnp.array(123), geo)
    padded = pad_geometry(geo, V0=sizes["V0"] + 37, V1=sizes["V1"] + 11, M=sizes["M"] + 3)
    zp = jnp.concatenate([z, 5.0 + tangent_noise(jax.random.key(2), (37, 2), dtype=jnp.complex128)])
    outp = denoise(params, CFG, zp, jnp.array(123), padded)
    np.testing.assert_allclose(outp[: len(v)], out, rtol=1e-10, atol=1e-12)
    assert bool(jnp.all(outp[len(v) :] == 0))


def test_timestep_and_labels_change_the_output_and_jit_does_not_recompile(sphere):
    v, f, geo = sphere
    cfg = CFG.replace(num_labels=3)
    params = init_denoiser(jax.random.key(0), cfg, geo)
    z = tangent_noise(jax.random.key(1), (len(v), 2))
    labels = jnp.asarray(np.arange(len(v)) % 3, jnp.int32)
    traces = []

    @jax.jit
    def run(params, z, t, labels):
        traces.append(1)
        return denoise(params, cfg, z, t, geo, labels=labels)

    a = run(params, z, jnp.array(10), labels)
    b = run(params, z, jnp.array(500), labels)
    c = run(params, z, jnp.array(10), jnp.zeros_like(labels))
    assert len(traces) == 1
    assert a.dtype == jnp.complex64 and a.shape == z.shape
    assert float(jnp.abs(a - b).max()) > 1e-3 and float(jnp.abs(a - c).max()) > 1e-3


def test_gradients_are_finite_at_zero_latents(sphere):
    v, f, geo = sphere
    params = init_denoiser(jax.random.key(0), CFG, geo, dtype=jnp.complex128)

    def loss(params, z):
        return jnp.sum(jnp.abs(denoise(params, CFG, z, jnp.array(3), geo)) ** 2)

    z = jnp.zeros((len(v), 2), jnp.complex128).at[:5].set(1.0)
    g_params, g_z = jax.grad(loss, argnums=(0, 1))(params, z)
    assert all(bool(jnp.all(jnp.isfinite(x))) for x in jax.tree.leaves(g_params))
    assert bool(jnp.all(jnp.isfinite(g_z)))


def test_input_errors(sphere):
    v, f, geo = sphere
    params = init_denoiser(jax.random.key(0), CFG, geo)
    with pytest.raises(InputError, match="channels"):
        denoise(params, CFG, jnp.zeros((len(v), 3), jnp.complex64), 1, geo)
    with pytest.raises(InputError, match="complex"):
        denoise(params, CFG, jnp.zeros((len(v), 2)), 1, geo)
    with pytest.raises(InputError, match="vertices"):
        denoise(params, CFG, jnp.zeros((10, 2), jnp.complex64), 1, geo)
    with pytest.raises(InputError, match="labels"):
        denoise(params, CFG.replace(num_labels=2), jnp.zeros((len(v), 2), jnp.complex64), 1, geo)
    with pytest.raises(ConfigError, match="widths"):
        Config(widths=(4,))


def test_timestep_embedding_and_flops():
    e = timestep_embedding(jnp.array(7), 6, dtype=jnp.float64)
    w = np.exp(-np.log(1e4) * np.arange(3) / 3)
    np.testing.assert_allclose(e, np.stack([np.sin(7 * w), np.cos(7 * w)], 1).ravel(), rtol=1e-12)
    small, big = (
        denoiser_flops(Config.cpu(), 5000, 1250),
        denoiser_flops(Config.paper(), 5000, 1250),
    )
    assert big > 5 * small
    assert denoiser_flops(Config.paper(), 10000, 2500) == pytest.approx(2 * big, rel=1e-12)


# the harness: the full transform list runs in `jmeshtex verify` (all pass: errors ~1e-15, measured);
# here a subset that reaches every code path (frames, relabelling, an isometry, float32) stays fast
SUBSET = {
    "fldm.denoiser": (("gauge", "float64"), ("fold", "float64"), ("gauge", "float32")),
    "fldm.denoiser_labels": (("permute_vertices", "float64"),),
    "fldm.sampler": (("gauge", "float64"),),
    "fldm.denoiser_mask": (
        ("gauge", "float64"),
        ("permute_vertices", "float64"),
        ("fold", "float64"),
    ),
    "fldm.sampler_inpaint": (("gauge", "float64"), ("permute_vertices", "float64")),
}


@pytest.mark.parametrize(
    "entry", [e for e in _fldm_equivariance.ENTRIES if not e.expect_fail], ids=lambda e: e.name
)
def test_registered_entries(entry):
    """The subset's float64 cases are asserted by equivariance_tests/test_registry.py (the same
    ``check``); its float32 cases run here on every sample mesh (the registry's on the closed one)."""
    assert set(entry.transforms) >= {"rigid", "gauge", "permute_vertices", "fold", "hinge"}
    assert_registry_asserts(entry, tuple(t for t, dt in SUBSET[entry.name] if dt == "float64"))
    for t, dt in SUBSET[entry.name]:
        if dt == "float32":
            result = check(entry, t, dtype=jnp.float32)
            assert result.passed, (t, dt, result)


def test_the_reference_codes_untransported_filter_argument_is_flagged():
    """The registered negative control: the reference's get_rel_pos argument (log map with the
    neighbour's untransported feature direction) breaks gauge equivariance; permutations pass."""
    entry = next(
        e for e in _fldm_equivariance.ENTRIES if e.name == "fldm.denoiser_reference_argument"
    )
    assert entry.expect_fail == ("gauge",)
    flagged = check(entry, "gauge")
    assert flagged.expect_fail and flagged.passed and flagged.error > 1e-3, flagged
    assert check(entry, "permute_vertices").passed


def test_a_denoiser_that_ignores_transport_is_flagged():
    """Negative control: the same U-Net with every transport set to 1 is not gauge-equivariant."""
    from jmeshtex.testing import Field

    good = _fldm_equivariance.ENTRIES[0]

    def broken(state, params, z):
        geo = _fldm_equivariance._geometry(state)
        geo = geo._replace(fine=geo.fine._replace(transport=jnp.ones_like(geo.fine.transport)))
        return Field(
            "vertex_tangent",
            denoise(params, CFG.replace(widths=(4, 6)), z, jnp.array(37, jnp.int32), geo),
        )

    assert_flagged(
        good, "fldm.negative.no_transport", broken, "gauge", transforms=("permute_vertices",)
    )


def test_output_scales_with_input_at_high_noise():
    """ε-prediction needs ε̂ ≈ z_t at high noise, so the output must follow the input's scale: the
    reference's linear residuals and linear output give RMS(ε̂(s z)) ∝ s for large s. The earlier
    network (FRN → VN → dense at the end, filters on directions only) was near degree-0 homogeneous:
    measured at init (Config.tiny, icosphere(3), t = 999/500/10, 2 seeds) RMS(ε̂(16 z)) / RMS(ε̂(z)) =
    0.89-1.05; this network gives 8.4-12.0 (RMS(ε̂(16 z)) / RMS(ε̂(4 z)) = 3.8-4.0)."""
    cfg = Config.tiny(latent_channels=2)
    v, f = icosphere(2)
    geo = denoiser_geometry((v, f), knn=cfg.knn)
    params = init_denoiser(jax.random.key(0), cfg)
    z = tangent_noise(jax.random.key(1), (len(v), 2))

    def rms(s, t):
        out = denoise(params, cfg, z * s, jnp.array(t), geo)
        return float(jnp.sqrt(jnp.mean(jnp.abs(out) ** 2)))

    for t in (999, 900):
        r1, r4, r16 = rms(1.0, t), rms(4.0, t), rms(16.0, t)
        assert r4 > 1.8 * r1 and r16 > 3.0 * r4, (
            t,
            r1,
            r4,
            r16,
        )  # linear: 4 and 4; the old network: ~1 and ~1


def test_the_network_reads_only_the_fields_its_programs_are_keyed_on():
    """``init_denoiser`` and ``denoise`` compile once per ``Config.network()``: a field the network
    read but ``network()`` reset would silently take its default. Trace the module with a config
    that records every field read (every option switched on) and check the reads."""
    from jmeshtex._config import ConfigBase
    from jmeshtex.fldm._config import NETWORK_FIELDS
    from jmeshtex.fldm._denoiser import Denoiser, _as_jax

    read: set[str] = set()

    class Recording:
        def __init__(self, config):
            object.__setattr__(self, "_config", config)

        def __getattr__(self, name):
            value = getattr(self._config, name)
            if isinstance(value, ConfigBase):  # a section: its fields are read by their flat names
                return Recording(value)
            read.add(name)
            return value

        def __hash__(self):
            return hash(self._config)

    cfg = CFG.replace(num_labels=2, mask_conditioning=True, invariants=True, remat=True)
    v, f = icosphere(1)
    geo = _as_jax(denoiser_geometry((v, f), knn=cfg.knn, pool_ratio=0.5), jnp.complex64)
    z = jnp.zeros((len(v), 2), jnp.complex64)
    args = (z, jnp.int32(3), geo, jnp.zeros(len(v), jnp.int32), jnp.zeros(len(v), bool), z)
    jax.eval_shape(lambda k: Denoiser(Recording(cfg)).init(k, *args), jax.random.key(0))
    assert read and read <= set(NETWORK_FIELDS), sorted(read - set(NETWORK_FIELDS))
    assert cfg.replace(steps=3, diffusion_steps=7, batch_size=8).network() == cfg.network()

"""Structure measures (autocorrelation length, peaks, reconstruction error) on textures with a known period,
the ground truth of a transfer (oracle textures, peak density), and the official fitting schedule."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jmeshtex import InputError, Mesh
from jmeshtex.data import (
    GEOMETRIC_TEXTURES,
    icosphere,
    texture_centers,
    textured_sphere,
    textured_torus,
    torus,
)
from jmeshtex.dgts import PrepareConfig
from jmeshtex.dgts.core import (
    density_error,
    fit_level,
    height_autocorrelation,
    height_autocorrelation_length,
    matched_noise,
    oracle_texture,
    peak_statistics,
    period_in_mean_edges,
    reconstruction_errors,
    relief_heights,
    texture_scores,
)
from jmeshtex.geometry import mean_edge_length, subdivide_midpoint


@pytest.mark.parametrize("period", [0.3, 0.45])
def test_peaks_of_knobs_are_the_texture_centres_at_the_known_spacing(period):
    m = textured_sphere("knobs", subdivisions=4, period=period)
    centres = texture_centers("sphere", period=period)
    stats = peak_statistics(m)
    assert stats.count == len(centres)
    d = np.linalg.norm(centres[:, None] - centres[None], axis=-1) + 9 * np.eye(len(centres))
    known = d.min(axis=1).mean() / mean_edge_length(*m)  # nearest-centre spacing in mean edges
    assert abs(stats.spacing - known) < 0.1 * known
    area = 4 * np.pi / mean_edge_length(*m) ** 2
    assert (
        abs(stats.density - len(centres) / area) < 0.15 * stats.density
    )  # the displaced sphere is a bit larger


def test_autocorrelation_length_grows_with_the_period_and_is_short_for_noise():
    lengths = [
        height_autocorrelation_length(textured_sphere("knobs", subdivisions=4, period=p))
        for p in (0.3, 0.6)
    ]
    assert (
        lengths[1] > 1.3 * lengths[0]
    )  # sub-linear: the Taubin high-pass of normal_heights damps wide bumps
    v, f = icosphere(4)
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(len(v))
    assert (
        height_autocorrelation_length((v, f), noise) < 1.0
    )  # white noise decorrelates within one edge
    assert height_autocorrelation_length((v, f), np.zeros(len(v))) == 0.0
    r, c = height_autocorrelation((v, f), noise)
    assert r[0] == 0 and c[0] == 1 and np.all(np.abs(c[2:]) < 0.1)


@pytest.mark.parametrize("kind", GEOMETRIC_TEXTURES)
def test_every_texture_has_relief_on_sphere_and_torus(kind):
    for m in (
        textured_sphere(kind, subdivisions=3, period=0.6),
        textured_torus(kind, n_major=48, n_minor=16, period=0.5),
    ):
        assert np.isfinite(m.vertices).all()
        s = peak_statistics(m)
        assert s.count >= 5 and np.isfinite(s.spacing)


def test_reconstruction_errors_are_per_level_and_zero_free(tiny_model, tiny_meshes):
    e = reconstruction_errors(tiny_model, tiny_meshes)
    assert e.shape == (tiny_model.num_levels,) and np.all(np.isfinite(e)) and np.all(e > 0)


def test_official_schedule_fits_like_the_joint_one():
    ref = textured_sphere("knobs", subdivisions=3, period=0.6)
    v, f = icosphere(1)
    start = fit_level(
        (v, f), ref, config=PrepareConfig.official(steps=0), num_samples=300, key=jax.random.key(0)
    )[1]
    cfg = PrepareConfig.official(steps=40, learning_rate=5e-3, samples_per_level=300)
    fitted, terms = fit_level((v, f), ref, config=cfg, num_samples=300, key=jax.random.key(0))
    assert fitted.shape == v.shape and set(terms) >= {"s2t", "t2s", "edge_std", "laplacian"}
    joint = fit_level(
        (v, f),
        ref,
        config=PrepareConfig(steps=200, learning_rate=5e-3),
        num_samples=300,
        key=jax.random.key(0),
    )[1]  # as many Adam steps (40 × (3 + 2))

    def cd(t):
        return t["s2t"] + t["t2s"]

    print(f"Chamfer start {cd(start):.4f}, official {cd(terms):.4f}, joint {cd(joint):.4f}")
    assert cd(terms) < 0.9 * cd(start) and cd(joint) < 0.9 * cd(start)
    assert cd(terms) < 1.25 * cd(joint)
    with pytest.raises(Exception, match="schedule"):
        PrepareConfig(schedule="alternate")


def _subdivided(mesh, times: int):
    v, f = mesh
    for _ in range(times):
        s = subdivide_midpoint(v, f)
        v, f = s.vertices, s.faces
    return Mesh(v, f)


#: tessellations of one surface each: resolutions, and coarse meshes subdivided as a transfer does
TESSELLATIONS = {
    "sphere": [icosphere(4), icosphere(5), _subdivided(icosphere(2), 2)],
    "torus": [torus(128, 44), torus(96, 32), _subdivided(torus(64, 24), 1)],
}


@pytest.mark.parametrize(
    "surface, period", [("sphere", 4.0), ("sphere", 5.5), ("torus", 4.0)], ids=str
)
def test_oracle_peak_density_is_the_same_on_every_tessellation_of_a_surface(surface, period):
    """Peaks per squared mean edge of an oracle at ``period`` mean edges: within ±10 % across
    resolutions and subdivided coarse meshes (mean of 3 centre seeds). Where the period nears the
    surface's radius of curvature the count follows the curvature instead (a 48 × 18 torus, tube
    radius 0.35, at 5.5 edges ≈ 0.9: half the peaks), as ACL and spacing always do."""
    densities = []
    for base in TESSELLATIONS[surface]:
        truths = [
            oracle_texture(base, "knobs", period=period, key=jax.random.key(s)) for s in range(3)
        ]
        d = [texture_scores(t, t, base=base).peak_density for t in truths]
        densities.append(float(np.mean(d)))
    mid = float(np.mean(densities))
    print(f"{surface} period {period}: densities {np.round(densities, 4)}")
    assert all(abs(x - mid) <= 0.1 * mid for x in densities)
    expected = 1.0 / period**2  # about one knob per squared period (Poisson-disc packing)
    assert 0.5 * expected < mid < 2.0 * expected


def test_peak_density_separates_the_oracle_from_zero_and_noise():
    base = _subdivided(torus(32, 12), 1)
    truth = oracle_texture(base, "knobs", period=4.0)
    own = texture_scores(truth, truth, base=base)
    zero = texture_scores(base, truth, base=base)
    noise = texture_scores(matched_noise(base, own.relief, key=jax.random.key(0)), truth, base=base)
    other = texture_scores(
        oracle_texture(base, "knobs", period=4.0, key=jax.random.key(5)), truth, base=base
    )
    assert own.w1 == 0 and own.peaks > 20
    assert zero.peaks == 0 and density_error(zero, own) == np.inf
    assert abs(noise.relief - own.relief) < 0.02 * own.relief  # matched relief ...
    assert noise.peak_density > 2 * own.peak_density  # ... but twice as many peaks, or more
    assert density_error(other, own) < 0.15 < np.log(2) < density_error(noise, own)


def test_relief_heights_need_the_base_connectivity():
    with pytest.raises(InputError, match="base"):
        relief_heights(icosphere(3), icosphere(2))
    with pytest.raises(InputError, match="period"):
        oracle_texture(icosphere(2), "knobs", period=0.0)


def test_period_in_mean_edges_follows_the_training_scale(tiny_meshes):
    p = period_in_mean_edges(tiny_meshes, 1.0)
    ell = mean_edge_length(tiny_meshes.vertices[-1], tiny_meshes.faces[-1])
    assert np.isclose(p * ell, tiny_meshes.scales[-1])
    assert np.isclose(period_in_mean_edges(tiny_meshes, 2.0), 2 * p)

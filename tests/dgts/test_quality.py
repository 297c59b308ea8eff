"""Structure measures (autocorrelation length, peaks, reconstruction error) on textures with a known period,
and the official fitting schedule."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jmeshtex.data import (
    GEOMETRIC_TEXTURES,
    icosphere,
    texture_centers,
    textured_sphere,
    textured_torus,
)
from jmeshtex.dgts import PrepareConfig
from jmeshtex.dgts.core import (
    fit_level,
    height_autocorrelation,
    height_autocorrelation_length,
    peak_statistics,
    reconstruction_errors,
)
from jmeshtex.geometry import mean_edge_length


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

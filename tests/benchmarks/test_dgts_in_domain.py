"""The DGTS benchmark's in-domain base: the sphere under the training mesh, not the template's
facets (``benchmarks/dgts.py`` ``in_domain_truth``)."""

from __future__ import annotations

import pathlib
import sys
from types import SimpleNamespace

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))  # the benchmark imports its harness as a sibling

import dgts as bench  # noqa: E402

from jmeshtex import Mesh  # noqa: E402
from jmeshtex.data import icosphere  # noqa: E402
from jmeshtex.dgts.core import knob_scores, oracle_texture  # noqa: E402
from jmeshtex.geometry import mean_edge_length, subdivide_midpoint  # noqa: E402


def test_the_in_domain_base_is_the_sphere_under_the_truth_not_the_templates_facets():
    """An icosphere(0) template subdivided flat four times is an icosahedron; the truth (knobs on
    the unit sphere, icosphere(4)'s connectivity) scored on it sees the facets' creases as
    texture. The base ``in_domain_truth`` returns lies on the truth's sphere: there the bare
    sphere has no knob and the truth's density is the one measured on icosphere(4) itself."""
    v, f = np.asarray(icosphere(0).vertices, np.float64), np.asarray(icosphere(0).faces)
    for _ in range(4):
        sub = subdivide_midpoint(v, f)
        v, f = np.asarray(sub.vertices, np.float64), np.asarray(sub.faces)
    sphere = icosphere(4)
    assert np.array_equal(f, np.asarray(sphere.faces)), "flat and spherical subdivision differ"
    truth = oracle_texture(sphere, "knobs", period=5.0)
    tm = SimpleNamespace(num_levels=1, faces=[f], vertices=[truth.vertices], scales=[1.0])
    reference_period = 5.0 * mean_edge_length(sphere.vertices, sphere.faces)
    truth_t, base, period = bench.in_domain_truth(tm, (v, f), reference_period)

    centre = truth_t.vertices.mean(axis=0)
    radius = np.linalg.norm(base.vertices - centre, axis=1)
    assert np.ptp(radius) < 1e-9
    assert radius[0] == pytest.approx(np.linalg.norm(truth_t.vertices - centre, axis=1).mean())
    flat = (v - centre) / np.linalg.norm(v - centre, axis=1, keepdims=True)
    np.testing.assert_allclose((base.vertices - centre) / radius[:, None], flat, atol=1e-12)
    assert period == pytest.approx(5.0, rel=0.05)

    bare = Mesh(base.vertices, f)  # the sphere alone: no texture
    on_base = knob_scores(truth_t, truth_t, base=base, period=period)
    on_sphere = knob_scores(truth, truth, base=sphere, period=5.0)
    assert on_base.density == pytest.approx(on_sphere.density, rel=0.05)  # 0.572 and 0.590
    bare_on_base = knob_scores(bare, truth_t, base=base, period=period)
    assert bare_on_base.count == 0
    # on the facets the bare sphere has a knob at every face centre and looks 3x closer to the truth
    facets = Mesh(v, f)
    bare_on_facets = knob_scores(
        bare, truth_t, base=facets, period=reference_period / mean_edge_length(v, f)
    )
    assert bare_on_facets.count >= 12
    assert bare_on_facets.distance < 0.5 * bare_on_base.distance

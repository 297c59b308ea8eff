"""The DGTS benchmark's in-domain layout score: 1 for the truth's own layout, near 0 for another."""

from __future__ import annotations

import pathlib
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))  # the benchmark imports its harness as a sibling

import dgts  # noqa: E402

from jmeshtex.data import icosphere, textured_sphere  # noqa: E402


@pytest.mark.parametrize("kind", ["knobs", "scales"])
def test_layout_correlation_tells_the_truths_layout_from_another(kind):
    truth = textured_sphere(kind, subdivisions=4, period=0.5, seed=0)
    moved = textured_sphere(kind, subdivisions=4, period=0.5, seed=1)  # the same texture elsewhere
    assert dgts.layout_correlation(truth, truth) == pytest.approx(1.0)
    assert abs(dgts.layout_correlation(moved, truth)) < 0.3
    with pytest.raises(ValueError, match="vertices"):
        dgts.layout_correlation(icosphere(3), truth)

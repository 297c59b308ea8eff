"""The DGTS studies' scores: the in-domain layout (1 for the truth's own layout, near 0 for
another) and the rows' headline columns."""

from __future__ import annotations

import pathlib
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "studies"))  # a study imports its helpers as siblings

import _dgts as dgts  # noqa: E402

from jmeshtex.data import icosphere, textured_sphere  # noqa: E402


@pytest.mark.parametrize("kind", ["knobs", "scales"])
def test_layout_correlation_tells_the_truths_layout_from_another(kind):
    truth = textured_sphere(kind, subdivisions=4, period=0.5, seed=0)
    moved = textured_sphere(kind, subdivisions=4, period=0.5, seed=1)  # the same texture elsewhere
    assert dgts.layout_correlation(truth, truth) == pytest.approx(1.0)
    assert abs(dgts.layout_correlation(moved, truth)) < 0.3
    with pytest.raises(ValueError, match="vertices"):
        dgts.layout_correlation(icosphere(3), truth)


def test_score_rows_lead_with_the_knob_measure():
    """The studies' rows: knobs per squared period and the patch distance come before the former
    per-mesh-edge peak density, which stays as a diagnostic."""
    from _study import Report

    from jmeshtex.dgts.core import oracle_texture

    base = icosphere(3)
    truth = oracle_texture(base, "knobs", period=4.0)
    report = Report("test_dgts_scores", ceilings=False)
    dgts.score_rows(report, "s", {"truth": [truth], "zero": [base]}, truth, base, {}, 4.0)
    keys = list(report.rows[0])
    assert keys.index("knob_density_vs_truth") < keys.index("peak_density")
    assert report.rows[0]["patch_distance"] == 0 and report.rows[0]["knob_density_vs_truth"] == 1
    assert report.rows[1]["knob_density_vs_truth"] == 0 and report.rows[1]["patch_distance"] > 0

"""What every study shares: the benchmarks' harness and the folder of the studies' results.

A study is one change at a time, measured apart from the product's benchmarks (``benchmarks/``):
each ``studies/<name>.py`` runs standalone (``python studies/<name>.py --help``), writes its own
``studies/results/<report>.{json,md}`` (and figures) from this run alone, and reuses the
benchmarks' ``Report`` (machine, versions, JSON + markdown) and, where it extends one, that
benchmark's scoring. ``studies/README.md`` lists them with the commands that produced their files.
"""

from __future__ import annotations

import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # the harness and the benchmarks import as siblings

import _harness  # noqa: E402

Size, size_label = _harness.Size, _harness.size_label

#: where the studies' tables and figures land
RESULTS = ROOT / "studies" / "results"


class Report(_harness.Report):
    """The benchmarks' report, written to :data:`RESULTS` unless told otherwise."""

    def write(self, directory: pathlib.Path | None = None) -> pathlib.Path:
        return super().write(RESULTS if directory is None else directory)

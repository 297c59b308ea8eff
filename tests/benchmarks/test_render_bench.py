"""Smoke test of ``benchmarks/render.py --smoke``: it runs end to end and writes every row with finite
times; where Embree is importable its face buffer agrees with the z-buffer."""

from __future__ import annotations

import json
import math
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "render.py"


@pytest.mark.slow
def test_smoke_run_writes_every_row(tmp_path):
    # a separate process: the benchmark runs with JAX's defaults, as it would from the command line
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--smoke", "--out", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    payload = json.loads((tmp_path / "render.json").read_text())
    names = [r["name"] for r in payload["rows"]]
    for name in (
        "visibility (NumPy z-buffer)",
        "shading (JAX, jit)",
        "total render()",
        "old matplotlib path",
    ):
        assert name in names, names
    assert names.count("scaling: faces") == 2 and names.count("scaling: pixels") == 2
    for r in payload["rows"]:
        assert math.isfinite(r["seconds"]) and r["seconds"] > 0, r
        if "agree_with_zbuffer" in r:
            assert r["agree_with_zbuffer"] > 0.99, r
    assert "visibility (NumPy z-buffer)" in (tmp_path / "render.md").read_text()

"""The benchmark runner (``python -m benchmarks``): a quick sweep end to end, the one JSON schema,
the adapter over the committed results, the growth-exponent fit, ``compare``'s exit codes, and the
GPU check script on CPU at tiny size."""

from __future__ import annotations

import doctest
import json
import os
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from benchmarks import _compare, _runner  # noqa: E402

FIGURE_KEYS = {
    "benchmark",
    "name",
    "params",
    "seconds",
    "runs",
    "ceiling",
    "ratio_to_ceiling",
    "metrics",
    "machine",
    "versions",
    "commit",
}


def _cli(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    return subprocess.run(
        [sys.executable, "-m", "benchmarks", *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def test_docstring_examples():
    for module in (_runner, _compare):
        result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
        assert result.failed == 0 and result.attempted > 0, module.__name__


def test_quick_sweep_writes_one_schema_a_table_and_plots_and_compare_flags_a_slowdown(tmp_path):
    out = tmp_path / "sweep"
    run = _cli("run", "ceilings", "ops_chamfer", "--quick", "--repeats", "2", "--out", str(out))
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    doc = json.loads((out / "sweep.json").read_text())
    assert doc["schema"] == _runner.SCHEMA and len(doc["cells"]) == 4
    assert {f["benchmark"] for f in doc["figures"]} == {"ceilings", "ops_chamfer"}
    for f in doc["figures"]:
        assert FIGURE_KEYS <= set(f), f
        assert f["seconds"] > 0 and len(f["runs"]) == 2 and f["versions"]["jax"] and f["commit"]
        assert f["machine"]["devices"], f["machine"]
    matmul = [f for f in doc["figures"] if f["name"] == "matmul"]
    assert matmul and all(
        f["ceiling"]["kind"] == "matmul_gflops" and f["ratio_to_ceiling"] > 0 for f in matmul
    )
    table = (out / "sweep.md").read_text()
    assert "| ceilings | matmul |" in table and "ratio to ceiling" in table
    assert (out / "ceiling.png").stat().st_size > 1000

    # the same file against itself: no regression, exit 0
    same = _cli("compare", str(out / "sweep.json"), str(out / "sweep.json"), timeout=120)
    assert same.returncode == 0, same.stdout + same.stderr
    assert "REGRESSION" not in same.stdout
    # one figure 3x slower: exit 1, the figure named. The quick sweep's own repeats can spread by
    # 70% on a loaded machine (then 3x is within 3 sigmas of noise), so the victim's repeats are made
    # tight in both files: what is tested here is the CLI's path, the noise rule has its own test.
    base, slow = json.loads(json.dumps(doc)), json.loads(json.dumps(doc))
    victim = slow["figures"][0]
    base["figures"][0]["runs"] = [victim["seconds"]] * 2
    victim["runs"] = [3 * victim["seconds"]] * 2
    victim["seconds"] *= 3
    (tmp_path / "base.json").write_text(json.dumps(base))
    (tmp_path / "slow.json").write_text(json.dumps(slow))
    worse = _cli("compare", str(tmp_path / "base.json"), str(tmp_path / "slow.json"), timeout=120)
    assert worse.returncode == 1, worse.stdout + worse.stderr
    line = next(x for x in worse.stdout.splitlines() if "REGRESSION" in x and "|" in x)
    assert victim["name"] in line and "3.000" in line


def test_compare_separates_noise_from_regressions():
    def doc(runs):
        return {
            "figures": [
                {
                    "benchmark": "b",
                    "name": "x",
                    "params": {"n": 10},
                    "seconds": sorted(runs)[1],
                    "runs": runs,
                }
            ]
        }

    # 20% slower, but the repeats spread by 40%: flagged only as noise, no failure
    rows, failed = _compare.compare(doc([1.0, 1.2, 1.4]), doc([1.2, 1.44, 1.68]))
    assert rows[0]["status"] == "ok" and not failed
    # 20% slower with 1% spread: a regression past a 10% threshold, not past a 30% one
    tight_old, tight_new = doc([1.0, 1.005, 1.01]), doc([1.2, 1.206, 1.212])
    assert _compare.compare(tight_old, tight_new, threshold=0.1)[1]
    rows, failed = _compare.compare(tight_old, tight_new, threshold=0.3)
    assert rows[0]["status"] == "slower (noise)" and not failed
    assert _compare.compare(tight_new, tight_old)[0][0]["status"] == "faster"


def test_growth_exponent_and_scaling_plot(tmp_path):
    ns = [1e3, 4e3, 1.6e4, 6.4e4]
    figs = [
        {
            "benchmark": "op",
            "name": "fwd",
            "params": {"n": n},
            "seconds": 1e-6 * n**1.5,
            "runs": [1e-6 * n**1.5],
            "ceiling": {"kind": "matmul_gflops", "value": 100.0, "achieved": 50.0},
            "ratio_to_ceiling": 0.5,
        }
        for n in ns
    ]
    assert abs(_runner.growth_exponent(ns, [f["seconds"] for f in figs]) - 1.5) < 1e-12
    paths = _runner.plot({"figures": figs}, tmp_path)
    assert [p.name for p in paths] == ["scaling.png", "ceiling.png"] and all(
        p.stat().st_size > 1000 for p in paths
    )


def test_the_adapter_keeps_every_committed_row():
    doc = _runner.import_results()
    rows = 0
    for path in (ROOT / "benchmarks" / "results").glob("*.json"):
        report = json.loads(path.read_text())  # a _harness report, or a bare list of rows
        rows += len(report) if isinstance(report, list) else len(report.get("rows", []))
    assert rows > 50 and len(doc["figures"]) == rows
    keys = [_runner.figure_key(f) for f in doc["figures"]]
    assert len(set(keys)) == len(keys)  # compare can tell every figure apart
    assert sum(f["ratio_to_ceiling"] is not None for f in doc["figures"]) > 10


@pytest.mark.skipif(sys.platform != "linux", reason="bash script, Linux coreutils (timeout)")
def test_gpu_check_script_runs_on_cpu_at_tiny_size(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"} | {"PYTHON": sys.executable}
    run = subprocess.run(
        ["bash", str(ROOT / "benchmarks" / "gpu_check.sh"), str(tmp_path), "--cpu", "--tiny"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    summary = (tmp_path / "summary.txt").read_text()
    assert run.returncode == 0, summary + run.stdout[-2000:] + run.stderr[-2000:]
    assert json.loads((tmp_path / "device.json").read_text())["backend"] == "cpu"
    for name in ("ops_field_conv", "ops_face_conv"):
        doc = json.loads((tmp_path / f"{name}_cpu.json").read_text())
        assert doc["figures"] and all(
            f["seconds"] > 0 for f in doc["figures"] if f["seconds"] is not None
        )
    assert "OK tests" in summary

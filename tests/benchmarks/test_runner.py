"""The benchmark runner (``python -m benchmarks``): a quick sweep end to end, the one JSON schema,
the adapter over the committed results, true sizes (``size_label``, ``Size``, warnings for a size
that cannot be determined), the growth-exponent fit with its confidence interval, ``compare``'s exit
codes and its interpolation over size, load warnings, and the GPU check script on CPU at tiny
size."""

from __future__ import annotations

import doctest
import json
import math
import os
import pathlib
import re
import subprocess
import sys

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from benchmarks import _compare, _harness, _runner  # noqa: E402

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
    for module in (_runner, _compare, _harness):
        result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
        assert result.failed == 0 and result.attempted > 0, module.__name__


@pytest.mark.slow
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


@pytest.mark.slow
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


# --- sizes -------------------------------------------------------------------------------------


def test_size_label_keeps_small_sizes_and_size_records_the_true_count():
    assert [_harness.size_label(n) for n in (300, 500, 1536, 20480, 1_234_567)] == [
        "300",
        "500",
        "1.5K",
        "20K",
        "1.2M",
    ]
    with pytest.raises(TypeError):
        _harness.size_label(1.5e3)
    with pytest.raises(ValueError):
        _harness.size_label(-1)
    assert _harness.SIZE_UNITS == _runner._SIZE_KEYS[:-1]  # the runner reads what Size writes

    report = _harness.Report("sizes", ceilings=False)
    row = report.add(name="fwd", size=_harness.Size("500", vertices=500), seconds=0.1)
    assert list(row)[:3] == ["name", "size", "vertices"] and row["vertices"] == 500
    assert type(row["size"]) is str and json.loads(json.dumps(row))["size"] == "500"
    with pytest.raises(ValueError, match="counts 500"):
        report.add(name="fwd", size=_harness.Size("500", vertices=500), vertices=499)
    for bad in ({}, {"vertices": 1, "faces": 2}, {"edges": 3}):
        with pytest.raises(TypeError):
            _harness.Size("x", **bad)


def test_the_size_scripts_record_counts_and_no_label_truncates_to_thousands():
    """Every script of item 7 builds its size labels with Size (the count travels with the label);
    none writes the old ``f"{n // 1000}K"`` that turned 500 vertices into "0K"."""
    scripts = ("ops_face_conv", "render", "ops_texel", "ops_chamfer", "meshmatch", "ops_field_conv")
    for name in scripts:
        text = (ROOT / "benchmarks" / f"{name}.py").read_text()
        assert "Size(" in text and "size_label(" in text, name
        assert not re.search(r"//\s*1000\}K|/\s*1000:\.0f\}K", text), name


def _report(rows, name="op"):
    return {"name": name, "machine": {"devices": ["cpu:0"]}, "rows": rows}


def test_a_500_vertex_row_enters_the_fit_and_an_unparsable_size_is_reported(tmp_path):
    report = _harness.Report("op", ceilings=False)
    for n in (500, 2000, 8000):
        report.add(
            name="fwd", size=_harness.Size(_harness.size_label(n), vertices=n), seconds=n**1.5
        )
    figs = _runner.figures_from_report(_report(report.rows))
    assert [f["params"]["n"] for f in figs] == [500, 2000, 8000]
    fit = _runner.growth_table({"figures": figs})["op: fwd"]
    assert fit.points == 3 and fit.sizes == (500, 2000, 8000) and abs(fit.exponent - 1.5) < 1e-12
    assert _runner.unsized_figures(figs) == []

    # a report written by an old script: "0K" has no count and cannot be parsed; it is named
    old = _runner.figures_from_report(
        _report([{"name": "fwd", "size": "0K", "seconds": 1.0}, *report.rows])
    )
    assert [f["params"]["size"] for f in _runner.unsized_figures(old)] == ["0K"]
    table = _runner.markdown({"figures": old})
    assert "## Warnings" in table
    warning = next(line for line in table.splitlines() if line.startswith("- warning: size"))
    assert "'0K'" in warning and "op/fwd[] @ 0K" in warning
    assert "## Warnings" not in _runner.markdown({"figures": figs})


# --- growth exponents --------------------------------------------------------------------------


def test_growth_fit_interval_matches_the_textbook_slope_interval():
    rng = np.random.default_rng(0)
    ns = np.array([1e3, 2e3, 4e3, 8e3, 1.6e4, 3.2e4])
    ts = 1e-6 * ns**1.3 * np.exp(rng.normal(0.0, 0.1, ns.size))
    fit = _runner.growth_fit(ns, ts)
    x, y = np.log(ns), np.log(ts)
    slope, intercept = np.polyfit(x, y, 1)
    resid = y - (slope * x + intercept)
    se = math.sqrt(resid @ resid / (ns.size - 2) / ((x - x.mean()) @ (x - x.mean())))
    t975_4 = 2.7764451051977987  # Student t, 97.5 % quantile, 4 degrees of freedom (tables)
    assert abs(fit.exponent - slope) < 1e-10 and fit.points == 6
    assert abs(fit.half_width - t975_4 * se) < 1e-9 and fit.half_width > 0
    assert abs(_runner.t_quantile(0.975, 4) - t975_4) < 1e-9
    assert _runner.growth_fit([1e3, 1e4], [1.0, 3.0]).half_width is None
    assert _runner.growth_fit([1e3, 1e3], [1.0, 3.0]) is None  # one size: no slope
    with pytest.raises(ValueError):
        _runner.t_quantile(0.3, 4)


def test_growth_table_in_markdown_and_the_plot_legend_say_the_same(tmp_path, monkeypatch):
    rng = np.random.default_rng(1)
    figs = []
    for name, ns in (("fwd", [1e3, 4e3, 1.6e4, 6.4e4]), ("bwd", [1e3, 4e3])):
        for n in ns:
            t = 1e-6 * n**1.5 * math.exp(rng.normal(0.0, 0.05))
            figs.append({"benchmark": "op", "name": name, "params": {"n": n}, "seconds": t})
    doc = {"figures": figs}
    fits = _runner.growth_table(doc)
    table = _runner.markdown(doc)
    assert "## Growth" in table and "| series | sizes n | exponent ± 95 % CI | points |" in table
    fwd = fits["op: fwd"]
    row = next(line for line in table.splitlines() if line.startswith("| op: fwd |"))
    assert f"{fwd.exponent:.2f} ± {fwd.half_width:.2f}" in row and row.endswith("| 4 |")
    assert "1000, 4000, 16000, 64000" in row
    row = next(line for line in table.splitlines() if line.startswith("| op: bwd |"))
    assert "no interval" in row and row.endswith("| 2 |")

    import matplotlib.figure

    legends: list[str] = []
    save = matplotlib.figure.Figure.savefig

    def spy(self, *args, **kwargs):
        for ax in self.axes:
            if ax.get_legend() is not None:
                legends.extend(t.get_text() for t in ax.get_legend().get_texts())
        return save(self, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", spy)
    _runner.plot(doc, tmp_path)
    text = next(t for t in legends if t.startswith("fwd"))
    assert f"n^{fwd.exponent:.2f} ± {fwd.half_width:.2f}" in text and "4 points" in text


# --- compare over size -------------------------------------------------------------------------


def _fig(name, n, seconds, **params):
    return {
        "benchmark": "op",
        "name": name,
        "params": {"size": _harness.size_label(n), "vertices": n, "n": n, **params},
        "seconds": seconds,
        "runs": [seconds, seconds],
    }


def test_compare_interpolates_over_size_and_never_extrapolates():
    old = {"figures": [_fig("fwd", n, 1e-6 * n**1.5) for n in (1000, 10000, 100000)]}
    new = {
        "figures": [
            _fig("fwd", 10000, 1e-6 * 10000**1.5),  # exact
            _fig("fwd", 3000, 2 * 1e-6 * 3000**1.5),  # interpolated, twice as slow
            _fig("fwd", 500, 1.0),  # below OLD's sizes
            _fig("fwd", 200000, 1.0),  # above
            _fig("fwd", 3000, 1.0, threads=2),  # a series OLD does not have
            _fig("bwd", 3000, 1.0),
        ]
    }
    rows, failed = _compare.compare(old, new)
    assert [r["match"] for r in rows] == ["exact", "interpolated", None, None, None, None]
    interp = rows[1]
    expected = 1e-6 * 3000**1.5  # log-linear interpolation of a power law is exact
    assert abs(interp["old"] - expected) < 1e-12 * expected and interp["old_sizes"] == (1000, 10000)
    assert abs(interp["ratio"] - 2.0) < 1e-9 and interp["status"] == "REGRESSION" and failed
    assert (
        "outside OLD's sizes 1000..100000" in rows[2]["reason"]
        and "extrapolated" in rows[3]["reason"]
    )
    assert rows[4]["reason"] == rows[5]["reason"] == "series not in OLD"
    assert _compare.match_counts(rows) == {"exact": 1, "interpolated": 1, "unmatched": 4}
    text = _compare.compare_markdown(rows, threshold=0.1)
    assert (
        "6 timed figures in NEW: 1 matched exactly, 1 by interpolation over size, 4 not at all"
        in text
    )
    assert "| interpolated (1000..10000) |" in text

    # the same label but another recorded count is not the same figure: interpolated instead
    shifted = _fig("fwd", 10000, 1e-6 * 10000**1.5)
    shifted["params"].update(vertices=10240, n=10240)
    (row,), _ = _compare.compare(old, {"figures": [shifted]})
    assert row["match"] == "interpolated" and row["old_sizes"] == (10000, 100000)

    # an OLD written before sizes were recorded ("0K": unknown) and a NEW figure without a size
    unsized_old = {"figures": [{**_fig("fwd", 500, 1.0), "params": {"size": "0K", "n": None}}]}
    (row,), _ = _compare.compare(unsized_old, {"figures": [_fig("fwd", 500, 1.0)]})
    assert row["match"] is None and "could not determine" in row["reason"]
    (row,), _ = _compare.compare(old, {"figures": [{**_fig("fwd", 500, 1.0), "params": {}}]})
    assert row["match"] is None and row["reason"] == "size unknown"


def test_compare_a_local_sweep_with_the_committed_baseline(tmp_path):
    """A sweep at other sizes than the committed ``results/ops_face_conv.json`` (its rows carry no
    count: sizes parsed from "20K faces" ...): exact where the label agrees, interpolated inside the
    committed sizes, unmatched outside; before, this said "no figure in common" and exited 2."""
    baseline = ROOT / "benchmarks" / "results" / "ops_face_conv.json"
    committed = _runner.load_sweep(baseline)
    fwd = {f["params"]["n"]: f["seconds"] for f in committed["figures"] if f["name"] == "stack fwd"}
    assert len(fwd) >= 2
    lo, hi = sorted(fwd)[:2]
    between = int(math.sqrt(lo * hi))
    expected = math.exp(np.interp(math.log(between), np.log([lo, hi]), np.log([fwd[lo], fwd[hi]])))
    rows = []
    for count, seconds in ((int(lo) + 480, fwd[lo]), (between, expected), (320, 1e-3)):
        size = _harness.Size(f"{_harness.size_label(count)} faces", faces=count)
        rows.append({"name": "stack fwd", "size": str(size), "faces": count, "seconds": seconds})
    (tmp_path / "new.json").write_text(json.dumps(_report(rows, "ops_face_conv")))
    run = _cli("compare", str(baseline), str(tmp_path / "new.json"), timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    assert (
        "3 timed figures in NEW: 1 matched exactly, 1 by interpolation over size, 1 not at all"
        in run.stdout
    )
    line = next(x for x in run.stdout.splitlines() if "| interpolated" in x)
    assert "| 1.000 |" in line and "| ok |" in line
    assert "320 faces: size 320 outside OLD's sizes" in run.stdout

    (tmp_path / "tiny.json").write_text(json.dumps(_report(rows[2:], "ops_face_conv")))
    none = _cli("compare", str(baseline), str(tmp_path / "tiny.json"), timeout=120)
    assert none.returncode == 2 and "no figure in common" in none.stderr
    assert "0 matched exactly, 0 by interpolation over size, 1 not at all" in none.stderr


# --- load --------------------------------------------------------------------------------------


def _fake_cell(rows):
    def run_cell(bench, argv, *, threads, out, timeout):
        cell = {"benchmark": bench.name, "argv": argv, "threads": threads, "returncode": 0}
        return _report(rows, bench.name), cell | {"wall_s": 0.1}

    return run_cell


@pytest.mark.parametrize("over", [True, False])
def test_a_load_above_the_core_count_is_warned_and_recorded(tmp_path, monkeypatch, capsys, over):
    cores = os.cpu_count() or 1
    loads = iter([cores + 0.5, cores - 0.5] if over else [0.0, 0.0])
    monkeypatch.setattr(_runner, "load_average", lambda: next(loads))
    rows = [{"name": "fwd", "size": "300", "vertices": 300, "seconds": 0.1}]
    monkeypatch.setattr(_runner, "run_cell", _fake_cell(rows))
    log: list[str] = []
    doc = _runner.sweep(["ops_field_conv"], quick=True, out=tmp_path, log=log.append)
    (cell,) = doc["cells"]
    assert (cell["load_start"], cell["load_end"]) == (
        (cores + 0.5, cores - 0.5) if over else (0, 0)
    )
    err = capsys.readouterr().err
    warnings = doc["machine"].get("load_warnings", [])
    if over:
        assert [w["when"] for w in warnings] == ["start"] and warnings[0]["cores"] == cores
        assert (
            f"load average {cores + 0.5:.2f} > {cores} cores at the start of ops_field_conv" in err
        )
        assert any("WARNING: load average" in line for line in log)
        assert f"warning: load average {cores + 0.5:.2f} > {cores} cores" in _runner.markdown(doc)
    else:
        assert (
            warnings == []
            and "load average" not in err
            and "## Warnings" not in _runner.markdown(doc)
        )
    assert doc["figures"][0]["params"]["n"] == 300


def test_the_sweep_log_names_a_figure_whose_size_is_unknown(tmp_path, monkeypatch):
    rows = [
        {"name": "fwd", "size": "0K", "seconds": 0.1},
        {"name": "fwd", "size": "5K", "seconds": 0.5},
    ]
    monkeypatch.setattr(_runner, "load_average", lambda: 0.0)
    monkeypatch.setattr(_runner, "run_cell", _fake_cell(rows))
    log: list[str] = []
    doc = _runner.sweep(["ops_field_conv"], quick=True, out=tmp_path, log=log.append)
    assert [line for line in log if "WARNING" in line] == [
        "  WARNING: " + _runner._unsized_line(doc["figures"][0])
    ]
    assert "'0K'" in log[-1] and len(doc["figures"]) == 2  # reported, not dropped

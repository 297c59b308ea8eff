"""The benchmark runner: any set of benchmarks over a grid, one JSON schema for every figure.

Each benchmark script (``benchmarks/<name>.py``) keeps its own measurement code and its own
``results/<name>.json`` (``_harness.Report``). The runner runs it in a fresh process per grid cell
(size × dtype × preset × threads × repeat) with its results folder redirected into the sweep's
folder, reads the rows the script wrote back (:func:`figures_from_report`, the adapter) and turns
every timed row into one *figure*::

    {"benchmark": "ops_face_conv", "name": "stack fwd",
     "params": {"size": "20K faces", "n": 20480, "dtype": null, "preset": null, "threads": 2, ...},
     "seconds": 0.081,            # median over the sweep's repeats of the script's own median
     "runs": [0.080, 0.083],      # one per repeat: the noise estimate of `compare`
     "ceiling": {"kind": "matmul_gflops", "value": 283.0, "achieved": 104.9},
     "ratio_to_ceiling": 0.37,    # share of the ceiling measured in the same run (None: no ceiling)
     "metrics": {...},            # the row's other numbers (compile_s, gflops, psnr, ...)
     "machine": {...}, "versions": {...}, "commit": "2e2a954..."}

A sweep file is ``{"schema": SCHEMA, "figures": [...], "cells": [...]}`` (``cells``: what ran, its
wall time, exit status and the 1-minute load average at its start and end). A figure's *size* ``n``
is the count its row records (``texels``, ``pixels``, ``vertices``, ``faces``, ``points`` or ``n``:
``_harness.Size`` writes it), else parsed from its ``size`` label; its *series* is everything but
the size (:func:`series_key`), the line of the log-log plot and of the growth fit
(:func:`growth_fit`), and what ``compare`` interpolates over. A timed figure whose size cannot be
determined is reported (sweep log and :func:`markdown`), never dropped silently; so is a cell that
started or ended with the load average above the core count. Threads: a cell with ``threads=n`` runs pinned to ``n`` cores
(``sched_setaffinity``; XLA:CPU and BLAS size their pools by it) with the BLAS thread variables set.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import os
import pathlib
import platform
import re
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
SCHEMA = "jmeshtex-bench/1"

#: row keys that name a figure's setting (kept in ``params``) rather than measure it
_PARAM_KEYS = (
    "size",
    "mesh",
    "method",
    "model",
    "preset",
    "activation",
    "table",
    "chunk",
    "source",
    "bound",
    "what",
    "dtype",
    "atlas",
    "steps",
    "level",
)
#: row keys giving the problem size ``n`` of the log-log plot, in order of preference
_SIZE_KEYS = ("texels", "pixels", "vertices", "faces", "points", "n")
#: params that are not part of a figure's series: its size, and the roofline bound (which can flip
#: between "flops" and "bytes" from one size to the next)
_NOT_SERIES = ("size", *_SIZE_KEYS, "bound")


@dataclasses.dataclass(frozen=True)
class Benchmark:
    """How to run one benchmark script over the grid.

    Attributes:
      name: the script (``benchmarks/<name>.py``) and its report's name.
      size_args: ``sizes -> argv`` (None: the script has no size axis; one cell per other setting).
      quick_args: argv of the tiny ``--quick`` sweep (None: not in the quick sweep).
      preset_args: ``preset -> argv`` (None: no preset axis).
      dtype_args: ``dtype -> argv`` (None: no dtype axis).
      extra_args: argv always passed.
      report: the name of the JSON the script writes (default ``name``).
      per_size: run one process per size (scripts that take one size) rather than all sizes at once.
      script: the script's name when it differs from ``name`` (one script, several suites).
    """

    name: str
    size_args: Callable[[Sequence[str]], list[str]] | None = None
    quick_args: tuple[str, ...] | None = None
    preset_args: Callable[[str], list[str]] | None = None
    dtype_args: Callable[[str], list[str]] | None = None
    extra_args: tuple[str, ...] = ()
    report: str | None = None
    per_size: bool = False
    script: str | None = None


def _flag(flag: str, *, join: str | None = None):
    def args(sizes: Sequence[str]) -> list[str]:
        return [flag, join.join(sizes)] if join is not None else [flag, *sizes]

    return args


#: every benchmark the runner knows, with the sizes of its quick sweep (tiny, seconds each)
BENCHMARKS: dict[str, Benchmark] = {
    b.name: b
    for b in (
        Benchmark(
            "ceilings",
            size_args=_flag("--sizes"),
            quick_args=("--sizes", "256"),
            dtype_args=lambda d: ["--dtype", d],
        ),
        Benchmark("ops_face_conv", size_args=_flag("--sizes"), quick_args=("--sizes", "2")),
        Benchmark(
            "ops_field_conv",
            size_args=_flag("--sizes"),
            quick_args=("--sizes", "300", "--activations", "relu", "--repeats", "1"),
        ),
        Benchmark(
            "ops_texel",
            size_args=_flag("--size"),
            per_size=True,
            quick_args=("--size", "16", "--channels", "4"),
        ),
        Benchmark(
            "ops_chamfer",
            size_args=_flag("--points"),
            per_size=True,
            quick_args=("--points", "400", "--chunks", "128"),
        ),
        Benchmark("geometry", size_args=_flag("--sizes", join=","), quick_args=("--sizes", "400")),
        Benchmark("fldm_step", size_args=_flag("--sizes"), preset_args=lambda p: ["--presets", p]),
        Benchmark("fl_vae", size_args=_flag("--sizes", join=",")),
        Benchmark(
            "surfacecnn", size_args=lambda s: ["--precompute", ",".join(s), "--steps", ",".join(s)]
        ),
        Benchmark("meshmatch", size_args=_flag("--sizes", join=",")),
        Benchmark("meshmatch_cross", script="meshmatch", extra_args=("--suite", "cross")),
        Benchmark("render", size_args=_flag("--faces"), per_size=True, quick_args=("--smoke",)),
        Benchmark("dgts", extra_args=("--sections", "timing"), report="dgts_timing"),
        Benchmark("fldm_spot", script="fldm", quick_args=("--quick",)),
    )
}


def machine_and_versions() -> tuple[dict, dict]:
    """Facts about this machine and the versions of what is measured (no JAX import needed)."""
    from importlib import metadata

    machine = {
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "node": platform.node(),
    }
    try:
        machine["load"] = round(os.getloadavg()[0], 2)
    except OSError:
        pass
    versions = {"python": sys.version.split()[0]}
    for dist in ("jax", "jaxlib", "flax", "optax", "numpy", "jmeshtex"):
        try:
            versions[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            versions[dist] = None
    return machine, versions


def git_commit() -> str | None:
    """The checked-out commit, ``+dirty`` when the tree has changes (None outside git)."""
    try:
        sha = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, timeout=10
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return (sha + ("+dirty" if dirty else "")) or None


def problem_size(row: dict) -> float | None:
    """The size ``n`` of a row for the log-log plot: a count field, else parsed from ``size``.

    A count field (``_SIZE_KEYS``, first present wins) is the true size and the label is then not
    read. Without one: ``"20K faces"`` → 20000, ``"512x512 (262K texels)"`` → 262144, ``"512²"`` →
    262144, ``"1.5M"`` → 1.5e6; None when the label says nothing usable (``"0K"``, the truncated
    label of a size under 1000 written by old scripts), which the runner reports as a warning.

    Example:
      >>> problem_size({"size": "512x512 (262K texels), 64->64"}), problem_size({"size": "5K"}), problem_size({"size": "512²"})
      (262144, 5000.0, 262144)
      >>> problem_size({"size": "0K", "vertices": 500}), problem_size({"size": "0K"})
      (500, None)
    """
    for key in _SIZE_KEYS:
        if isinstance(row.get(key), (int, float)) and not isinstance(row.get(key), bool):
            return row[key]
    size = str(row.get("size", ""))
    if m := re.search(r"(\d+)\s*[x×]\s*(\d+)", size):
        return int(m.group(1)) * int(m.group(2))
    if m := re.search(r"(\d+)\s*²", size):
        return int(m.group(1)) ** 2
    if m := re.search(r"(\d+(?:\.\d+)?)\s*([KkM]?)", size):
        n = float(m.group(1)) * {"": 1, "k": 1e3, "K": 1e3, "M": 1e6}[m.group(2)]
        return n or None  # "0K faces": a tiny size rounded away, unknown
    return None


def _ceiling(row: dict, ceilings: dict) -> tuple[dict | None, float | None]:
    """The ceiling a row is measured against and the share of it reached (rows of ``_harness``)."""
    if "pct_of_bound" in row:
        kind = "bandwidth_gbs" if row.get("bound") == "bytes" else "matmul_gflops"
        achieved = row.get("gbs") if kind == "bandwidth_gbs" else row.get("gflops")
        return (
            {"kind": kind, "value": ceilings.get(kind), "achieved": achieved},
            row["pct_of_bound"] / 100,
        )
    for pct, kind, achieved in (
        ("pct_matmul", "matmul_gflops", "gflops"),
        ("pct_bandwidth", "bandwidth_gbs", "gbs"),
    ):
        want = {"pct_matmul": "flops", "pct_bandwidth": "bytes"}[pct]
        if pct in row and (
            row.get("bound") in (None, want) or ("pct_matmul" in row) != ("pct_bandwidth" in row)
        ):
            return {"kind": kind, "value": ceilings.get(kind), "achieved": row.get(achieved)}, row[
                pct
            ] / 100
    return None, None


def figures_from_report(
    report: dict,
    *,
    params: dict | None = None,
    machine: dict | None = None,
    versions: dict | None = None,
    commit: str | None = None,
) -> list[dict]:
    """The adapter: every timed row of a ``_harness`` report (``results/<name>.json``) as a figure.

    Rows without ``seconds`` (quality tables) are kept too, with ``seconds`` None, so no figure is
    lost; ``compare`` and the plots use the timed ones.

    Example:
      >>> rep = {"name": "ops_x", "machine": {"jax": "0.10"}, "ceilings": {"matmul_gflops": 100.0},
      ...        "rows": [{"name": "fwd", "size": "5K", "seconds": 0.5, "gflops": 40.0, "pct_matmul": 40.0}]}
      >>> f, = figures_from_report(rep, params={"threads": 2})
      >>> f["name"], f["params"]["n"], f["params"]["threads"], f["ratio_to_ceiling"], f["ceiling"]["value"]
      ('fwd', 5000.0, 2, 0.4, 100.0)
    """
    ceilings = report.get("ceilings") or {}
    out = []
    for i, row in enumerate(report.get("rows", [])):
        name = str(row.get("name") or row.get("table") or f"row {i}")
        p = {k: row[k] for k in (*_PARAM_KEYS, *_SIZE_KEYS) if k in row and k != "name"}
        p["n"] = problem_size(row)
        p.update(params or {})
        ceiling, ratio = _ceiling(row, ceilings)
        seconds = row.get("seconds")
        metrics = {
            k: v
            for k, v in row.items()
            if k not in p
            and k not in ("name", "seconds")
            and isinstance(v, (int, float))
            and not isinstance(v, bool)
        }
        out.append(
            {
                "benchmark": report.get("name"),
                "name": name,
                "params": p,
                "seconds": float(seconds) if isinstance(seconds, (int, float)) else None,
                "runs": [float(seconds)] if isinstance(seconds, (int, float)) else [],
                "ceiling": ceiling,
                "ratio_to_ceiling": ratio,
                "metrics": metrics,
                "machine": machine if machine is not None else report.get("machine", {}),
                "versions": versions if versions is not None else {},
                "commit": commit,
            }
        )
    seen: dict[str, int] = {}
    for fig in out:  # rows a report repeats with the same settings stay apart (in their order)
        key = figure_key(fig)
        seen[key] = seen.get(key, 0) + 1
        if seen[key] > 1:
            fig["params"]["occurrence"] = seen[key]
    return out


def series_key(fig: dict) -> str:
    """A figure's series: benchmark, name and every param but the size (``_NOT_SERIES``).

    Example:
      >>> series_key({"benchmark": "b", "name": "fwd", "params": {"size": "5K", "n": 5000, "threads": 2}})
      'b/fwd[threads=2]'
    """
    params = fig["params"]
    rest = ",".join(f"{k}={params[k]}" for k in sorted(params) if k not in _NOT_SERIES)
    return f"{fig['benchmark']}/{fig['name']}[{rest}]"


def _fmt_n(n: float) -> str:
    return str(int(n)) if float(n).is_integer() else f"{n:g}"


def figure_key(fig: dict) -> str:
    """What identifies a figure across runs: its series and its size (the ``size`` label when the
    row has one, else ``n``).

    The label, not the count, names the size so that a row that now records its true count
    (``"20K faces"``, ``faces=20480``) is still the figure an older file measured from its label
    alone (``n`` = 20000 parsed); ``compare`` checks recorded counts where both files have them.

    Example:
      >>> figure_key({"benchmark": "b", "name": "fwd", "params": {"size": "20K faces", "faces": 20480, "n": 20480}})
      'b/fwd[] @ 20K faces'
      >>> figure_key({"benchmark": "b", "name": "fwd", "params": {"faces": 320, "n": 320}})
      'b/fwd[] @ 320'
    """
    params = fig["params"]
    size = params.get("size")
    if size is None and params.get("n") is not None:
        size = _fmt_n(params["n"])
    return series_key(fig) + ("" if size is None else f" @ {size}")


def recorded_count(fig: dict) -> float | None:
    """The size a figure's row recorded in a count field (``texels``, ``pixels``, ``vertices``,
    ``faces``, ``points``), None when it had only a label (``n`` is then the label parsed).

    Example:
      >>> recorded_count({"params": {"size": "20K faces", "faces": 20480, "n": 20480}}), recorded_count({"params": {"size": "20K", "n": 20000.0}})
      (20480, None)
    """
    for key in _SIZE_KEYS[:-1]:
        value = fig["params"].get(key)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return value
    return None


def unsized_figures(figures: Sequence[dict]) -> list[dict]:
    """Timed figures whose size could not be determined although they have one: a ``size`` label
    that does not parse, or a series whose other figures have a size. They cannot enter a growth
    fit or an interpolation; the sweep log and :func:`markdown` name them.

    Example:
      >>> f = lambda size, n: {"benchmark": "b", "name": "x", "params": {"size": size, "n": n}, "seconds": 1.0}
      >>> [g["params"]["size"] for g in unsized_figures([f("0K", None), f("5K", 5000.0)])]
      ['0K']
    """
    sized = {series_key(f) for f in figures if f["params"].get("n")}
    return [
        f
        for f in figures
        if f.get("seconds") is not None
        and not f["params"].get("n")
        and (f["params"].get("size") is not None or series_key(f) in sized)
    ]


def _unsized_line(fig: dict) -> str:
    return (
        f"size unknown: {figure_key(fig)} (label {fig['params'].get('size')!r}, no count field "
        f"{'/'.join(_SIZE_KEYS[:-1])}): left out of the growth fits and of compare's interpolation"
    )


def merge_repeats(figures: list[dict]) -> list[dict]:
    """Figures that differ only by repeat merged: ``runs`` joined, ``seconds`` their median."""
    merged: dict[tuple, dict] = {}
    for fig in figures:
        key = (figure_key(fig), recorded_count(fig))  # one label, two true sizes: two figures
        if key not in merged:
            merged[key] = json.loads(json.dumps(fig))
        else:
            merged[key]["runs"] += fig["runs"]
    for fig in merged.values():
        if fig["runs"]:
            fig["seconds"] = statistics.median(fig["runs"])
    return list(merged.values())


def _cell_argv(
    bench: Benchmark,
    sizes: Sequence[str] | None,
    dtype: str | None,
    preset: str | None,
    quick: bool,
) -> list[str]:
    argv = list(bench.extra_args)
    if quick:
        argv += list(bench.quick_args or ())
    elif sizes:
        if bench.size_args is None:
            raise SystemExit(f"benchmark {bench.name} has no size axis; run it without --sizes")
        argv += bench.size_args(sizes)
    if preset is not None:
        if bench.preset_args is None:
            raise SystemExit(f"benchmark {bench.name} has no preset axis (presets: fldm_step)")
        argv += bench.preset_args(preset)
    if dtype is not None:
        if bench.dtype_args is None:
            raise SystemExit(
                f"benchmark {bench.name} has no dtype axis (dtypes: "
                f"{', '.join(n for n, b in BENCHMARKS.items() if b.dtype_args)})"
            )
        argv += bench.dtype_args(dtype)
    return argv


#: run a benchmark script with ``_harness.RESULTS`` pointed at a folder (scripts without ``--out``)
_BOOT = (
    "import pathlib, runpy, sys; sys.path.insert(0, sys.argv[1]); import _harness; "
    "_harness.RESULTS = pathlib.Path(sys.argv[2]); script = sys.argv[3]; sys.argv = [script, *sys.argv[4:]]; "
    "runpy.run_path(script, run_name='__main__')"
)


def run_cell(
    bench: Benchmark, argv: list[str], *, threads: int | None, out: pathlib.Path, timeout: float
) -> tuple[dict | None, dict]:
    """Run one benchmark process; returns its report (None if it failed) and the cell record."""
    out.mkdir(parents=True, exist_ok=True)
    script = HERE / f"{bench.script or bench.name}.py"
    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(ROOT))
    preexec = None
    if threads is not None:
        env.update(
            {
                v: str(threads)
                for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
            }
        )
        cores = (
            sorted(os.sched_getaffinity(0))[:threads] if hasattr(os, "sched_getaffinity") else None
        )
        if cores and len(cores) < threads:
            raise SystemExit(f"--threads {threads}: only {len(cores)} cores available")
        if cores:

            def preexec():
                os.sched_setaffinity(0, cores)

    cmd = [sys.executable, "-c", _BOOT, str(HERE), str(out), str(script), *argv]
    if "--out" not in argv and _takes_out(script):
        cmd += ["--out", str(out)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            cmd,
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout,
            preexec_fn=preexec,
        )
        rc, log = proc.returncode, proc.stdout[-2000:] + proc.stderr[-4000:]
    except subprocess.TimeoutExpired as err:
        rc, log = -1, f"timed out after {timeout} s\n{(err.stdout or b'')[-2000:]!r}"
    cell = {
        "benchmark": bench.name,
        "argv": argv,
        "threads": threads,
        "returncode": rc,
        "wall_s": time.perf_counter() - t0,
    }
    path = out / f"{bench.report or bench.name}.json"
    if rc != 0 or not path.is_file():
        cell["log"] = log
        return None, cell
    return json.loads(path.read_text()), cell


def _takes_out(script: pathlib.Path) -> bool:
    return '"--out"' in script.read_text()


def load_average() -> float | None:
    """The 1-minute load average (None where the platform has none)."""
    try:
        return os.getloadavg()[0]
    except (OSError, AttributeError):
        return None


def _cores() -> int:
    return os.cpu_count() or 1


def _warn(message: str, log: Callable[[str], Any]) -> None:
    """A warning to stderr, and to the sweep log when that is not stdout's ``print``."""
    print(f"warning: {message}", file=sys.stderr, flush=True)
    if log is not print:
        log(f"  WARNING: {message}")


def sweep(
    names: Sequence[str],
    *,
    sizes: Sequence[str] | None = None,
    dtypes: Sequence[str] | None = None,
    presets: Sequence[str] | None = None,
    threads: Sequence[int] | None = None,
    repeats: int = 1,
    quick: bool = False,
    out: pathlib.Path,
    timeout: float = 3600,
    log=print,
) -> dict:
    """Run every benchmark in ``names`` over the grid; returns (and writes) the sweep document.

    Sizes of a script that takes one size per run (``per_size``) become one process each; the
    others get all sizes in one process. ``quick`` replaces the sizes by each script's tiny ones.

    Warnings: a cell that starts or ends with the 1-minute load average above the core count (its
    times include waiting for a core) goes to stderr (and ``log`` when that is not ``print``) and is
    recorded in the cell and in ``machine["load_warnings"]``; a timed figure whose size cannot be
    determined (:func:`unsized_figures`) goes to ``log``.
    """
    unknown = [n for n in names if n not in BENCHMARKS]
    if unknown:
        raise SystemExit(f"unknown benchmarks {unknown}; known: {', '.join(BENCHMARKS)}")
    machine, versions = machine_and_versions()
    commit = git_commit()
    figures, cells, load_warnings = [], [], []
    cores = _cores()
    out.mkdir(parents=True, exist_ok=True)
    work = out / "cells"  # each cell's own report, as the script wrote it
    for name in names:
        bench = BENCHMARKS[name]
        if quick and bench.quick_args is None:
            log(f"skip {name}: no quick settings")
            continue
        size_groups = (
            [None]
            if quick or not sizes
            else ([[s] for s in sizes] if bench.per_size else [list(sizes)])
        )
        grid = itertools.product(
            size_groups, dtypes or [None], presets or [None], threads or [None], range(repeats)
        )
        for group, dtype, preset, nthreads, rep in grid:
            argv = _cell_argv(bench, group, dtype, preset, quick)
            cell_dir = work / f"{name}-{len(cells):03d}"
            log(f"run {name} {' '.join(argv)} threads={nthreads} repeat={rep}")
            load_start = load_average()
            report, cell = run_cell(bench, argv, threads=nthreads, out=cell_dir, timeout=timeout)
            cell.update(load_start=load_start, load_end=load_average())
            cells.append(cell)
            for when in ("start", "end"):
                load = cell[f"load_{when}"]
                if load is not None and load > cores:
                    record = {"benchmark": name, "argv": argv, "when": when, "load": load}
                    load_warnings.append(record | {"cores": cores})
                    _warn(_load_line(record, cores), log)
            if report is None:
                log(f"  FAILED (exit {cell['returncode']}):\n{cell.get('log', '')}")
                continue
            params = {"dtype": dtype, "preset": preset, "threads": nthreads}
            params = {k: v for k, v in params.items() if v is not None}
            ran_on = dict(machine, devices=report.get("machine", {}).get("devices"))
            new = figures_from_report(
                report, params=params, machine=ran_on, versions=versions, commit=commit
            )
            for fig in unsized_figures(new):
                log(f"  WARNING: {_unsized_line(fig)}")
            figures += new
    doc = {
        "schema": SCHEMA,
        "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "commit": commit,
        "machine": dict(machine, load_warnings=load_warnings) if load_warnings else machine,
        "versions": versions,
        "figures": merge_repeats(figures),
        "cells": cells,
    }
    return doc


def _load_line(record: dict, cores: int) -> str:
    return (
        f"load average {record['load']:.2f} > {cores} cores at the {record['when']} of "
        f"{record['benchmark']} {' '.join(record['argv'])}: its times include waiting for a core"
    )


def import_results(
    names: Sequence[str] | None = None, folder: pathlib.Path = HERE / "results"
) -> dict:
    """The committed ``results/<name>.json`` of the scripts as one sweep document (the adapter)."""
    figures = []
    for path in sorted(folder.glob("*.json")):
        report = _as_report(json.loads(path.read_text()), path)
        if report is None or (names and report.get("name") not in names):
            continue
        info = report.get("machine", {})
        versions = {
            k: info.get(k)
            for k in ("python", "jax", "jaxlib", "flax", "optax", "numpy")
            if k in info
        }
        figures += figures_from_report(report, machine=info, versions=versions, commit=None)
    return {
        "schema": SCHEMA,
        "created": None,
        "commit": None,
        "machine": {},
        "versions": {},
        "figures": figures,
        "cells": [],
    }


def _as_report(data: Any, path: pathlib.Path) -> dict | None:
    """A script's JSON as a ``_harness`` report: a report as it is, a bare list of rows named after
    the file (``surfacecnn.quality.json``), anything else None."""
    if isinstance(data, dict) and isinstance(data.get("rows"), list):
        return data
    if isinstance(data, list) and data and all(isinstance(r, dict) for r in data):
        return {"name": path.name.removesuffix(".json"), "rows": data}
    return None


def load_sweep(path: str | os.PathLike) -> dict:
    """A sweep document, or a script's own report converted by the adapter."""
    doc = json.loads(pathlib.Path(path).read_text())
    if isinstance(doc, dict) and doc.get("schema") == SCHEMA:
        return doc
    report = _as_report(doc, pathlib.Path(path))
    if report is not None:
        return {"schema": SCHEMA, "figures": figures_from_report(report), "cells": []}
    raise SystemExit(f"{path}: neither a {SCHEMA} sweep nor a benchmark report")


def _fmt(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def warnings_of(doc: dict) -> list[str]:
    """The sweep's warnings as lines: cells run under a load above the core count, and timed
    figures whose size could not be determined."""
    cores = (doc.get("machine") or {}).get("cpu_count") or _cores()
    lines = [
        _load_line(w, w.get("cores", cores))
        for w in (doc.get("machine") or {}).get("load_warnings", [])
    ]
    return lines + [_unsized_line(f) for f in unsized_figures(doc["figures"])]


def markdown(doc: dict) -> str:
    """The sweep as markdown: warnings, one table of every figure (benchmark, name, params, seconds
    (± spread), ceiling, ratio) and a *Growth* table (every series with two sizes or more: the sizes
    used, the fitted exponent ± its 95 % confidence half-width, the number of points)."""
    machine = {k: v for k, v in (doc.get("machine") or {}).items() if k != "load_warnings"}
    lines = [
        f"# benchmark sweep ({doc.get('created') or 'imported'})",
        "",
        f"commit `{doc.get('commit')}`, machine `{json.dumps(machine)}`, "
        f"versions `{json.dumps(doc.get('versions', {}))}`",
        "",
    ]
    warnings = warnings_of(doc)
    if warnings:
        lines += ["## Warnings", "", *(f"- warning: {w}" for w in warnings), ""]
    lines += [
        "| benchmark | figure | params | seconds | repeats | spread | ceiling | ratio to ceiling |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for f in doc["figures"]:
        params = ", ".join(f"{k}={_fmt(v)}" for k, v in f["params"].items() if v is not None)
        runs = f.get("runs") or []
        spread = (
            (max(runs) - min(runs)) / statistics.median(runs)
            if len(runs) > 1 and statistics.median(runs)
            else None
        )
        ceiling = (
            f"{f['ceiling']['kind']} = {_fmt(f['ceiling']['value'])}" if f.get("ceiling") else ""
        )
        lines.append(
            f"| {f['benchmark']} | {f['name']} | {params} | {_fmt(f.get('seconds'))} | {len(runs)} | "
            f"{_fmt(spread)} | {ceiling} | {_fmt(f.get('ratio_to_ceiling'))} |"
        )
    failed = [c for c in doc.get("cells", []) if c["returncode"] != 0]
    if failed:
        lines += [
            "",
            "Failed cells: "
            + "; ".join(
                f"{c['benchmark']} {' '.join(c['argv'])} (exit {c['returncode']})" for c in failed
            ),
        ]
    fits = growth_table(doc)
    if fits:
        lines += [
            "",
            "## Growth",
            "",
            "Least-squares slope of log seconds against log size per series (1: linear); ± the 95 % "
            "confidence half-width (Student t on points - 2 degrees of freedom; none from 2 points).",
            "",
            "| series | sizes n | exponent ± 95 % CI | points |",
            "|---|---|---|---|",
        ]
        lines += [
            f"| {label} | {', '.join(_fmt_n(n) for n in fit.sizes)} | {_fmt_fit(fit)} | "
            f"{fit.points} |"
            for label, fit in fits.items()
        ]
    return "\n".join(lines) + "\n"


class GrowthFit(NamedTuple):
    """A growth exponent fitted to one series.

    Attributes:
      exponent: the least-squares slope of ``log t`` against ``log n``.
      half_width: the half-width of its confidence interval (Student t on ``points - 2`` degrees
        of freedom); None from 2 points, where a line fits exactly and says nothing of its error.
      points: the (size, seconds) pairs the fit used (positive ones).
      sizes: the distinct sizes among them, ascending.
    """

    exponent: float
    half_width: float | None
    points: int
    sizes: tuple[float, ...]


def growth_fit(
    ns: Sequence[float], seconds: Sequence[float], *, confidence: float = 0.95
) -> GrowthFit | None:
    """Slope of ``log t`` against ``log n`` with its confidence half-width; None below 2 sizes.

    The half-width is ``t_{(1+confidence)/2, m-2} · se`` with ``se² = Σr² / ((m-2) Σ(x-x̄)²)``
    over the ``m`` points' residuals ``r`` (the textbook interval of a regression slope).
    Non-positive sizes or times are left out.

    Example:
      >>> fit = growth_fit([1e3, 1e4, 1e5], [1e-3, 1e-1, 1e1])
      >>> round(fit.exponent, 6), round(fit.half_width, 6), fit.points
      (2.0, 0.0, 3)
      >>> growth_fit([1e3, 1e4], [1e-3, 1e-2]).half_width is None
      True
      >>> fit = growth_fit([1, 2, 4, 8], [1.0, 2.2, 3.9, 8.3])
      >>> round(fit.exponent, 3), round(fit.half_width, 3)
      (0.999, 0.178)
    """
    if not 0 < confidence < 1:
        raise ValueError(f"growth_fit: confidence is in (0, 1), got {confidence}")
    used = [(n, t) for n, t in zip(ns, seconds, strict=True) if n and t and n > 0 and t > 0]
    pts = [(math.log(n), math.log(t)) for n, t in used]
    if len({x for x, _ in pts}) < 2:
        return None
    m = len(pts)
    mx = sum(x for x, _ in pts) / m
    my = sum(y for _, y in pts) / m
    sxx = sum((x - mx) ** 2 for x, _ in pts)
    slope = sum((x - mx) * (y - my) for x, y in pts) / sxx
    half = None
    if m > 2:
        rss = sum((y - my - slope * (x - mx)) ** 2 for x, y in pts)
        half = t_quantile((1 + confidence) / 2, m - 2) * math.sqrt(rss / (m - 2) / sxx)
    return GrowthFit(slope, half, m, tuple(sorted({n for n, _ in used})))


def growth_exponent(ns: Sequence[float], seconds: Sequence[float]) -> float | None:
    """Least-squares slope of ``log t`` against ``log n`` (1: linear). None with fewer than 2 sizes.

    Example:
      >>> round(growth_exponent([1e3, 1e4, 1e5], [1e-3, 1e-1, 1e1]), 6)
      2.0
    """
    fit = growth_fit(ns, seconds)
    return None if fit is None else fit.exponent


def t_quantile(p: float, df: int) -> float:
    """The ``p`` quantile (``p >= 0.5``) of Student's t with ``df`` degrees of freedom (SciPy's).

    Example:
      >>> [round(t_quantile(0.975, df), 3) for df in (1, 2, 3, 10, 30)]
      [12.706, 4.303, 3.182, 2.228, 2.042]
    """
    if not 0.5 <= p < 1 or df < 1:
        raise ValueError(f"t_quantile: needs 0.5 <= p < 1 and df >= 1, got p={p}, df={df}")
    from scipy import stats

    return float(stats.t.ppf(p, df))


def _fmt_fit(fit: GrowthFit) -> str:
    if fit.half_width is None:
        return f"{fit.exponent:.2f} (2 points: no interval)"
    return f"{fit.exponent:.2f} ± {fit.half_width:.2f}"


def _series_label(fig: dict) -> str:
    rest = [f"{k}={v}" for k, v in fig["params"].items() if k not in _NOT_SERIES and v is not None]
    return f"{fig['benchmark']}: {fig['name']}" + (f" ({', '.join(rest)})" if rest else "")


def _series(doc: dict) -> dict[str, list[tuple[float, float]]]:
    """Timed figures with a size grouped by :func:`series_key`: ``label -> [(n, seconds), ...]``
    (figures without a size are :func:`unsized_figures`'s business)."""
    series: dict[str, list[tuple[float, float]]] = {}
    labels: dict[str, str] = {}
    for f in doc["figures"]:
        if f["seconds"] is None or not f["params"].get("n"):
            continue
        label = labels.setdefault(series_key(f), _series_label(f))
        series.setdefault(label, []).append((float(f["params"]["n"]), f["seconds"]))
    return series


def growth_table(doc: dict) -> dict[str, GrowthFit]:
    """:func:`growth_fit` of every series of the sweep with at least two sizes, by series label.

    Example:
      >>> fig = lambda n, t: {"benchmark": "op", "name": "fwd", "params": {"n": n}, "seconds": t}
      >>> fits = growth_table({"figures": [fig(1e3, 1.0), fig(2e3, 2.0), fig(4e3, 4.0), fig(500, None)]})
      >>> [(label, round(f.exponent, 6), f.points) for label, f in fits.items()]
      [('op: fwd', 1.0, 3)]
    """
    fits = {label: growth_fit(*zip(*pts, strict=True)) for label, pts in _series(doc).items()}
    return {label: fit for label, fit in fits.items() if fit is not None}


def plot(doc: dict, out: pathlib.Path) -> list[pathlib.Path]:
    """``scaling.png``: log–log time against size per series with its fitted growth exponent ± its
    95 % confidence half-width (the Growth table of :func:`markdown`); ``ceiling.png``: bars of the fraction of the ceiling each figure reached."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    series = {k: sorted(v) for k, v in _series(doc).items() if len({n for n, _ in v}) >= 2}
    benches = sorted({label.split(":")[0] for label in series})
    if benches:
        cols = min(3, len(benches))
        rows = -(-len(benches) // cols)
        fig, axes = plt.subplots(rows, cols, figsize=(6 * cols, 4.5 * rows), squeeze=False)
        for ax, bench in zip(axes.ravel(), benches, strict=False):
            for label, pts in series.items():
                if label.split(":")[0] != bench:
                    continue
                ns, ts = zip(*pts, strict=True)
                fit = growth_fit(ns, ts)
                text = "" if fit is None else f"  (n^{_fmt_fit(fit)}, {fit.points} points)"
                ax.loglog(ns, ts, "o-", label=f"{label.split(': ', 1)[1]}{text}")
            ax.set_title(bench)
            ax.set_xlabel("size n")
            ax.set_ylabel("seconds")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
        for ax in axes.ravel()[len(benches) :]:
            ax.axis("off")
        fig.tight_layout()
        paths.append(out / "scaling.png")
        fig.savefig(paths[-1], dpi=90)
        plt.close(fig)
    bars = [
        (
            f"{f['benchmark']}: {f['name']} [{_fmt(f['params'].get('size') or f['params'].get('n'))}]",
            f["ratio_to_ceiling"],
            f["ceiling"]["kind"],
        )
        for f in doc["figures"]
        if f.get("ratio_to_ceiling") is not None
    ]
    if bars:
        fig, ax = plt.subplots(figsize=(11, 0.28 * len(bars) + 1.5))
        colors = ["tab:blue" if kind == "matmul_gflops" else "tab:orange" for _, _, kind in bars]
        ax.barh(range(len(bars)), [r for _, r, _ in bars], color=colors)
        ax.set_yticks(range(len(bars)), [label for label, _, _ in bars], fontsize=7)
        ax.invert_yaxis()
        ax.axvline(1.0, color="k", lw=0.8)
        ax.set_xlabel(
            "fraction of the same run's ceiling (blue: matmul GFLOP/s, orange: copy GB/s)"
        )
        fig.tight_layout()
        paths.append(out / "ceiling.png")
        fig.savefig(paths[-1], dpi=90)
        plt.close(fig)
    return paths

"""The test suite's budget: wall and CPU time of a pytest run, per folder, so growth is seen.

Usage (from the repository root)::

    python -m benchmarks.suite                          # the README's run: pytest -n 2
    python -m benchmarks.suite --out /tmp/s -- tests/io -n 0    # any pytest arguments after --
    python -m benchmarks.suite --seeds 30 --out /tmp/sweep -- tests/ops -k "not slow"  # seed sweep

Runs pytest with ``--durations=0 -p no:cacheprovider --junitxml`` and this module as a plugin,
which records every test's process CPU time (all threads: XLA compiles in its own), wall time and
the time JAX reports compiling (``jax.monitoring``) in its worker, setup and teardown included (a
session fixture counts in the first test that takes it). Writes ``suite.json`` (machine, versions,
totals, per folder and the 25 slowest tests) and ``suite.md`` into ``--out`` (default
``benchmarks/results/``). Figures depend on the machine's load for wall time only; compare CPU time
across runs.

``--records`` also writes every test's record (``records.jsonl``: node id, CPU, wall and compile
seconds, the eight jitted functions that took longest to compile, worker) for a closer look than
the 25 slowest.

``--seeds N`` is a flakiness sweep (not for CI): every test that takes the ``seed`` fixture
(directly or through ``key``/``rng``) runs once per seed ``0 .. N-1`` in one process, and
``sweep.json`` / ``sweep.md`` list each such test's failing seeds (replay one with
``JMESHTEX_SEED=<seed>``).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import pathlib
import platform
import resource
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET

import pytest

_ENV = "JMESHTEX_SUITE_TIMES"
_SEEDS = "JMESHTEX_SWEEP_SEEDS"


def _write_record(line: dict) -> None:
    path = os.environ.get(_ENV)
    if path:
        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        with open(f"{path}.{worker}", "a") as f:
            f.write(json.dumps({**line, "worker": worker}) + "\n")


def pytest_generate_tests(metafunc):
    """Under ``--seeds N``, parametrize the ``seed`` fixture of every test that takes it."""
    n = int(os.environ.get(_SEEDS, "0"))
    if not n or "seed" not in metafunc.fixturenames:
        return
    for m in metafunc.definition.iter_markers("parametrize"):
        names = m.args[0].split(",") if isinstance(m.args[0], str) else m.args[0]
        if "seed" in [name.strip() for name in names]:
            return  # the test chooses its own seeds
    metafunc.parametrize("seed", range(n), ids=[f"sweep{s}" for s in range(n)])


def pytest_runtest_logreport(report):
    if report.failed:
        _write_record({"nodeid": report.nodeid, "failed": report.when})


#: JAX's own timings of a compilation (tracing, lowering to MLIR, XLA's backend compile)
_COMPILE_EVENTS = (
    "/jax/core/compile/jaxpr_trace_duration",
    "/jax/core/compile/jaxpr_to_mlir_module_duration",
    "/jax/core/compile/backend_compile_duration",
)
_compile_s = [0.0]
#: the compile seconds of the running test per jitted function name (``records.jsonl``)
_compiled_functions: collections.Counter = collections.Counter()
#: the times a record holds, summed per folder
_TIMES = ("cpu_s", "wall_s", "compile_s")


def _on_duration(event: str, duration: float, fun_name: str = "?", **_) -> None:
    if event in _COMPILE_EVENTS:
        _compile_s[0] += duration
        _compiled_functions[fun_name] += duration


def pytest_configure(config):
    if os.environ.get(_ENV):
        import jax.monitoring

        jax.monitoring.register_event_duration_secs_listener(_on_duration)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """Record ``nodeid, cpu_s, wall_s, compile_s`` of one test (plugin side; active when ``$_ENV``
    is set). ``compile_s`` is the wall time JAX reports tracing, lowering and compiling (a
    persistent-cache hit skips the backend compile)."""
    cpu, wall, compiled = time.process_time(), time.perf_counter(), _compile_s[0]
    _compiled_functions.clear()
    yield
    _write_record(
        {
            "nodeid": item.nodeid,
            "cpu_s": time.process_time() - cpu,
            "wall_s": time.perf_counter() - wall,
            "compile_s": _compile_s[0] - compiled,
            "compiled": {k: round(v, 3) for k, v in _compiled_functions.most_common(8)},
        }
    )


def folder_of(nodeid: str) -> str:
    """``tests/io/test_x.py::t`` → ``tests/io``; ``jmeshtex/ops/_x.py::d`` → ``jmeshtex (doctests)``.

    Example:
      >>> folder_of("tests/io/test_obj.py::test_read"), folder_of("equivariance_tests/test_a.py::t")
      ('tests/io', 'equivariance_tests')
      >>> folder_of("jmeshtex/ops/_conv.py::jmeshtex.ops._conv.f")
      'jmeshtex (doctests)'
    """
    parts = nodeid.split("::")[0].split("/")
    if parts[0] == "jmeshtex":
        return "jmeshtex (doctests)"
    if parts[0] == "tests" and len(parts) > 2:
        return "/".join(parts[:2])
    return parts[0]


def summarise(records: list[dict], *, wall_s: float, cpu_s: float, outcome: dict) -> dict:
    """Totals and per-folder sums of the per-test records.

    Example:
      >>> r = [{"nodeid": "tests/io/a.py::t", "cpu_s": 2.0, "wall_s": 3.0}]
      >>> summarise(r, wall_s=5.0, cpu_s=4.0, outcome={})["folders"]["tests/io"]
      {'tests': 1, 'cpu_s': 2.0, 'wall_s': 3.0, 'compile_s': 0.0}
    """
    folders: dict = collections.defaultdict(lambda: {"tests": 0, **dict.fromkeys(_TIMES, 0.0)})
    for r in records:
        f = folders[folder_of(r["nodeid"])]
        f["tests"] += 1
        for k in _TIMES:
            f[k] += r.get(k, 0.0)
    slowest = sorted(records, key=lambda r: -r["cpu_s"])[:25]
    return {
        "machine": {
            "platform": platform.platform(),
            "python": platform.python_version(),
            "cpus": os.cpu_count(),
            "load_before": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
        },
        "wall_s": wall_s,
        "cpu_s": cpu_s,
        "outcome": outcome,
        "folders": {
            k: {**v, **{t: round(v[t], 2) for t in _TIMES}}
            for k, v in sorted(folders.items(), key=lambda kv: -kv[1]["cpu_s"])
        },
        "slowest": [
            {k: (round(v, 2) if isinstance(v, float) else v) for k, v in r.items()} for r in slowest
        ],
    }


def markdown(doc: dict) -> str:
    """``suite.md``: totals, a table per folder, the slowest tests."""
    o = doc["outcome"]
    lines = [
        "# Test suite budget",
        "",
        f"{doc['machine']['platform']}, Python {doc['machine']['python']}, "
        f"{doc['machine']['cpus']} CPUs, load {doc['machine']['load_before']}",
        "",
        f"Wall {doc['wall_s']:.0f} s, CPU {doc['cpu_s']:.0f} s (pytest and its workers); "
        + ", ".join(f"{v} {k}" for k, v in o.items()),
        "",
        "| folder | tests | CPU s | wall s | JAX compile s |",
        "|---|---:|---:|---:|---:|",
    ]
    for k, v in doc["folders"].items():
        lines.append(
            f"| {k} | {v['tests']} | {v['cpu_s']:.1f} | {v['wall_s']:.1f} "
            f"| {v.get('compile_s', 0.0):.1f} |"
        )
    total = sum(v.get("compile_s", 0.0) for v in doc["folders"].values())
    lines += [
        "",
        f"JAX compile (tracing, lowering, XLA; wall s inside the tests): {total:.0f} s in all.",
        "",
        "Slowest tests (CPU s; JAX compile s):",
        "",
    ]
    lines += [
        f"- {r['cpu_s']:.1f} s; {r.get('compile_s', 0.0):.1f} s `{r['nodeid']}`"
        for r in doc["slowest"]
    ]
    return "\n".join(lines) + "\n"


def seed_sweep(records: list[dict], failed: list[str], seeds: int) -> dict:
    """Per seeded test (its node id without the sweep's ``[sweepK]``), runs, CPU and failing seeds.

    Example:
      >>> recs = [{"nodeid": f"t.py::f[sweep{s}]", "cpu_s": 0.5} for s in range(3)]
      >>> seed_sweep(recs, ["t.py::f[sweep2]"], 3)["tests"]["t.py::f"]
      {'runs': 3, 'cpu_s': 1.5, 'failed_seeds': [2]}
    """
    import re

    tests: dict = {}
    for r in records:
        m = re.search(r"sweep(\d+)", r["nodeid"])
        if m is None:
            continue
        base = re.sub(r"\[sweep\d+\]", "", r["nodeid"])
        base = re.sub(r"(?<=\[)sweep\d+-|-sweep\d+(?=[\]-])", "", base)
        t = tests.setdefault(base, {"runs": 0, "cpu_s": 0.0, "failed_seeds": []})
        t["runs"] += 1
        t["cpu_s"] = round(t["cpu_s"] + r["cpu_s"], 2)
        if r["nodeid"] in failed:
            t["failed_seeds"].append(int(m.group(1)))
    return {"seeds": seeds, "tests": tests}


def sweep_markdown(sweep: dict) -> str:
    """``sweep.md``: the tests that failed on some seed first, then the count of those that did not."""
    bad = {k: v for k, v in sweep["tests"].items() if v["failed_seeds"]}
    lines = [
        f"# Seed sweep: {len(sweep['tests'])} seeded tests × {sweep['seeds']} seeds",
        "",
        f"{len(bad)} failed on some seed (replay with JMESHTEX_SEED=<seed>):",
        "",
    ]
    lines += [f"- `{k}`: seeds {v['failed_seeds']}" for k, v in bad.items()]
    return "\n".join(lines) + "\n"


def _outcome(junit: pathlib.Path) -> dict:
    if not junit.exists():
        return {}
    suites = ET.parse(junit).getroot()
    suites = [suites] if suites.tag == "testsuite" else list(suites)
    keys = ("tests", "failures", "errors", "skipped")
    return {k: sum(int(s.get(k, 0)) for s in suites) for k in keys}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.suite", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--out", type=pathlib.Path, default=pathlib.Path("benchmarks/results"))
    ap.add_argument(
        "--seeds", type=int, default=0, help="sweep: run every seeded test for seeds 0..N-1"
    )
    ap.add_argument(
        "--records", action="store_true", help="also write every test's record to records.jsonl"
    )
    ap.add_argument("pytest_args", nargs="*", help="pytest arguments (after --); default: -n 2")
    args = ap.parse_args(argv)
    extra = args.pytest_args or ["-n", "2"]
    with tempfile.TemporaryDirectory() as tmp:
        times = pathlib.Path(tmp) / "times"
        junit = pathlib.Path(tmp) / "junit.xml"
        cmd = [sys.executable, "-m", "pytest", "--durations=0", "-p", "no:cacheprovider"]
        cmd += ["-p", "benchmarks.suite", f"--junitxml={junit}", *extra]
        env = {**os.environ, _ENV: str(times), _SEEDS: str(args.seeds)}
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        rc = subprocess.call(cmd, env=env)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        lines = [
            json.loads(line)
            for p in sorted(pathlib.Path(tmp).glob("times.*"))
            for line in p.read_text().splitlines()
        ]
        records = [r for r in lines if "cpu_s" in r]
        doc = summarise(
            records, wall_s=round(wall, 1), cpu_s=round(cpu, 1), outcome=_outcome(junit)
        )
    doc["command"] = " ".join(["pytest", *cmd[3:]]).replace(str(junit), "<junit>")
    args.out.mkdir(parents=True, exist_ok=True)
    if args.records:
        (args.out / "records.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    if args.seeds:
        sweep = seed_sweep(records, [r["nodeid"] for r in lines if "failed" in r], args.seeds)
        (args.out / "sweep.json").write_text(json.dumps(sweep, indent=1))
        (args.out / "sweep.md").write_text(sweep_markdown(sweep))
        flaky = sum(1 for t in sweep["tests"].values() if t["failed_seeds"])
        print(f"{len(sweep['tests'])} seeded tests × {args.seeds} seeds: {flaky} failed on a seed")
        return rc
    (args.out / "suite.json").write_text(json.dumps(doc, indent=1))
    (args.out / "suite.md").write_text(markdown(doc))
    print(f"wall {wall:.0f} s, CPU {cpu:.0f} s; wrote {args.out / 'suite.json'}, suite.md")
    return rc


if __name__ == "__main__":
    sys.exit(main())

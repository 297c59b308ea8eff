"""Benchmark of the host geometry on tori of ~5K, 20K and 80K vertices.

Times each geometry builder (median of repeats after a warm-up, ``_harness.time_host``) and reports
seconds, microseconds per vertex and the growth exponent between consecutive sizes
(``log(t2/t1) / log(V2/V1)``: 1 is linear), next to the targets of the Foundation issue
(one-ring log maps + transport ≤ 5 s at 80K, k-NN (k = 8) ≤ 15 s at 80K, tracer ≥ 200K traces/s).
A builder that the library does not have yet is skipped with a printed note.

Usage::

    python benchmarks/geometry.py                       # 5K, 20K, 80K
    python benchmarks/geometry.py --sizes 2000,8000 --out /tmp/bench

Results: ``benchmarks/results/geometry.{json,md}`` (or ``--out``), with the load average and the BLAS
thread settings of the run. On a busy machine set ``OPENBLAS_NUM_THREADS=1``: ARPACK (HKS) with
spinning BLAS threads on oversubscribed cores runs several times slower (measured 10×+ at 5K).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import pathlib
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from _harness import Report, time_host

import jmeshtex.geometry as geometry
from jmeshtex.data import torus


@dataclasses.dataclass(frozen=True)
class Case:
    """One benchmarked builder: ``setup(v, f) -> args`` (untimed), then ``run(*args)`` is timed."""

    name: str
    needs: tuple[str, ...]
    run: Callable[..., Any]
    setup: Callable[[np.ndarray, np.ndarray], tuple] = lambda v, f: (v, f)
    repeats: int = 3
    target_s_at_80k: float | None = None
    items: Callable[[tuple], int] | None = None  # work items per call (e.g. traces), for a rate


def _g(name: str) -> Callable:
    return getattr(geometry, name)


def _trace_setup(v: np.ndarray, f: np.ndarray) -> tuple:
    n_dirs = 8
    vertex = np.repeat(np.arange(len(v)), n_dirs)
    direction = np.exp(2j * np.pi * np.tile(np.arange(n_dirs), len(v)) / n_dirs)
    length = 3.0 * geometry.mean_edge_length(v, f)  # a 3-ring walk, several face crossings each
    return v, f, vertex, direction, length, _g("tracer_geometry")(v, f)


CASES: list[Case] = [
    Case("validate_mesh", ("validate_mesh",), lambda v, f: _g("validate_mesh")(v, f)),
    Case(
        "one_ring_neighborhood (log + transport)",
        ("one_ring_neighborhood",),
        lambda v, f: _g("one_ring_neighborhood")(v, f),
        target_s_at_80k=5.0,
    ),
    Case("tangent_frames", ("tangent_frames",), lambda v, f: _g("tangent_frames")(v, f)),
    Case(
        "geodesic_knn_neighborhood (k = 8)",
        ("geodesic_knn_neighborhood",),
        lambda v, f: _g("geodesic_knn_neighborhood")(v, f, k=8),
        repeats=1,
        target_s_at_80k=15.0,
    ),
    Case(
        "tracer_geometry (tables)", ("tracer_geometry",), lambda v, f: _g("tracer_geometry")(v, f)
    ),
    Case(
        "trace_from_vertices (8 per vertex, 3 edges)",
        ("trace_from_vertices", "tracer_geometry"),
        lambda v, f, vertex, d, length, tables: _g("trace_from_vertices")(
            v, f, vertex, d, length, geometry=tables
        ),
        setup=_trace_setup,
        items=lambda args: len(args[2]),
    ),
    Case(
        "heat_kernel_signature (k = 100)",
        ("heat_kernel_signature",),
        lambda v, f: _g("heat_kernel_signature")(v, f, k=100),
        repeats=1,
    ),
    Case(
        "subdivide_midpoint", ("subdivide_midpoint",), lambda v, f: _g("subdivide_midpoint")(v, f)
    ),
    Case("mesh_hierarchy", ("mesh_hierarchy",), lambda v, f: _g("mesh_hierarchy")(v, f), repeats=1),
]

TRACES_PER_S_TARGET = 200_000


def bench_mesh(n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """A torus with about ``n_vertices`` vertices (``2m × m`` grid), mean edge length 1."""
    m = max(3, round(math.sqrt(n_vertices / 2)))
    v, f = torus(2 * m, m)
    v, _ = geometry.rescale_to_mean_edge(v, f, target=1.0)
    return v, f


def _label(n: int) -> str:
    return f"{n / 1000:g}K" if n >= 1000 else str(n)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="5000,20000,80000", help="comma-separated vertex counts")
    parser.add_argument(
        "--out", type=pathlib.Path, default=None, help="results folder (default benchmarks/results)"
    )
    parser.add_argument("--only", default=None, help="run only cases whose name contains this text")
    args = parser.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",") if s.strip()]

    report = Report("geometry")
    # host timings on a shared machine depend on load and on BLAS threads (eigsh): record both
    report.info["blas_threads_env"] = {
        k: os.environ.get(k) for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
    }
    report.info["loadavg_start"] = list(os.getloadavg())
    cases = [c for c in CASES if args.only is None or args.only in c.name]
    missing = {c.name: [n for n in c.needs if not hasattr(geometry, n)] for c in cases}
    for name, names in missing.items():
        if names:
            print(f"SKIP {name}: jmeshtex.geometry has no {', '.join(names)} yet", flush=True)
    cases = [c for c in cases if not missing[c.name]]

    previous: dict[str, tuple[int, float]] = {}
    for n in sizes:
        v, f = bench_mesh(n)
        print(f"-- torus with {len(v)} vertices, {len(f)} faces", flush=True)
        for case in cases:
            t0 = time.perf_counter()
            call_args = case.setup(v, f)
            setup_s = time.perf_counter() - t0
            timing = time_host(case.run, *call_args, repeats=case.repeats)
            row: dict[str, Any] = {
                "name": case.name,
                "size": _label(n),
                "vertices": len(v),
                "faces": len(f),
                "seconds": timing.run_s,
                "us_per_vertex": 1e6 * timing.run_s / len(v),
                "first_call_s": timing.runs[0],
                "setup_s": setup_s,
            }
            if case.name in previous:
                n0, t0_run = previous[case.name]
                row["growth_exponent"] = math.log(timing.run_s / t0_run) / math.log(len(v) / n0)
            previous[case.name] = (len(v), timing.run_s)
            if case.items is not None:
                rate = case.items(call_args) / timing.run_s
                row["items_per_s"] = rate
                row["target"] = f">= {TRACES_PER_S_TARGET:,} /s"
                row["meets_target"] = bool(rate >= TRACES_PER_S_TARGET)
            if case.target_s_at_80k is not None:
                row["target"] = f"<= {case.target_s_at_80k:g} s at 80K"
                if abs(len(v) - 80_000) / 80_000 < 0.05:
                    row["meets_target"] = bool(timing.run_s <= case.target_s_at_80k)
            report.add(**row)
    skipped = [name for name, names in missing.items() if names]
    if skipped:
        report.add(
            name="skipped (not in jmeshtex.geometry yet)",
            size="",
            vertices="",
            faces="",
            seconds=None,
            us_per_vertex=None,
            target=", ".join(skipped),
        )
    report.info["loadavg_end"] = list(os.getloadavg())
    report.write(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

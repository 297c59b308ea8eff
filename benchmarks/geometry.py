"""Benchmark of the host geometry on tori of ~5K, 20K and 80K vertices.

Times each geometry builder (median of repeats after a warm-up, ``_harness.time_host``) and reports
seconds, microseconds per vertex and the growth exponent between consecutive sizes
(``log(t2/t1) / log(V2/V1)``: 1 is linear), next to the targets of the Foundation issue
(one-ring log maps + transport ≤ 5 s at 80K, k-NN (k = 8) ≤ 15 s at 80K, tracer ≥ 200K traces/s).
A builder that the library does not have yet is skipped with a printed note.

With ``--eigen`` it benchmarks the eigen-solve instead, on real meshes (``../shared/data``
cow, subdivided to about the requested sizes): the sparse LU factorisation of
``L - σM`` under each fill-reducing ordering (fill and seconds), ``laplacian_eigenpairs`` (k = 100)
and ``heat_kernel_signature`` against the issue-36 target (≤ 10 s at 35K vertices on 2 cores).
Orderings other than the library's are timed only up to ``--ordering-max-vertices`` (the
minimum-degree ones take minutes at 35K).

Usage::

    python benchmarks/geometry.py                       # 5K, 20K, 80K
    python benchmarks/geometry.py --sizes 2000,8000 --out /tmp/bench
    python benchmarks/geometry.py --eigen               # 35K, 50K real meshes -> geometry_eigen.*

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


DATA = pathlib.Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
EIGEN_MESH = "cow.obj"
HKS_TARGET_S_AT_35K = 10.0


def real_mesh_near(name: str, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """A ``../shared/data`` mesh midpoint-subdivided (whole, then a prefix of faces) to ~n vertices."""
    import trimesh

    m = trimesh.load(DATA / name, process=True, force="mesh")
    v, f = np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)
    while True:
        v2, f2 = trimesh.remesh.subdivide(v, f)
        if len(v2) > n_vertices:
            break
        v, f = v2, f2
    # a partial subdivision adds ~1.5 vertices per split face (shared edge midpoints)
    idx = np.arange(min(len(f), max(0, int((n_vertices - len(v)) / 1.5))))
    if len(idx):
        v, f = trimesh.remesh.subdivide(v, f, face_index=idx)
    return np.asarray(v, np.float64), np.asarray(f, np.int32)


def eigen_main(args: argparse.Namespace) -> int:
    """The eigen-solve benchmark (``--eigen``): orderings, eigenpairs and HKS on real meshes."""
    import robust_laplacian
    import scipy
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    sizes = [int(s) for s in (args.sizes or "35000,50000").split(",") if s.strip()]
    report = Report("geometry_eigen")  # matmul and bandwidth ceilings measured in this run
    report.info["scipy"] = scipy.__version__
    report.info["blas_threads_env"] = {
        k: os.environ.get(k) for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
    }
    report.info["loadavg_start"] = list(os.getloadavg())
    for n in sizes:
        name = EIGEN_MESH
        v, f = real_mesh_near(name, n)
        print(f"-- {name} subdivided: {len(v)} vertices, {len(f)} faces", flush=True)
        base = {"mesh": name, "size": _label(n), "vertices": len(v), "faces": len(f)}
        L, M = robust_laplacian.mesh_laplacian(v, f, mollify_factor=1e-5)
        sigma = -1e-8 * float(np.mean(L.diagonal() / M.diagonal()))
        a = sp.csc_matrix(L - sigma * M)
        for spec in ("COLAMD", "MMD_AT_PLUS_A", "MMD_ATA"):
            if spec != "COLAMD" and len(v) > args.ordering_max_vertices:
                report.add(name=f"splu {spec}", **base, seconds=None, target="not run (too slow)")
                continue
            t0 = time.perf_counter()
            lu = spla.splu(a, permc_spec=spec)
            seconds = time.perf_counter() - t0
            fill = int(lu.L.nnz + lu.U.nnz)
            # the factor is written once: 12 bytes (value + index) per non-zero, a floor on traffic
            report.add(name=f"splu {spec}", **base, seconds=seconds, fill_nnz=fill, bytes=12 * fill)
        timing = time_host(lambda v=v, f=f: geometry.laplacian_eigenpairs(v, f, k=100), repeats=1)
        report.add(name="laplacian_eigenpairs (k = 100)", **base, seconds=timing.run_s)
        timing = time_host(lambda v=v, f=f: geometry.heat_kernel_signature(v, f, k=100), repeats=1)
        row = {"name": "heat_kernel_signature (k = 100)", **base, "seconds": timing.run_s}
        if abs(len(v) - 35_000) / 35_000 < 0.15:
            row["target"] = f"<= {HKS_TARGET_S_AT_35K:g} s at 35K"
            row["meets_target"] = bool(timing.run_s <= HKS_TARGET_S_AT_35K)
        report.add(**row)
    report.info["loadavg_end"] = list(os.getloadavg())
    report.write(args.out)
    return 0


def _label(n: int) -> str:
    return f"{n / 1000:g}K" if n >= 1000 else str(n)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--sizes",
        default=None,
        help="comma-separated vertex counts (default 5K,20K,80K; --eigen 35K,50K)",
    )
    parser.add_argument("--eigen", action="store_true", help="the eigen-solve benchmark instead")
    parser.add_argument(
        "--ordering-max-vertices",
        type=int,
        default=12_000,
        help="--eigen: time the non-default LU orderings only up to this many vertices",
    )
    parser.add_argument(
        "--out", type=pathlib.Path, default=None, help="results folder (default benchmarks/results)"
    )
    parser.add_argument("--only", default=None, help="run only cases whose name contains this text")
    args = parser.parse_args(argv)
    if args.eigen:
        return eigen_main(args)
    sizes = [int(s) for s in (args.sizes or "5000,20000,80000").split(",") if s.strip()]

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

"""Benchmark: DGTS training time per iteration per level, projected totals, and transfer time.

Run: ``.venv/bin/python benchmarks/dgts.py [--levels 4] [--iterations 300] [--measure 20]``.
Writes ``benchmarks/results/dgts.{json,md}``.

What is measured (float32, CPU, jit; compile time reported apart):

- ``prepare level l``: seconds per Adam step of the multi-scale fitting (PrepareConfig defaults);
- ``train level l``: seconds per WGAN-GP iteration (2 critic + 3 generator updates) with the
  default widths (TrainConfig: 7 layers, 32 → 128 channels), template icosphere(1) (80 faces) on
  a bumpy sphere, over ``--measure`` iterations; compilation (ahead of time, per level: the
  level's step and its newest frozen level) is timed apart. The totals of the small configuration
  (``levels × iterations``) and of the default one (``levels × 2000``) are projected from these
  per-iteration times plus the measured compile times plus the preparation as run here;
- ``cpu_s``: process CPU seconds of the same span (all threads): with other jobs on the machine,
  wall times grow but CPU seconds much less; ``load`` is the 1-minute load average at the start;
- ``transfer 20K``: one sample on a 20480-face icosphere running the last generator (no
  subdivision) and the last two (one subdivision, 82K output faces), after compilation.
"""

from __future__ import annotations

import argparse
import os
import time

import jax
import jax.numpy as jnp
import numpy as np
from _harness import Report, time_jax

from jmeshtex.data import icosphere
from jmeshtex.dgts import PrepareConfig, TrainConfig, train, training_meshes
from jmeshtex.data import bumpy_sphere
from jmeshtex.dgts._transfer import _prepare_target, _run_jit


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--levels", type=int, default=4)
    ap.add_argument("--iterations", type=int, default=300, help="iterations per level of the small config")
    ap.add_argument("--measure", type=int, default=30, help="timed iterations per level (projection basis)")
    ap.add_argument("--prepare-iterations", type=int, default=100)
    args = ap.parse_args()
    report = Report("dgts")

    t0 = time.perf_counter()
    prep = PrepareConfig(num_levels=args.levels, iterations=args.prepare_iterations)
    ends = {"start": t0}

    def progress(stage, done, total):
        if done >= total:
            ends[stage] = time.perf_counter()

    tm = training_meshes(bumpy_sphere(subdivisions=4), icosphere(1), config=prep, progress=progress)
    prep_s = time.perf_counter() - t0
    for level, f in enumerate(tm.faces):
        report.add(name=f"prepare level {level}", faces=len(f), steps=args.prepare_iterations,
                   seconds_incl_compile=ends[f"level {level}"] - ends[f"level {level - 1}" if level else "start"])

    cfg = TrainConfig(iterations=args.measure)
    load = os.getloadavg()[0]
    cpu0 = time.process_time()
    model, reports = train(tm, cfg, progress=False)
    report.add(name="train (all levels, measured)", seconds=sum(r.seconds for r in reports),
               cpu_s=time.process_time() - cpu0, load=load)
    small = default = 0.0
    for r in reports:
        report.add(name=f"train level {r.level}", faces=r.faces, seconds=r.seconds_per_iteration,
                   compile_s=r.compile_seconds, ms_per_iteration=1000 * r.seconds_per_iteration)
        small += r.compile_seconds + args.iterations * r.seconds_per_iteration
        default += r.compile_seconds + TrainConfig().iterations * r.seconds_per_iteration
    report.add(name=f"projected total small ({args.levels} levels x {args.iterations} it)",
               seconds=small + prep_s, target_s=600.0)
    report.add(name=f"projected total default ({args.levels} levels x 2000 it)", seconds=default + prep_s)

    v, f = icosphere(5)
    for start in (model.num_levels - 1, model.num_levels - 2):
        v0, _, _, _, n, geos, faces, sizes = _prepare_target(model, v, f, start)
        x = jnp.asarray(v0, jnp.float32)
        params = tuple(model.generators[start:])
        zs = [0.1 * jax.random.normal(jax.random.key(i), (s, 3), jnp.float32) for i, s in enumerate(sizes)]
        t = time_jax(lambda x, zs, geos=geos, params=params: _run_jit(model, x, geos, params, zs), x, zs, repeats=3)
        report.add(name=f"transfer 20K faces, {n} level(s)", faces_in=len(f), faces_out=len(faces[-1]),
                   seconds=t.run_s, compile_s=t.compile_s, target_s=5.0)
    report.write()


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()

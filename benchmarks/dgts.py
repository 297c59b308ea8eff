"""Benchmark: DGTS training time per iteration per level, projected totals, and transfer time.

Run: ``.venv/bin/python benchmarks/dgts.py [--levels 4] [--steps 300] [--measure 20]``.
Writes ``benchmarks/results/dgts.{json,md}``.

What is measured (float32, CPU, jit; compile time reported apart):

- ``prepare level l``: seconds per Adam step of the multi-scale fitting (PrepareConfig defaults);
- ``train level l``: seconds per WGAN-GP step (2 critic + 3 generator updates) with the
  default widths (``dgts.Config``: 7 layers, 32 → 128 channels), template icosphere(1) (80 faces) on
  a bumpy sphere, over ``--measure`` steps; compilation (ahead of time, per level: the
  level's step and its newest frozen level) is timed apart. The totals of the small configuration
  (``levels × steps``) and of the default one (``levels × 2000``) are projected from these
  per-step times plus the measured compile times plus the preparation as run here;
- ``cpu_s``: process CPU seconds of the same span (all threads): with other jobs on the machine,
  wall times grow but CPU seconds much less; ``load`` is the 1-minute load average at the start;
- ``transfer 20K``: one sample on a 20480-face icosphere running the last generator (no
  subdivision) and the last two (one subdivision, 82K output faces), after compilation
  (``dgts.plan_transfer`` once on the host, then ``dgts.run_plan`` timed).
"""

from __future__ import annotations

import argparse
import os
import time

import jax
import jax.numpy as jnp
import numpy as np
from _harness import Report, time_jax

from jmeshtex.data import bumpy_sphere, icosphere
from jmeshtex.dgts import Config, PrepareConfig, plan_transfer, run_plan, train, training_meshes


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--levels", type=int, default=4)
    ap.add_argument("--steps", type=int, default=300, help="training steps per level of the small config")
    ap.add_argument("--measure", type=int, default=30, help="timed steps per level (projection basis)")
    ap.add_argument("--prepare-steps", type=int, default=100)
    args = ap.parse_args()
    report = Report("dgts")

    t0 = time.perf_counter()
    prep = PrepareConfig(levels=args.levels, steps=args.prepare_steps)
    ends = {"start": t0}

    def progress(stage, done, total):
        if done >= total:
            ends[stage] = time.perf_counter()

    k_prepare, k_train, k_noise = jax.random.split(jax.random.key(0), 3)
    tm = training_meshes(bumpy_sphere(subdivisions=4), icosphere(1), config=prep, key=k_prepare, progress=progress)
    prep_s = time.perf_counter() - t0
    for level, f in enumerate(tm.faces):
        report.add(name=f"prepare level {level}", faces=len(f), steps=args.prepare_steps,
                   seconds_incl_compile=ends[f"level {level}"] - ends[f"level {level - 1}" if level else "start"])

    cfg = Config(steps=args.measure)
    load = os.getloadavg()[0]
    cpu0 = time.process_time()
    result = train(tm, cfg, key=k_train, progress=False)
    model, reports = result.model, result.extra["levels"]
    report.add(name="train (all levels, measured)", seconds=sum(r.seconds for r in reports),
               cpu_s=time.process_time() - cpu0, load=load)
    small = default = 0.0
    for r in reports:
        report.add(name=f"train level {r.level}", faces=r.faces, seconds=r.seconds_per_step,
                   compile_s=r.compile_seconds, ms_per_step=1000 * r.seconds_per_step)
        small += r.compile_seconds + args.steps * r.seconds_per_step
        default += r.compile_seconds + Config().steps * r.seconds_per_step
    report.add(name=f"projected total small ({args.levels} levels x {args.steps} steps)",
               seconds=small + prep_s, target_s=600.0)
    report.add(name=f"projected total default ({args.levels} levels x 2000 steps)", seconds=default + prep_s)

    target = icosphere(5)
    for start in (model.num_levels - 1, model.num_levels - 2):
        plan = plan_transfer(model, target, start_level=start)
        keys = jax.random.split(jax.random.fold_in(k_noise, start), len(plan.sizes))
        zs = [0.1 * jax.random.normal(k, (s, 3), jnp.float32) for k, s in zip(keys, plan.sizes, strict=True)]
        t = time_jax(lambda zs, plan=plan: run_plan(model, plan, zs), zs, repeats=3)
        report.add(name=f"transfer 20K faces, {len(plan.sizes)} level(s)", faces_in=target.num_faces,
                   faces_out=len(plan.faces[-1]), seconds=t.run_s, compile_s=t.compile_s, target_s=5.0)
    report.write()


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()

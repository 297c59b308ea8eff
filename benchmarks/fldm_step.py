"""Benchmark: FLDM training steps/s at 5K and 30K vertices, DDIM-50 sampling time at 30K vertices.

Run: ``python benchmarks/fldm_step.py [--sizes 5000 30000] [--measure 3] [--full-ddim]``.
Writes ``benchmarks/results/fldm_step.{json,md}``. (FLDM's results table on Spot is ``benchmarks/fldm.py``.)

What is measured (float32 / complex64, CPU, jit; compile time reported apart; random parameters and
tangent-noise latents — timings do not depend on the values):

- ``remesh``: host time of :func:`jmeshtex.geometry.remesh` to the size (one training copy), and of
  the denoiser geometry (k-NN neighbourhoods of two levels + pooling map);
- ``train``: seconds per optimiser step (ε-loss, Adam) for the paper denoiser (96/192 channels,
  2+4+4 FCResNet blocks, batch 1) and the CPU preset (32/64, 1+2+2, ReLU filters, batch 2);
  ``steps_per_s`` is its inverse;
- ``denoise``: one denoiser evaluation, beside its FLOP count (``fldm.core.denoiser_flops``) and the
  matmul ceiling measured in the same run: ``row_ceiling`` is the highest of the run's first
  ceiling and two more measured right before and after the row (this machine is shared, with steal
  time up to a third, so a single ceiling can be low and flatter the ratio); ``seconds`` is the
  median repeat, ``best_s`` the best one; ``x_bound`` = ``best_s`` / bound (best case against best
  case), ``x_bound_median`` the median's ratio; ``ddim50_s`` is 50 median evaluations (the sampler
  adds a few element-wise ops per step), ``bound_s`` the time the ceiling allows for 50;
  ``--full-ddim`` also runs the whole jitted DDIM-50 loop once for the CPU preset at the largest size;
  ``activations`` counts the filter nonlinearity's evaluations (``fldm.core.denoiser_activations``), and
  ``x_bound_act`` compares the best time with a bound that adds them at the activation's own
  ceiling (``silu_gevals`` / ``relu_gevals``; ``row_act_ceiling`` taken like ``row_ceiling``): a
  SiLU costs a tanh (a rational function with a division), which the FLOP count does not see;
- presets: ``paper`` (96/192, 2+4+4, SiLU filters as the reference), ``paper-relu`` (the same
  network with ReLU filters), ``cpu``;
- ``load``: the 1-minute load average at the start of each row (other jobs inflate wall times).
"""

from __future__ import annotations

import argparse
import os
import time

import jax
import jax.numpy as jnp
import numpy as np
from _harness import Report, activation_ceiling, matmul_ceiling, time_jax

from jmeshtex import fldm
from jmeshtex.data import icosphere
from jmeshtex.geometry import remesh, to_jax
from jmeshtex.ops import tangent_noise


def _load() -> float:
    return os.getloadavg()[0]


def _timed_between_ceilings(report: Report, activation: str, measure):
    """``measure()`` between two fresh ceiling measurements; its result and the highest matmul and
    activation ceilings of the run's first and these two (the machine is shared, with steal time up
    to a third: one low ceiling would flatter the ratio)."""
    before = matmul_ceiling(), activation_ceiling(activation)
    result = measure()
    after = matmul_ceiling(), activation_ceiling(activation)
    matmul = max(report.ceilings["matmul_gflops"], before[0], after[0])
    act = max(report.ceilings[f"{activation}_gevals"], before[1], after[1])
    return result, matmul, act


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[5000, 30000])
    ap.add_argument("--measure", type=int, default=3, help="timed repeats of each step")
    ap.add_argument("--presets", nargs="+", default=["paper", "paper-relu", "cpu"])
    ap.add_argument("--full-ddim", action="store_true")
    ap.add_argument(
        "--paper-train-max",
        type=int,
        default=5000,
        help="largest size for the paper-size training step (30K needs ~56 GB on the CPU: skipped)",
    )
    args = ap.parse_args()
    report = Report("fldm_step")
    for act in (
        "silu",
        "relu",
    ):  # the filter nonlinearity's own ceiling (FLOP counts do not see it)
        report.ceilings[f"{act}_gevals"] = activation_ceiling(act)
    print(f"activation ceilings: {report.ceilings}", flush=True)
    base = icosphere(6)  # 40962 vertices: both sizes are re-triangulations of it
    for n in args.sizes:
        t0 = time.perf_counter()
        copy = remesh(base, n_vertices=n, key=jax.random.key(0))
        report.add(name="remesh", vertices=n, seconds=time.perf_counter() - t0, load=_load())
        t0 = time.perf_counter()
        geo = fldm.core.denoiser_geometry(
            copy, knn=fldm.Config.paper().knn, pool_ratio=0.25
        )  # every preset: k = 8
        report.add(
            name="denoiser geometry", vertices=n, seconds=time.perf_counter() - t0, load=_load()
        )
        sizes = fldm.core.geometry_sizes(geo)
        for preset in args.presets:
            if (
                preset == "paper-relu"
            ):  # the paper's widths and blocks with piecewise-linear filters
                cfg = fldm.Config.paper(latent_channels=8, copy_vertices=n, activation="relu")
            else:
                cfg = getattr(fldm.Config, preset)(latent_channels=8, copy_vertices=n)
            if preset.startswith("paper"):
                cfg = cfg.replace(batch_size=1)
            # training step on a batch of copies (the same copy repeated: timing only)
            mu = np.asarray(tangent_noise(jax.random.key(0), (n, 8)), np.complex128)
            data = fldm.core.stack_copies([(copy, geo, mu, None)], cfg)
            params = fldm.core.init_denoiser(jax.random.key(0), cfg)
            opt_state = fldm.core.optimizer(cfg).init(params)
            step = fldm.core.make_train_step(cfg)
            z0, g, lab = fldm.core.training_batch(
                data, 0, cfg.batch_size, key=jax.random.key(5), dtype=jnp.complex64
            )
            key = jax.random.key(1)

            def run(params=params, opt_state=opt_state, z0=z0, g=g, lab=lab, step=step, key=key):
                return step(params, opt_state, z0, g, lab, key)[2]

            if preset.startswith("paper") and n > args.paper_train_max:
                report.add(
                    name=f"train {preset}",
                    vertices=n,
                    batch=cfg.batch_size,
                    note="skipped (memory)",
                )
                run = None
            load = _load()
            t = time_jax(run, repeats=args.measure, min_time=0.0) if run is not None else None
            if t is not None:
                report.add(
                    name=f"train {preset}",
                    vertices=n,
                    batch=cfg.batch_size,
                    compile_s=t.compile_s,
                    seconds=t.run_s,
                    steps_per_s=1.0 / t.run_s,
                    load=load,
                )
            # one denoiser evaluation, and DDIM-50 = 50 of them
            gj = to_jax(geo, jnp.float32)
            z = tangent_noise(jax.random.key(2), (n, 8))
            fn = jax.jit(
                lambda p, z, cfg=cfg, gj=gj: fldm.core.denoise(
                    p, cfg, z, jnp.array(500, jnp.int32), gj
                )
            )
            load = _load()
            t, ceiling, act_ceiling = _timed_between_ceilings(
                report,
                cfg.activation,
                lambda fn=fn, z=z, params=params: time_jax(
                    fn, params, z, repeats=args.measure, min_time=0.0
                ),
            )
            best = min(t.runs)
            flops = fldm.core.denoiser_flops(cfg, sizes["V0"], sizes["V1"])
            bound = flops / (ceiling * 1e9)
            acts = fldm.core.denoiser_activations(cfg, sizes["V0"], sizes["V1"])
            bound_act = bound + acts / (act_ceiling * 1e9)
            report.add(
                name=f"denoise {preset}",
                vertices=n,
                compile_s=t.compile_s,
                seconds=t.run_s,
                best_s=best,
                flops=flops,
                row_ceiling=ceiling,
                row_act_ceiling=act_ceiling,
                ddim50_s=50 * t.run_s,
                bound_s=50 * bound,
                x_bound=best / bound,
                x_bound_median=t.run_s / bound,
                activations=acts,
                x_bound_act=best / bound_act,
                load=load,
            )
            if args.full_ddim and preset == "cpu" and n == max(args.sizes):
                model = fldm.Model(params, cfg, np.ones(8))
                load = _load()
                t0 = time.perf_counter()
                fldm.sample(model, geo, key=jax.random.key(3), num_samples=1, steps=50)
                first = time.perf_counter() - t0
                t0 = time.perf_counter()
                fldm.sample(model, geo, key=jax.random.key(4), num_samples=1, steps=50)
                second = time.perf_counter() - t0
                report.add(
                    name="ddim50 cpu (full loop)",
                    vertices=n,
                    first_call_s=first,
                    seconds=second,
                    load=load,
                )
    report.write()


if __name__ == "__main__":
    main()

"""Study: where an FL-VAE training step's time goes (host batch building against the jitted step).

``python studies/fl_step_profile.py [--base JSON]``: CPU and wall seconds of the host stages
(textures and planar meshes; one-ring sampling, colours and corner logs) and the jitted step at
``Config.small(**BASE)``; ``--base`` may be a list of changes, one profile each. Writes
``studies/results/fl_vae_profile.{json,md}``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import jax
import numpy as np
from _fl import load
from _study import Report

from jmeshtex import fl


def step_profile(report, *, base: dict, steps: int = 6) -> None:
    """Where a training step's time goes: host batch building (meshes, one-ring sampling, colour
    lookup) against the jitted step, in CPU and wall seconds, at ``Config.small(**base)``."""
    config = fl.Config.small(**base)
    images = fl.training_images(max_size=config.max_image_size)
    n = config.batch_size * max(
        int(round(config.texture_size**2 / (config.pixels_per_vertex / config.density_spread))), 4
    )
    params = fl.init(config, key=jax.random.key(0)).params
    opt_state = fl.core.optimizer(config).init(params)
    train_step = fl.core.make_train_step(config)
    stages = {"meshes": [], "samples": [], "step": []}
    cpu = {k: [] for k in stages}
    for i in range(steps):
        rng = np.random.default_rng(i)
        c0, t0 = time.process_time(), time.perf_counter()
        # (training_meshes also builds each image's pyramid, which fl.train does once per run)
        meshes = fl.core.training_meshes(jax.random.key(i), config, images=images)
        c1, t1 = time.process_time(), time.perf_counter()
        batch = fl.core.mesh_batch(meshes, config, rng, num_vertices=n)
        c2, t2 = time.process_time(), time.perf_counter()
        params, opt_state, loss, aux = train_step(
            params, opt_state, batch, jax.random.key(i), np.int32(i)
        )
        jax.block_until_ready(loss)
        c3, t3 = time.process_time(), time.perf_counter()
        if i == 0:
            compile_s = t3 - t2
            continue
        for k, (a, b, ca, cb) in {
            "meshes": (t0, t1, c0, c1),
            "samples": (t1, t2, c1, c2),
            "step": (t2, t3, c2, c3),
        }.items():
            stages[k].append(b - a)
            cpu[k].append(cb - ca)
    for k in stages:
        report.add(
            table="step_profile",
            stage={
                "meshes": "host: textures + planar meshes",
                "samples": "host: one-ring sampling + colours + corner logs (mesh_batch)",
                "step": "jitted step (encoder, decoder, grad, Adam)",
            }[k],
            **{kk: v for kk, v in base.items()},
            padded_vertices=n,
            wall_s=round(float(np.median(stages[k])), 4),
            cpu_s=round(float(np.median(cpu[k])), 4),
            first_step_compile_s=round(compile_s, 1) if k == "step" else None,
            load=load(),
        )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--base", default="{}", help="JSON changes to Config.small (or a list of them)")
    ap.add_argument("--out", type=pathlib.Path, default=None, help="results folder")
    args = ap.parse_args(argv)
    base = json.loads(args.base)
    report = Report("fl_vae_profile")
    report.config = {"base": base}
    for one in base if isinstance(base, list) else [base]:
        step_profile(report, base=one)
    report.write(args.out)


if __name__ == "__main__":
    main()

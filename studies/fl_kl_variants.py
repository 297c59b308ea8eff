"""Study: KL control of the FL-VAE, short ``Config.small`` runs per variant.

``python studies/fl_kl_variants.py STEPS [--variants NAME,...] [--base JSON]``: one run of
``fl.Config.small(**BASE)`` per KL variant (``KL_VARIANTS``: lambda 0.01, warm-up over the first
half, free bits 0.25, lambda 1e-3), one at a time: per-channel KL, held-out PSNR next to the P1
codecs, CPU seconds per step. Writes ``studies/results/fl_vae_study.{json,md}``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import jax
import numpy as np
from _fl import held_out_quality, load
from _study import Report

from jmeshtex import fl

#: KL-control variants of the ``--study`` mode (changes to ``Config.small``)
KL_VARIANTS = {
    "lambda=0.01": {},
    "warm-up": {"kl_warmup_steps": -1},  # -1: the run's first half
    "free bits 0.25": {"free_bits": 0.25},
    "lambda=1e-3": {"kl_weight": 1e-3},
}


def study(report, *, steps: int, variants: dict, base: dict) -> None:
    """Short training runs of ``Config.small(**base)`` per variant: per-channel KL, held-out PSNR
    next to the P1 codecs, CPU seconds per step (one run at a time)."""
    for name, changes in variants.items():
        changes = dict(changes)
        if changes.get("kl_warmup_steps") == -1:
            changes["kl_warmup_steps"] = max(1, steps // 2)
        config = fl.Config.small(
            steps=steps, warmup_steps=min(50, steps // 4), checkpoint_every=steps, **base
        ).replace(**changes)
        cpu0, t0 = time.process_time(), time.perf_counter()
        r = fl.train(None, config, key=jax.random.key(0), progress=False)
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - t0
        kl = [float(np.mean(r.losses[f"kl{c}"][-50:])) for c in range(config.latent_dim)]
        quality = held_out_quality(r.model)
        report.add(
            table="study",
            variant=name,
            **{k: v for k, v in base.items()},
            steps=steps,
            kl_channels=" ".join(f"{x:.2f}" for x in kl),
            channels_above_0p1=sum(x > 0.1 for x in kl),
            l1_last50=round(float(np.mean(r.losses["l1"][-50:])), 4),
            **{k: round(float(v), 3) for k, v in quality.items()},
            cpu_s_per_step=round(cpu / steps, 3),
            wall_s=round(wall, 1),
            compile_s=round(r.compile_seconds, 1),
            load=load(),
        )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("steps", type=int, help="training steps per variant")
    ap.add_argument("--variants", default=None, help="comma-separated KL_VARIANTS names")
    ap.add_argument("--base", default="{}", help="JSON changes to Config.small")
    ap.add_argument("--out", type=pathlib.Path, default=None, help="results folder")
    args = ap.parse_args(argv)
    base = json.loads(args.base)
    report = Report("fl_vae_study")
    report.config = {"base": base, "study_steps": args.steps}
    names = args.variants.split(",") if args.variants else list(KL_VARIANTS)
    study(report, steps=args.steps, variants={n: KL_VARIANTS[n] for n in names}, base=base)
    report.write(args.out)


if __name__ == "__main__":
    main()

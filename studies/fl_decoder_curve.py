"""Study: the FL-VAE's log decoder against its barycentric ablation along one training run each.

``python studies/fl_decoder_curve.py 1000,2000,3000,5000 [--decoders log,barycentric] [--base JSON]
[--work runs/fl_vae_curve] [--tag TAG]``: one ``Config.small(**BASE)`` run per decoder, evaluated
at each step budget (held-out PSNR beside the P1 codecs, per-channel KL), resumable in
``WORK/<decoder>`` with each budget's model kept as ``WORK/<decoder>/step_NNNNN.npz`` (the shipped
weights are two of these snapshots: ``jmeshtex/fl/weights/README.md``). Writes
``studies/results/fl_vae_curve[_TAG].{json,md}``.
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


def curve(
    report, *, budgets: list[int], decoders: list[str], work: pathlib.Path, base: dict, out=None
):
    """One ``Config.small(**base)`` run per decoder, evaluated at each budget (held-out PSNR beside
    the P1 codecs, per-channel KL): the log decoder against its barycentric ablation as training
    goes on. Resumable: each run checkpoints in ``work/<decoder>`` and each budget's model is
    kept as ``work/<decoder>/step_NNNNN.npz``; a re-run with larger budgets continues the same runs
    (the learning-rate schedule is the preset's, so a budget is a point along one run)."""
    from jmeshtex.io import Checkpoints

    for decoder in decoders:
        config = fl.Config.small(decoder=decoder, checkpoint_every=min(budgets), **base)
        folder = work / decoder
        for budget in sorted(budgets):
            snapshot = folder / f"step_{budget:05d}.npz"
            cpu0, t0 = time.process_time(), time.perf_counter()
            kl = None
            if snapshot.is_file():
                model = fl.load(snapshot)
            else:
                with Checkpoints(folder) as ckpt:
                    done = ckpt.latest_step() or 0
                if done > budget:
                    print(f"[curve] {decoder}: the run is past {budget} steps without its snapshot")
                    continue
                r = fl.train(
                    None,
                    config,
                    key=jax.random.key(0),
                    checkpoint_dir=folder,
                    stop_after=budget - done,
                    progress=False,
                )
                model = r.model
                fl.save(model, snapshot)
                if len(r.losses["l1"]):
                    kl = [
                        float(np.mean(r.losses[f"kl{c}"][-50:])) for c in range(config.latent_dim)
                    ]
            train_cpu, train_wall = time.process_time() - cpu0, time.perf_counter() - t0
            quality = held_out_quality(model)
            report.add(
                table="curve",
                decoder=decoder,
                steps=budget,
                **{k: round(float(v), 3) for k, v in quality.items()},
                kl_channels=" ".join(f"{x:.2f}" for x in kl) if kl else None,
                channels_above_0p1=sum(x > 0.1 for x in kl) if kl else None,
                train_cpu_s=round(train_cpu, 1),
                train_wall_s=round(train_wall, 1),
                load=load(),
            )
            print(f"[curve] {decoder} {budget}: {quality}", flush=True)
            report.write(out)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("budgets", metavar="STEPS,...", help="comma-separated step budgets")
    ap.add_argument("--decoders", default="log,barycentric")
    ap.add_argument("--base", default="{}", help="JSON changes to Config.small")
    ap.add_argument("--tag", default=None, help="writes fl_vae_curve_TAG (a variant beside)")
    ap.add_argument(
        "--work",
        type=pathlib.Path,
        default=pathlib.Path(__file__).resolve().parents[1] / "runs" / "fl_vae_curve",
        help="the resumable runs, one folder per decoder",
    )
    ap.add_argument("--out", type=pathlib.Path, default=None, help="results folder")
    args = ap.parse_args(argv)
    base = json.loads(args.base)
    report = Report("fl_vae_curve" + (f"_{args.tag}" if args.tag else ""))
    report.config = {"base": base, "budgets": args.budgets}
    curve(
        report,
        budgets=[int(b) for b in args.budgets.split(",")],
        decoders=args.decoders.split(","),
        work=args.work,
        base=base,
        out=args.out,
    )


if __name__ == "__main__":
    main()

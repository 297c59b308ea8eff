"""Study: DGTS at depth, the paper's network trained on textured spheres.

``python studies/dgts_depth.py KIND [KIND ...] [--levels 4] [--steps 2000] [--template 1]
[--work runs/dgts_depth]``: the paper's network (``dgts.Config()``: 7 layers, 32 -> 128 channels)
trained STEPS per level on LEVELS levels (from an icosphere(TEMPLATE) template: 80 -> 5120 faces
at 4 levels from icosphere(1), 20 -> 5120 at 5 levels from icosphere(0)) of a textured sphere of each kind
(``DEPTH_TEXTURES``), resumable in ``WORK/<kind>/`` (fitted training meshes, checkpoints every 250
steps, ``model.npz``), then scored in-domain and transferred to the torus, the cow and fandisk
against their oracles. Writes ``studies/results/dgts_depth.{json,md}`` (the kinds of this run only)
with ``dgts_depth_<kind>.png`` (reference | training levels | in-domain | transfers vs oracle,
untrained and noise).
"""

from __future__ import annotations

import os
import pathlib
import time

import jax
import numpy as np
from _dgts import (
    DEPTH_TEXTURES,
    depth_meshes,
    evaluate,
    study_arguments,
    study_parser,
    untrained_weights,
)
from _study import RESULTS, Report

from jmeshtex.dgts import Config, train
from jmeshtex.dgts.core import (
    period_in_mean_edges,
)


def depth(
    kinds: list[str],
    *,
    levels: int,
    steps: int,
    work: pathlib.Path,
    samples: int,
    checkpoint_every: int = 250,
    train_only: bool = False,
    template: int = 1,
) -> None:
    """The paper's network (``dgts.Config()``: 7 layers, 32 → 128 channels, ``steps`` per level) on
    ``levels`` levels of each textured sphere, resumable in ``work/<kind>/`` (the fitted training
    meshes on an icosphere(``template``), checkpoints every ``checkpoint_every`` steps, the final
    ``model.npz``); then
    :func:`evaluate` into ``dgts_depth`` with one figure per kind (skipped with ``train_only``:
    ``benchmarks/dgts.py --model WORK/<kind>`` scores a finished model)."""
    from jmeshtex.dgts import save

    report = Report("dgts_depth")  # the kinds of this run only: no row outlives its run
    for kind in kinds:
        reference_period = DEPTH_TEXTURES[kind]
        folder = work / kind
        folder.mkdir(parents=True, exist_ok=True)
        t0, c0 = time.perf_counter(), time.process_time()
        reference, tm = depth_meshes(kind, levels, folder, template=template)
        prepare = (time.perf_counter() - t0, time.process_time() - c0)
        cfg = Config(steps=steps, checkpoint_every=checkpoint_every)
        t0, c0 = time.perf_counter(), time.process_time()
        result = train(
            tm,
            cfg,
            key=jax.random.key(0),
            checkpoint_dir=folder / "checkpoints",
        )
        trained = result.model
        save(trained, folder)  # folder/model.npz
        if train_only:
            print(f"{kind}: trained, {folder / 'model.npz'}", flush=True)
            continue
        untrained = untrained_weights(tm, cfg)
        period = period_in_mean_edges(tm, reference_period)
        tag = f"[{kind} {levels} levels, period {period:.2f} edges] "
        report.add(
            name=f"{tag}prepare + train (paper network)",
            faces=len(tm.faces[-1]),
            steps_per_level=steps,
            prepare_s=prepare[0],
            prepare_cpu_s=prepare[1],
            train_s=time.perf_counter() - t0,
            train_cpu_s=time.process_time() - c0,
            resumed_from=result.resumed_from,
            period_mean_edges=period,
            load=os.getloadavg()[0],
        )
        evaluate(
            report,
            tag,
            trained,
            untrained,
            tm,
            reference,
            kind,
            reference_period,
            samples=samples,
            png=RESULTS / f"dgts_depth_{kind}.png",
            real=("cow", "fandisk"),
            title=f"DGTS, paper network, {levels} levels ({kind}, period {period:.2f} mean edges)",
        )
        report.write()


def main(argv: list[str] | None = None) -> None:
    ap = study_parser(__doc__, kind=False, train_levels=4)
    ap.add_argument("kinds", nargs="+", choices=sorted(DEPTH_TEXTURES))
    ap.add_argument(
        "--train-only",
        action="store_true",
        help="fit, train and save WORK/<kind>/model.npz; no scoring (resumable as it is)",
    )
    ap.add_argument(
        "--template",
        type=int,
        default=1,
        help="icosphere subdivisions of the coarsest level (0: 20 faces, 1: 80)",
    )
    args = ap.parse_args(argv)
    depth(
        args.kinds,
        train_only=args.train_only,
        template=args.template,
        **study_arguments(args),
    )


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()

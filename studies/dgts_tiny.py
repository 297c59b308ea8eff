"""Study: DGTS with the tiny configuration (2 levels, 120 steps) on knobs at two periods.

``python studies/dgts_tiny.py [--periods 0.6 0.45] [--samples 3] [--png DIR]``: a knobs sphere
(``data.textured_sphere("knobs", subdivisions=4, period=p)``; 0.6 and 0.45 are 3.7 and 2.8 mean
edges at the finest level) learned with ``PrepareConfig.tiny`` / ``Config.tiny`` (template
icosphere(2); not the paper's 5 levels, 32-128 channels, 2000 steps) and scored against ground
truth: in-domain samples against the finest training mesh, transfers (torus 64 x 24 and, when
``../shared/data`` is there, the cow; from the default start level and from level 0) against
their oracles (``dgts.core.oracle_texture``). Rows: the truth, the oracle with other centres (the
metric's spread), trained, untrained (same architecture, no step), zero displacement, Gaussian
normal noise of the truth's relief; the headline columns from ``dgts.core.knob_scores`` (knobs per
squared period of the shared base, the patch distance; in-domain on the subdivided template), the
former per-mesh-edge peak density (``dgts.core.texture_scores``) after them as a diagnostic.
Writes ``studies/results/dgts_tiny.{json,md}``.
"""

from __future__ import annotations

import argparse
import pathlib
import time

import jax
import numpy as np
from _dgts import (
    KIND,
    PERIOD,
    evaluate,
    tiny_configs,
    untrained_weights,
)
from _study import Report

from jmeshtex.data import icosphere, textured_sphere
from jmeshtex.dgts import train, training_meshes
from jmeshtex.dgts.core import (
    period_in_mean_edges,
)


def quality(
    report: Report, png: pathlib.Path | None, *, samples: int = 3, reference_period: float = PERIOD
) -> None:
    prep, cfg = tiny_configs()
    reference = textured_sphere(KIND, subdivisions=4, period=reference_period)
    t0 = time.perf_counter()
    tm = training_meshes(
        reference, icosphere(2), config=prep, key=jax.random.key(0), progress=False
    )
    t_prep = time.perf_counter() - t0
    t0 = time.perf_counter()
    trained = train(tm, cfg, key=jax.random.key(0), progress=False).model
    t_train = time.perf_counter() - t0
    untrained = untrained_weights(tm, cfg)
    period = period_in_mean_edges(tm, reference_period)
    tag = f"[period {period:.2f} edges] "
    report.add(
        name=f"{tag}quality: prepare + train (tiny)",
        faces=len(tm.faces[-1]),
        prepare_s=t_prep,
        train_s=t_train,
        texture=KIND,
        period_mean_edges=period,
    )
    evaluate(
        report,
        tag,
        trained,
        untrained,
        tm,
        reference,
        KIND,
        reference_period,
        samples=samples,
        starts=(None, 0),
        png=None if png is None else png / f"dgts_quality_{reference_period}.png",
        title=f"DGTS tiny ({KIND}, period {period:.2f} mean edges)",
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--periods", nargs="+", type=float, default=[PERIOD, 0.45])
    ap.add_argument("--samples", type=int, default=3, help="transfer samples per row")
    ap.add_argument("--png", type=pathlib.Path, default=None, help="folder of the figures")
    args = ap.parse_args(argv)
    report = Report("dgts_tiny", ceilings=False)
    for reference_period in args.periods:
        quality(report, args.png, samples=args.samples, reference_period=reference_period)
        report.write()


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()

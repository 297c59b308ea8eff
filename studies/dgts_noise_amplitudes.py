"""Study: does a DGTS transfer's layout come from its noise? Transfer noise scaled by each amplitude.

``python studies/dgts_noise_amplitudes.py 0 0.5 1 2 [--kind knobs] [--runs RUN ...] [--levels 4]
[--work runs/dgts_depth]``: the study models of ``--runs`` transferred with their transfer noise
scaled by each amplitude (0: none) to the torus grid, the icosphere of the training connectivity
and the cow, against their oracles, with each output's layout correlation to the noiseless one.
Writes ``studies/results/dgts_noise_amplitudes_<kind>.{json,md}``.
"""

from __future__ import annotations

import pathlib

import jax
import numpy as np
from _dgts import (
    DEPTH_TEXTURES,
    TRANSFER_SCORES_NOTE,
    layout_correlation,
    score_rows,
    study_arguments,
    study_models,
    study_parser,
    transfer_targets,
)
from _study import Report

from jmeshtex.data import icosphere, torus
from jmeshtex.dgts import transfer
from jmeshtex.dgts.core import (
    oracle_texture,
)


def noise_amplitudes(
    kind: str,
    runs: list[str],
    *,
    amplitudes: list[float],
    levels: int,
    work: pathlib.Path,
    samples: int,
) -> None:
    """Does a transfer's layout come from its noise? Each study model in ``work/<kind>/<run>/``
    (as :func:`tessellations`) and untrained weights, transferred with the transfer noise scaled by
    each of ``amplitudes`` (× ``Config.noise_amplitude``; 0: no noise at all) to the torus grid
    (default start), the icosphere of the training mesh's connectivity (from level 2) and the shared
    cow (default start), against their oracles. ``layout_vs_zero``: the correlation, vertex by
    vertex, of each output's relief heights with the same model's noiseless output on the same base
    (1: the noise moves nothing). Writes ``dgts_noise_amplitudes_<kind>``."""
    import dataclasses

    report = Report(f"dgts_noise_amplitudes_{kind}", ceilings=False)
    targets = [
        ("torus grid", torus(64, 24), None),
        (f"icosphere({levels - 1})", icosphere(levels - 1), 2),
    ]
    targets += [(name, mesh, None) for name, mesh in transfer_targets(("cow",))[1:]]
    report.config = {"kind": kind, "levels": levels, "runs": runs, "amplitudes": amplitudes}
    models = study_models(kind, runs, levels, work)
    for target_name, target, start in targets:
        at = "default start" if start is None else f"start {start}"
        for name, (model, period) in models.items():
            rows, extra, zero = {}, {}, None
            for a in sorted(amplitudes):
                scaled = dataclasses.replace(
                    model,
                    config=model.config.replace(noise_amplitude=a * model.config.noise_amplitude),
                )
                res = transfer(
                    scaled, target, num_samples=samples, start_level=start, key=jax.random.key(1)
                )
                meshes = [res.mesh(i) for i in range(samples)]
                zero = meshes[0] if zero is None else zero  # the smallest amplitude (0 when asked)
                rows[f"noise x{a:g}"] = meshes
                corr = np.mean([layout_correlation(m, zero) for m in meshes])
                extra[f"noise x{a:g}"] = {"layout_vs_zero": float(corr)}
            oracle = oracle_texture((res.base, res.faces), kind, period=period)
            score_rows(report, f"{target_name}, {at} [{name}] (F={len(res.faces)})", rows, oracle,
                        (res.base, res.faces), extra, period)  # fmt: skip
        report.write()
    report.notes.append(
        f"{TRANSFER_SCORES_NOTE}; noise xA: transfer noise A times Config.noise_amplitude; "
        "layout_vs_zero: correlation of relief heights with the smallest amplitude's output."
    )
    report.write()


def main(argv: list[str] | None = None) -> None:
    ap = study_parser(__doc__, kind=False, runs=True)
    ap.add_argument("amplitudes", nargs="+", type=float)
    ap.add_argument("--kind", default="knobs", choices=sorted(DEPTH_TEXTURES))
    args = ap.parse_args(argv)
    noise_amplitudes(args.kind, args.runs, amplitudes=args.amplitudes, **study_arguments(args))


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()

"""Study: new surface or new tessellation? DGTS study models on two tessellations of a torus and a sphere.

``python studies/dgts_tessellations.py KIND [--runs RUN ...] [--levels 4] [--work runs/dgts_depth]
[--starts 2]``: the study models of ``--runs`` (run folders under ``WORK/KIND``, trained by
``dgts_noise_response.py``) transferred to one surface under two tessellations each (the torus
grid and an isotropic remesh of it; the icosphere of the training mesh's connectivity and an
isotropic sphere) from the default and ``--starts`` levels, against their oracles. Writes
``studies/results/dgts_tessellations_<kind>.{json,md,png}``.
"""

from __future__ import annotations

import pathlib

import jax
import numpy as np
from _dgts import (
    TRANSFER_SCORES_NOTE,
    score_transfers,
    study_arguments,
    study_models,
    study_parser,
)
from _study import RESULTS, Report

from jmeshtex.data import icosphere, torus


def tessellations(
    kind: str,
    runs: list[str],
    *,
    levels: int,
    work: pathlib.Path,
    samples: int,
    starts: tuple[int | None, ...] = (None, 2),
) -> None:
    """New surface or new tessellation? Each study model in ``work/<kind>/<run>/`` (trained by
    :func:`noise_response`; its name tells its training meshes: ``coarse<K>_…`` fitted the
    coarsest K levels to the untextured sphere) and untrained weights, transferred to a torus as a
    64 × 24 grid and as an isotropic remesh of the same vertex count, and to a sphere as the
    icosphere of the training mesh's connectivity (one level coarser than the finest) and as an
    isotropic remesh of the same vertex count; scored against each output's oracle at the model's
    own period, beside matched noise. Writes ``dgts_tessellations_<kind>`` and its figure (each
    target's oracle and every model's transfer from the last of ``starts``)."""
    from jmeshtex.geometry import remesh

    report = Report(f"dgts_tessellations_{kind}", ceilings=False)
    grid = torus(64, 24)
    sphere = icosphere(levels - 1)  # icosphere(1) subdivided levels - 2 times: level L-2's faces
    targets = [
        ("torus grid", grid),
        ("torus isotropic", remesh(torus(128, 48), n_vertices=len(grid.vertices), key=jax.random.key(0))),
        (f"icosphere({levels - 1})", sphere),
        ("sphere isotropic", remesh(icosphere(levels + 1), n_vertices=len(sphere.vertices), key=jax.random.key(0))),
    ]  # fmt: skip
    report.config = {"kind": kind, "levels": levels, "runs": runs, "starts": list(starts)}
    models = study_models(kind, runs, levels, work)
    panels = []
    for target_name, target in targets:
        for start in starts:
            at = "default start" if start is None else f"start {start}"
            for name, (model, period) in models.items():
                rows, oracle = score_transfers(
                    report, f"{target_name}, {at} [{name}]", {name: model}, target, start, kind, period,
                    samples,
                )  # fmt: skip
                if start == starts[-1]:
                    if name == runs[0]:
                        panels.append((f"{target_name}: oracle", oracle))
                    short = name.replace("fake_inputs_", "").replace("_", " ")
                    panels.append((f"{target_name}: {short}", rows[name][0]))
        report.write()
    from jmeshtex.render import figure, render_mesh

    figure(
        [(title, render_mesh(mesh, size=(300, 300))) for title, mesh in panels],
        columns=len(models) + 1,
        title=f"DGTS {kind}: transfers from level {starts[-1]} to two tessellations of each surface",
        path=RESULTS / f"dgts_tessellations_{kind}.png",
    )
    report.notes.append(
        f"{TRANSFER_SCORES_NOTE}, at the model's own period in mean edges; matched noise: "
        "Gaussian relief of the oracle's std."
    )
    report.write()


def main(argv: list[str] | None = None) -> None:
    ap = study_parser(__doc__, runs=True)
    ap.add_argument("--starts", nargs="+", type=int, default=[2], help="extra start levels")
    args = ap.parse_args(argv)
    tessellations(args.kind, args.runs, **study_arguments(args), starts=(None, *args.starts))


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()

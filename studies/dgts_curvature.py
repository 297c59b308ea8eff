"""Study: does DGTS transfer density follow the target's curvature in edges?

``python studies/dgts_curvature.py KIND [--runs RUN ...] [--levels 4] [--work runs/dgts_depth]``:
the study models of ``--runs`` transferred from level 2 to a torus and a sphere at three
resolutions each (2x more edges across: half the curvature per edge, the same period in edges)
against their oracles (:func:`curvature`). Writes
``studies/results/dgts_curvature_<kind>.{json,md,png}``.
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
    transfer_targets,
)
from _study import RESULTS, Report

from jmeshtex.data import icosphere, torus


def curvature(
    kind: str,
    runs: list[str],
    *,
    levels: int,
    work: pathlib.Path,
    samples: int,
    start: int = 2,
    real=("cow", "fandisk"),
) -> None:
    """Does transfer density follow the target's curvature in edges? Each study model in
    ``work/<kind>/<run>/`` (as :func:`tessellations`) and untrained weights, transferred from level
    ``start`` to one torus and one sphere each at three resolutions: the same shape with 2× more
    edges across is half as curved per edge, while the texture's period in edges (and so the
    oracle's density per squared edge) stays. Tori: grids 32 × 12, 64 × 24, 128 × 48 (tube
    circumference 12 / 24 / 48 edges at the start level); spheres: icosphere(2…4); and the middle
    torus from one level coarser (``start`` − 1: the user's way to make a texture finer relative to
    a given target), and midpoint-subdivided once from ``start`` (the same output, but no
    generator at ``start`` − 1); the shared real meshes named in ``real`` from ``start`` and
    ``start`` − 1, and remeshed with even edge lengths (:func:`~jmeshtex.geometry.remesh`,
    ``even_lengths=True``, as many vertices) from ``start`` − 1.
    Writes ``dgts_curvature_<kind>``."""
    from jmeshtex import Mesh
    from jmeshtex.geometry import remesh, subdivide_midpoint

    report = Report(f"dgts_curvature_{kind}", ceilings=False)
    targets = [(f"torus {n * 8}x{n * 3}", torus(n * 8, n * 3), start) for n in (4, 8, 16)]
    targets += [(f"icosphere({k})", icosphere(k), start) for k in (2, 3, 4)]
    targets.append(("torus 64x24", torus(64, 24), start - 1))  # the middle torus, one level coarser
    fine = subdivide_midpoint(*torus(64, 24))  # ... and subdivided once, flat, from `start`
    targets.append(("torus 64x24 subdivided", Mesh(fine.vertices, fine.faces), start))
    for name, mesh in transfer_targets(real)[1:]:  # as given from two levels, isotropic from one
        targets += [(name, mesh, start), (name, mesh, start - 1)]
        iso = remesh(mesh, n_vertices=mesh.num_vertices, key=jax.random.key(0), even_lengths=True)
        targets.append((f"{name} isotropic", iso, start - 1))
    report.config = {"kind": kind, "levels": levels, "runs": runs, "start": start}
    models = study_models(kind, runs, levels, work)
    panels = []
    for target_name, target, at in targets:
        for name, (model, period) in models.items():
            rows, oracle = score_transfers(
                report, f"{target_name}, start {at} [{name}]", {name: model}, target, at, kind,
                period, samples,
            )  # fmt: skip
            if name == runs[0]:
                panels.append((f"{target_name} from {at}: oracle", oracle))
                panels.append((f"{target_name} from {at}: {name.split('_fake')[0]}", rows[name][0]))
        report.write()
    from jmeshtex.render import figure, render_mesh

    figure(
        [(title, render_mesh(mesh, size=(300, 300))) for title, mesh in panels],
        columns=4,
        title=f"DGTS {kind}: transfers to a torus and a sphere at three resolutions",
        path=RESULTS / f"dgts_curvature_{kind}.png",
    )
    report.notes.append(f"{TRANSFER_SCORES_NOTE}, at the model's own period in mean edges.")
    report.write()


def main(argv: list[str] | None = None) -> None:
    args = study_parser(__doc__, runs=True).parse_args(argv)
    curvature(args.kind, args.runs, **study_arguments(args))


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()

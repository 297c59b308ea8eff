"""Study: does DGTS transfer density depend on how fine the target is at the start level?

``python studies/dgts_start_resolution.py [--models FOLDER ...] [--samples 3]``: each knobs model
folder (``model.npz`` beside its ``training_meshes*.npz``; default the paper-grade 5-level model and
the committed 4-level one) and untrained weights of its architecture, transferred to spheres and
tori of several resolutions (:func:`start_resolution`), scored by issue 54's measure
(``dgts.core.knob_scores``, the rows of ``benchmarks/dgts.py``'s rescore: oracle, floor, zero
displacement, matched noise, untrained, trained). Writes
``studies/results/dgts_start_resolution.{json,md,png}``.
"""

from __future__ import annotations

import argparse
import pathlib

import jax
from _dgts import untrained_weights
from _study import RESULTS, ROOT, Report
from dgts import DEPTH_TEXTURES, _score, unit_edge

from jmeshtex.data import icosphere, torus

#: the paper-grade 5-level model (icosphere(0) template) and the committed 4-level one (icosphere(1))
MODELS = (
    ROOT / "benchmarks" / "results" / "dgts_depth5_knobs_model",
    ROOT / "benchmarks" / "results" / "dgts_knobs_coarse2_fixed3_model",
)


def cases(levels: int) -> list[tuple[str, tuple, int]]:
    """``(name, target, start level)``: icospheres 1–3 from level 1 (the official start; each 2× as
    many edges across as the one before, so half as curved per edge), the same spheres started where
    they give one output size (icosphere(k) from level k: the in-domain sample's 5,120 faces on the
    5-level model), and two tori from level 1. Starts beyond the model's last level are left out."""
    out = [(f"icosphere({k})", icosphere(k), 1) for k in (1, 2, 3)]
    out += [(f"icosphere({k})", icosphere(k), k) for k in (2, 3)]
    out += [(f"torus {8 * n}x{3 * n}", torus(8 * n, 3 * n), 1) for n in (4, 8)]
    return [(name, unit_edge(mesh), start) for name, mesh, start in out if start < levels]


def start_resolution(models: list[pathlib.Path], *, samples: int) -> None:
    """Each model's transfers (generators ``start … L − 1``, the official noise on the first two
    levels run, targets at unit edge) to :func:`cases`, with untrained weights of its
    architecture, scored against the oracle on the transfer's base at the model's own period in
    mean edges of its finest training level. Writes ``dgts_start_resolution``."""
    from jmeshtex import Mesh
    from jmeshtex.dgts import load, load_training_meshes, transfer
    from jmeshtex.dgts.core import period_in_mean_edges
    from jmeshtex.render import figure, render_mesh

    report = Report("dgts_start_resolution", ceilings=False)
    report.config = {"models": [str(m) for m in models], "samples": samples}
    keys = [jax.random.key(s) for s in range(samples)]
    panels = []
    for folder in models:
        tm = load_training_meshes(sorted(folder.glob("training_meshes*.npz"))[0])
        trained = load(folder)
        untrained = untrained_weights(tm, trained.config)  # no step, training key 0
        period = period_in_mean_edges(tm, DEPTH_TEXTURES["knobs"])
        L = trained.num_levels
        for name, target, start in cases(L):
            results = {
                tag: [transfer(m, target, start_level=start, stop_level=L - 1, key=k) for k in keys]
                for tag, m in (("trained", trained), ("untrained", untrained))
            }
            outputs = {tag: [r.mesh(0) for r in rs] for tag, rs in results.items()}
            base = Mesh(results["trained"][0].base, results["trained"][0].faces)
            section = f"{folder.name} ({L} levels): {name} from level {start} ({len(base.faces)} F)"
            oracle = _score(report, section, outputs, base, period, kind="knobs", seeds=samples)
            if folder == models[0] and name.startswith("icosphere"):
                panels += [
                    (f"{name} from {start}: oracle", oracle),
                    (f"{name} from {start}: trained", outputs["trained"][0]),
                ]
    report.notes.append(
        "Rows as benchmarks/dgts.py's rescore (knob density per squared period of the shared base, "
        "sliced-Wasserstein patch distance, ratios to the oracle and to the untrained and matched "
        "noise rows); transfers from the start level named to each model's last level."
    )
    report.write()
    figure(
        [(title, render_mesh(mesh, size=(300, 300))) for title, mesh in panels],
        columns=4,
        title=f"DGTS knobs ({models[0].name}): spheres at three resolutions, oracle | trained",
        path=RESULTS / "dgts_start_resolution.png",
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", type=pathlib.Path, default=list(MODELS))
    ap.add_argument("--samples", type=int, default=3, help="noise seeds per row")
    a = ap.parse_args(argv)
    start_resolution(a.models, samples=a.samples)


if __name__ == "__main__":
    main()

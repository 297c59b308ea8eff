"""Study: does a wider DGTS receptive field lay the texture out at the right density from noise?

``python studies/dgts_receptive_field.py KIND [--layer-counts 7 10] [--levels 3] [--steps 2000]
[--remeshes 1] [--work runs/dgts_depth]``: LAYER_COUNTS layers per network on REMESHES remeshes,
LEVELS levels; the last level lays the texture out from its own noise, in-domain and on new
surfaces (:func:`receptive_field`). Writes ``studies/results/dgts_receptive_field[...]``.
"""

from __future__ import annotations

import pathlib
import time

import jax
import numpy as np
from _dgts import (
    DEPTH_TEXTURES,
    depth_meshes,
    in_domain_truth,
    score_rows,
    score_transfers,
    study_arguments,
    study_parser,
    transfer_targets,
)
from _study import RESULTS, Report

from jmeshtex.dgts import Config, conditional, train
from jmeshtex.dgts.core import (
    period_in_mean_edges,
)


def receptive_field(
    kind: str,
    layer_counts: list[int],
    *,
    levels: int,
    steps: int,
    work: pathlib.Path,
    samples: int,
    remeshes: int,
    real=("cow", "fandisk"),
) -> None:
    """Does a wider receptive field lay the texture out at the right density from noise?

    The paper's widths with ``num_layers`` in ``layer_counts`` (7: the paper's; each face
    convolution widens generator and critic by one ring of faces), ``fake_inputs="reconstructed"``,
    trained ``steps`` per level on the first ``levels`` levels of ``remeshes`` remeshes of the run at
    depth's reference (:func:`depth_meshes`; several, so no generator can key the layout to the
    template's triangles), resumable in ``work/<kind>/receptive_field_<layers>_...``. Level 2 (about
    2.8 mean edges per period, the first that holds a knob) must lay the texture out: rows score the
    finest level's output with fresh noise at level 2 alone in-domain (every other level on the
    reconstruction's noise) against the finest training mesh, and transfers to a torus and the
    shared real meshes that start at level 2 (so it lays the texture out on a surface it never saw)
    against their oracles, beside untrained weights and matched noise. With 3 levels the scores are
    read at level 2 itself, where peak density separates little; with 4, at level 3. Writes
    ``dgts_receptive_field`` (``_<levels>_levels`` beyond 3)."""
    from jmeshtex import Mesh
    from jmeshtex.dgts import Model, load, save
    from jmeshtex.dgts.core import plan_transfer, run_plan

    if levels < 3:
        raise SystemExit("--study-levels must be >= 3 (level 2 lays the texture out)")
    suffix = "" if levels == 3 else f"_{levels}_levels"
    report = Report("dgts_receptive_field" + suffix, ceilings=False)
    folder = work / kind
    references = [depth_meshes(kind, 4, folder, remesh=i)[1] for i in range(remeshes)]
    tm = references[0]
    last, layout = levels - 1, 2
    period = period_in_mean_edges(tm, DEPTH_TEXTURES[kind]) / 2 ** (tm.num_levels - levels)
    truth = tm.mesh(last)
    template = (tm.template, tm.faces[0])
    report.config = {"kind": kind, "levels": levels, "steps": steps, "remeshes": remeshes,
                     "period_mean_edges_at_last_level": period}  # fmt: skip
    models: dict[str, Model] = {}
    for layers in layer_counts:
        cfg = Config(steps=steps, fake_inputs="reconstructed", num_layers=layers)
        run = (
            folder / f"receptive_field_{layers}_layers_{levels}_levels_{remeshes}_remeshes_{steps}"
        )
        if (run / "model.npz").is_file():
            models[f"{layers} layers"] = load(run)
            continue
        c0, t0 = time.process_time(), time.perf_counter()
        result = train(
            references,
            cfg.replace(checkpoint_every=250),
            key=jax.random.key(0),
            levels=levels,
            checkpoint_dir=run / "checkpoints",
            progress=False,
        )
        save(result.model, run)
        models[f"{layers} layers"] = result.model
        report.add(
            name=f"train ({layers} layers)",
            train_s=time.perf_counter() - t0,
            train_cpu_s=time.process_time() - c0,
            resumed_from=result.resumed_from,
        )
    models["untrained (7 layers)"] = train(
        references, Config(steps=0), key=jax.random.key(0), levels=levels, progress=False
    ).model

    def own_noise_only(model, plan, i: int) -> Mesh:
        noise = model.reconstruction_noise(plan.sizes)
        draw = jax.random.normal(jax.random.fold_in(jax.random.key(2), i), (plan.sizes[layout], 3))
        noise[layout] = model.config.noise_amplitude * draw
        return Mesh(plan.to_target(run_plan(model, plan, noise)), plan.faces[-1])

    rows = {
        name: [
            own_noise_only(m, plan_transfer(m, template, start_level=0), i) for i in range(samples)
        ]
        for name, m in models.items()
    }
    first = next(iter(models.values()))
    base = conditional(first, template, level=first.num_levels, key=jax.random.key(0))  # .base
    truth_t, in_base, in_period = in_domain_truth(
        tm, (base.base, base.faces), DEPTH_TEXTURES[kind], level=last,
        scale_factor=first.config.scale_factor,
    )  # fmt: skip
    score_rows(
        report, f"in-domain, fresh noise at level {layout} only", rows, truth_t, None, {},
        in_period, knob_base=in_base,
    )  # fmt: skip
    panels = [("training mesh", truth)] + [(f"in-domain: {n}", r[0]) for n, r in rows.items()]
    for target_name, target in transfer_targets(real):
        rows, oracle = score_transfers(
            report, f"{target_name}, start {layout}", models, target, layout, kind, period, samples
        )
        panels.append((f"{target_name}: oracle", oracle))
        panels += [(f"{target_name}: {n}", rows[n][0]) for n in models]
        report.write()
    from jmeshtex.render import figure, render_mesh

    figure(
        [(title, render_mesh(mesh, size=(320, 320))) for title, mesh in panels],
        columns=len(models) + 1,
        title=f"DGTS {kind}: layers per network, {levels} levels x {steps} steps, "
        f"{remeshes} remeshes, fake_inputs reconstructed",
        path=RESULTS / f"dgts_receptive_field{suffix}.png",
    )
    report.write()


def main(argv: list[str] | None = None) -> None:
    ap = study_parser(__doc__, train_levels=3)
    ap.add_argument("--layer-counts", nargs="+", type=int, default=[7, 10])
    ap.add_argument("--remeshes", type=int, default=1)
    args = ap.parse_args(argv)
    receptive_field(args.kind, args.layer_counts, **study_arguments(args), remeshes=args.remeshes)


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()

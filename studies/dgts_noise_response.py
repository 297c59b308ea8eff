"""Study: where a trained DGTS hierarchy's texture goes wrong under fresh noise, per ``Config.fake_inputs``.

``python studies/dgts_noise_response.py KIND [--levels 4] [--steps 2000] [--work runs/dgts_depth]
[--coarse-levels K] [--remeshes R] [--fixed-noise-levels N] [--fake-inputs sampled reconstructed]
[--starts 2]``: each level's output under fresh noise at that level alone, and transfers
(:func:`noise_response`). ``--remeshes R`` trains on R remeshes of the reference (the template
fitted under R - 1 random rotations too), ``--starts`` adds transfer start levels. Writes
``studies/results/dgts_noise_response_<kind>[...]``. The models it trains under ``WORK/KIND/`` are
the ones ``dgts_tessellations.py``, ``dgts_noise_amplitudes.py`` and ``dgts_curvature.py`` read.
"""

from __future__ import annotations

import json
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
    untrained_weights,
)
from _study import RESULTS, Report

from jmeshtex.dgts import Config, conditional, train
from jmeshtex.dgts.core import (
    period_in_mean_edges,
)


def noise_response(
    kind: str,
    *,
    levels: int,
    steps: int,
    work: pathlib.Path,
    samples: int,
    real=("cow", "fandisk"),
    coarse_levels: int = 0,
    remeshes: int = 1,
    fixed_noise_levels: int = 1,
    choices: tuple[str, ...] = ("sampled", "reconstructed"),
    starts: tuple[int | None, ...] = (None, 2),
) -> None:
    """Where a trained hierarchy's texture goes wrong under fresh noise, per ``Config.fake_inputs``.

    The paper's network on the run at depth's training meshes (:func:`depth_meshes`), trained
    ``steps`` per level once per ``fake_inputs`` choice (resumable in
    ``work/<kind>/fake_inputs_<choice>_<steps>/``). Rows, as peak density and relief relative to the
    truth: in-domain, every level reconstructed (``z*``) except fresh noise at level ``k`` alone
    (the noise response of generator ``k`` given the training coarse shape); transfers to the torus
    and the shared real meshes at the default start level and noise, and from each level of
    ``starts`` (default 2: noise at levels 2-3), against their oracles, beside untrained weights and matched noise. With
    ``coarse_levels`` the training meshes' coarsest levels fit the untextured sphere
    (:func:`depth_meshes`; runs in ``coarse<K>_fake_inputs_...``). With ``remeshes`` R > 1 each
    model trains on R remeshes of the reference (the plain fit and R − 1 fits from turned
    templates, one drawn per step; runs in ``remesh<R>_fake_inputs_...``); in-domain rows score
    against the plain fit. With ``fixed_noise_levels`` N > 1 the reconstruction runs on fixed noise
    up to level N − 1 (``Config.fixed_noise_levels``; runs in ``..._fixed<N>_fake_inputs_...``).
    ``choices``: the ``fake_inputs`` trained. Writes
    ``dgts_noise_response_<kind>[_coarse<K>][_remesh<R>][_fixed<N>]`` and its figure (in-domain under level L−1's noise; each target's oracle
    and transfers at the default start)."""
    from jmeshtex import Mesh
    from jmeshtex.dgts import load, save
    from jmeshtex.dgts.core import plan_transfer, run_plan

    suffix = f"_coarse{coarse_levels}" if coarse_levels else ""
    suffix += f"_remesh{remeshes}" if remeshes > 1 else ""
    suffix += f"_fixed{fixed_noise_levels}" if fixed_noise_levels > 1 else ""
    report = Report(f"dgts_noise_response_{kind}{suffix}", ceilings=False)
    folder = work / kind
    _, tm = depth_meshes(kind, levels, folder, coarse_levels)
    references = [tm] + [
        depth_meshes(kind, levels, folder, coarse_levels, remesh=i)[1] for i in range(1, remeshes)
    ]
    period = period_in_mean_edges(tm, DEPTH_TEXTURES[kind])
    truth = tm.mesh(-1)
    template = (tm.template, tm.faces[0])
    report.config = {
        "kind": kind,
        "levels": levels,
        "steps": steps,
        "period_mean_edges": period,
        "coarse_levels": coarse_levels,
        "remeshes": remeshes,
        "fixed_noise_levels": fixed_noise_levels,
    }
    models = {}
    for choice in choices:
        run = folder / f"{suffix[1:]}_fake_inputs_{choice}_{steps}".lstrip("_")
        cost = run / "train.json"  # the training's cost, kept beside its model
        if (run / "model.npz").is_file():
            models[choice] = load(run)
            if cost.is_file():
                report.add(name=f"train ({choice})", **json.loads(cost.read_text()))
            continue
        c0, t0 = time.process_time(), time.perf_counter()
        result = train(
            references,
            Config(
                steps=steps,
                fake_inputs=choice,
                fixed_noise_levels=fixed_noise_levels,
                checkpoint_every=250,
            ),
            key=jax.random.key(0),
            checkpoint_dir=run / "checkpoints",
            progress=False,
        )
        save(result.model, run)  # run/model.npz
        models[choice] = result.model
        spent = {
            "train_s": time.perf_counter() - t0,
            "train_cpu_s": time.process_time() - c0,
            "resumed_from": result.resumed_from,
        }
        cost.write_text(json.dumps(spent))
        report.add(name=f"train ({choice})", **spent)
    models["untrained"] = untrained_weights(tm, Config())
    panels = [("training mesh", truth)]
    label_last = f"fresh noise at level {levels - 1} only"

    def only_at(model, plan, k: int, i: int) -> Mesh:
        """The template through every level with the reconstruction's noise
        (``Model.reconstruction_noise``) except fresh noise at level ``k`` (none when ``k`` is the
        level count)."""
        noise = model.reconstruction_noise(plan.sizes)
        if k < levels:
            draw = jax.random.normal(jax.random.fold_in(jax.random.key(2), i), (plan.sizes[k], 3))
            noise[k] = model.config.noise_amplitude * draw
        return Mesh(plan.to_target(run_plan(model, plan, noise)), plan.faces[-1])

    for name, model in models.items():
        plan = plan_transfer(model, template, start_level=0)
        rows = {}
        for k in range(levels + 1):
            label = f"fresh noise at level {k} only" if k < levels else "reconstruction (no noise)"
            rows[label] = [only_at(model, plan, k, i) for i in range(samples)]
        base = conditional(model, template, level=levels, key=jax.random.key(0))  # its .base
        truth_t, in_base, in_period = in_domain_truth(
            tm,
            (base.base, base.faces),
            DEPTH_TEXTURES[kind],
            scale_factor=model.config.scale_factor,
        )
        score_rows(
            report, f"[{name}] in-domain vs training mesh", rows, truth_t, None, {}, in_period,
            knob_base=in_base,
        )  # fmt: skip
        panels.append((f"{name}: noise at level {levels - 1} only", rows[label_last][0]))
    for target_name, target in transfer_targets(real):
        for start in starts:
            at = "default start" if start is None else f"start {start}"
            rows, oracle = score_transfers(
                report, f"{target_name}, {at}", models, target, start, kind, period, samples
            )
            if start is None:
                panels.append((f"{target_name}: oracle", oracle))
                panels += [(f"{target_name}: {n}", rows[n][0]) for n in models]
        report.write()
    from jmeshtex.render import figure, render_mesh

    figure(
        [(title, render_mesh(mesh, size=(320, 320))) for title, mesh in panels],
        columns=4,
        title=f"DGTS {kind}, {levels} levels x {steps} steps: fake_inputs "
        + " vs ".join(choices)
        + (f"; levels < {coarse_levels} fit the untextured sphere" if coarse_levels else "")
        + (f"; trained on {remeshes} remeshes" if remeshes > 1 else "")
        + (
            f"; fixed reconstruction noise up to level {fixed_noise_levels - 1}"
            if fixed_noise_levels > 1
            else ""
        ),
        path=RESULTS / f"dgts_noise_response_{kind}{suffix}.png",
    )
    report.notes.append(
        "density_vs_truth / relief_vs_truth: the mesh's peak density (peaks per squared mean edge) "
        "and relief std over the truth's (the training mesh in-domain, the oracle on a transfer's "
        "own base); transfers use the default noise (fresh at the first two levels run)."
    )
    report.write()


def main(argv: list[str] | None = None) -> None:
    ap = study_parser(__doc__, train_levels=4)
    ap.add_argument(
        "--coarse-levels",
        type=int,
        default=0,
        help="the training meshes' coarsest K levels fit the untextured sphere",
    )
    ap.add_argument(
        "--remeshes", type=int, default=1, help="train on R remeshes (R - 1 from turned templates)"
    )
    ap.add_argument(
        "--fixed-noise-levels",
        type=int,
        default=1,
        help="Config.fixed_noise_levels (the reconstruction's noise is fixed below level N)",
    )
    ap.add_argument(
        "--fake-inputs",
        nargs="+",
        default=["sampled", "reconstructed"],
        choices=["sampled", "reconstructed"],
        help="the Config.fake_inputs choices trained",
    )
    ap.add_argument("--starts", nargs="+", type=int, default=[2], help="extra start levels")
    args = ap.parse_args(argv)
    noise_response(
        args.kind,
        **study_arguments(args),
        coarse_levels=args.coarse_levels,
        remeshes=args.remeshes,
        fixed_noise_levels=args.fixed_noise_levels,
        choices=tuple(args.fake_inputs),
        starts=(None, *args.starts),
    )


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()

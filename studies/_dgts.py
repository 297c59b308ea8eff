"""What the DGTS studies share: the tiny configuration, the studies' scoring rows (in-domain and
transfers against oracles, beside untrained weights, zero displacement and matched noise), the run
at depth's fitted training meshes and the study models trained into a work folder.

The benchmark's own pieces (the reference texture, the real meshes, the run at depth's periods) are
imported from ``benchmarks/dgts.py``."""

from __future__ import annotations

import argparse
import pathlib
import re
import shutil

import jax
import numpy as np
from _study import Report
from dgts import (  # noqa: F401  (the benchmark's own)
    DEPTH_TEXTURES,
    KIND,
    PERIOD,
    in_domain_truth,
    transfer_targets,
)

from jmeshtex.data import icosphere, textured_sphere
from jmeshtex.dgts import Config, PrepareConfig, conditional, train, training_meshes, transfer
from jmeshtex.dgts.core import (
    density_error,
    knob_scores,
    matched_noise,
    oracle_texture,
    period_in_mean_edges,
    reconstruction_errors,
    relief_heights,
    texture_operators,
    texture_scores,
)


def tiny_configs() -> tuple[PrepareConfig, Config]:
    """The demo's and the learning test's configuration: ``PrepareConfig.tiny``, ``Config.tiny``."""
    return PrepareConfig.tiny(), Config.tiny()


def layout_correlation(mesh, truth) -> float:
    """Correlation, vertex by vertex, of a mesh's relief heights with those of ``truth`` (a mesh of
    the same vertices: an in-domain sample and its training mesh). 1: the truth's layout, in place;
    near 0: a layout of its own (or none)."""
    h = relief_heights(mesh)
    t = relief_heights(truth)
    if h.shape != t.shape:
        raise ValueError(f"layout_correlation: {h.shape[0]} vertices against {t.shape[0]}")
    return float(np.corrcoef(h, t)[0, 1])


def score_rows(
    report,
    section: str,
    rows: dict,
    truth,
    base,
    samples: dict,
    period: float | None = None,
    knob_base=None,
) -> None:
    """One row per mesh list in ``rows`` (mean over its meshes), scored against ``truth``. With a
    shared base (``base``, or in-domain, where the older columns take none, ``knob_base``:
    :func:`in_domain_truth`) and the ``period`` (its mean edges) the headline columns come first:
    knobs per squared period against the truth's and the patch distance
    (``dgts.core.knob_scores``); the older per-mesh-edge columns (``peak_density`` …) follow as
    diagnostics."""
    own = texture_scores(truth, truth, base=base)
    shared = base if base is not None else knob_base
    ops = None if shared is None or period is None else texture_operators(shared, period=period)
    knob_own = None if ops is None else knob_scores(truth, truth, ops=ops)
    for name, meshes in rows.items():
        scores = [texture_scores(m, truth, base=base) for m in meshes]
        mean = {k: float(np.mean([getattr(s, k) for s in scores])) for k in own._fields}
        ratio = mean["peak_density"] / own.peak_density
        layout = {}
        if base is None:  # in-domain: the truth's own vertices, so its layout can be compared
            layout["layout_corr"] = float(np.mean([layout_correlation(m, truth) for m in meshes]))
        headline = {}
        if ops is not None:
            knobs = [knob_scores(m, truth, ops=ops) for m in meshes]
            density = float(np.mean([k.density for k in knobs]))
            headline = {
                "knob_density_vs_truth": density / knob_own.density,
                "patch_distance": float(np.mean([k.distance for k in knobs])),
            }
        report.add(
            name=f"{section}: {name}",
            samples=len(meshes),
            **headline,
            peak_density=mean["peak_density"],
            density_vs_truth=ratio,
            density_error=float(np.mean([density_error(s, own) for s in scores])),
            relief=mean["relief"],
            relief_vs_truth=mean["relief"] / own.relief,
            w1_heights=mean["w1"],
            autocorrelation_length=mean["autocorrelation_length"],
            peak_spacing=mean["spacing"],
            peaks=mean["peaks"],
            **layout,
            **samples.get(name, {}),
        )


def untrained_weights(tm, cfg: Config, *, seed: int = 0):
    """The baseline every study row stands beside: ``cfg``'s architecture on ``tm``, no step taken
    (the initial weights of training key ``seed``)."""
    return train(tm, cfg.replace(steps=0), key=jax.random.key(seed), progress=False).model


def evaluate(
    report: Report,
    tag: str,
    trained,
    untrained,
    tm,
    reference,
    kind: str,
    reference_period: float,
    *,
    samples: int,
    starts=(None,),
    png: pathlib.Path | None = None,
    title: str = "DGTS",
    real: tuple[str, ...] = ("cow",),
) -> None:
    """In-domain samples against the finest training mesh, transfers (to a torus and the shared
    real meshes, from each of ``starts``) against their oracles, each beside untrained, zero
    displacement and matched noise; level reconstruction errors as a diagnostic; a render figure."""
    period = period_in_mean_edges(tm, reference_period)
    # in-domain: samples from the template (fresh noise at every level) against the training mesh
    # (in the template's frame, on the subdivided template: in_domain_truth)
    template = (tm.template, tm.faces[0])
    cond = conditional(trained, template, level=0, num_samples=samples, key=jax.random.key(2))
    cond_u = conditional(untrained, template, level=0, num_samples=samples, key=jax.random.key(2))
    truth, in_base, in_period = in_domain_truth(
        tm, (cond.base, cond.faces), reference_period, scale_factor=trained.config.scale_factor
    )
    relief = float(np.std(relief_heights(truth)))
    score_rows(
        report,
        f"{tag}in-domain vs training mesh",
        {
            "training mesh (truth)": [truth],
            "trained": [cond.mesh(i) for i in range(samples)],
            "untrained": [cond_u.mesh(i) for i in range(samples)],
            "zero displacement": [(cond.base, cond.faces)],
            "noise (matched relief)": [
                matched_noise((cond.base, cond.faces), relief, key=jax.random.key(i))
                for i in range(samples)
            ],
        },
        truth,
        None,
        {},
        in_period,
        knob_base=in_base,
    )
    for name, model in (("trained", trained), ("untrained", untrained)):
        errs = reconstruction_errors(model, tm)
        report.add(
            name=f"{tag}diagnostic: reconstruction error ({name})",
            **{f"level_{i}": float(e) for i, e in enumerate(errs)},
            note="mean edges; level 0 never reconstructs from z* (reconstruction_start = 1)",
        )
    figures = []
    for target_name, target in transfer_targets(real):
        for start in starts:
            res = transfer(
                trained, target, num_samples=samples, start_level=start, key=jax.random.key(1)
            )
            res_u = transfer(
                untrained, target, num_samples=samples, start_level=start, key=jax.random.key(1)
            )
            base = (res.base, res.faces)
            oracle = oracle_texture(base, kind, period=period)
            own = texture_scores(oracle, oracle, base=base)
            section = (
                f"{tag}transfer to {target_name} from level {res.start_level}"
                f"{' (default)' if start is None else ''}, {len(res.faces)} F"
            )
            score_rows(
                report,
                section,
                {
                    "oracle (truth)": [oracle],
                    "oracle, other centres": [
                        oracle_texture(base, kind, period=period, key=jax.random.key(s))
                        for s in (1, 2)
                    ],
                    "trained": [res.mesh(i) for i in range(samples)],
                    "untrained": [res_u.mesh(i) for i in range(samples)],
                    "zero displacement": [base],
                    "noise (matched relief)": [
                        matched_noise(base, own.relief, key=jax.random.key(i))
                        for i in range(samples)
                    ],
                },
                oracle,
                base,
                {},
                period,
            )
            if start is None:
                figures.append((target_name, res, res_u, oracle, base, own.relief))
    if png is None:
        return
    from jmeshtex.render import figure, render_mesh

    size = (320, 320)
    panels = [("reference", render_mesh(reference, size=size))]
    panels += [
        (f"training level {level}", render_mesh(tm.mesh(level), size=size))
        for level in range(1, len(tm.faces))
    ]
    panels.append(("in-domain sample", render_mesh(cond.mesh(0), size=size)))
    for target_name, res, res_u, oracle, base, relief in figures:
        panels += [
            (f"{target_name}: trained", render_mesh(res.mesh(0), size=size)),
            (f"{target_name}: oracle", render_mesh(oracle, size=size)),
            (f"{target_name}: untrained", render_mesh(res_u.mesh(0), size=size)),
            (
                f"{target_name}: noise",
                render_mesh(matched_noise(base, relief, key=jax.random.key(0)), size=size),
            ),
        ]
    png.parent.mkdir(parents=True, exist_ok=True)
    figure(
        panels,
        columns=4,
        title=f"{title}: reference | training levels | in-domain | transfers vs oracle and baselines",
        path=png,
    )


def depth_meshes(
    kind: str,
    levels: int,
    folder: pathlib.Path,
    coarse_levels: int = 0,
    remesh: int = 0,
    template: int = 1,
):
    """The run at depth's reference (a textured sphere, period ``DEPTH_TEXTURES[kind]``) and its
    ``levels`` fitted training levels on an icosphere(``template``) template (the finest level
    has icosphere(``template + levels - 1``)'s faces), kept in
    ``folder/training_meshes.npz`` (fitted once, about 12 CPU-minutes at 4 levels; a stopped fit
    resumes after its last finished level, kept in ``training_meshes.levels/``). With
    ``coarse_levels`` the coarsest ones fit the sphere without its texture
    (``training_meshes(coarse_reference=...)``; ``folder/training_meshes_coarse<K>.npz``). Remesh
    ``i > 0`` fits the template under a random rotation (seed ``i``), so the texture lies elsewhere
    on its triangles (``folder/training_meshes_remesh<i>.npz``); remesh 0 is the plain fit."""
    from scipy.spatial.transform import Rotation

    from jmeshtex.dgts import load_training_meshes, save_training_meshes

    folder.mkdir(parents=True, exist_ok=True)
    fine = levels + template  # one subdivision finer than the finest level
    reference = textured_sphere(kind, subdivisions=fine, period=DEPTH_TEXTURES[kind])
    suffix = f"_coarse{coarse_levels}" if coarse_levels else ""
    suffix += f"_remesh{remesh}" if remesh else ""
    suffix += f"_template{template}" if template != 1 else ""
    meshes_file = folder / f"training_meshes{suffix}.npz"
    if meshes_file.is_file():
        return reference, load_training_meshes(meshes_file)
    untextured = icosphere(fine) if coarse_levels else None  # the sphere under the texture
    tm = training_meshes(
        reference,
        icosphere(template),
        config=PrepareConfig(levels=levels),
        key=jax.random.key(0),
        coarse_reference=untextured,
        coarse_levels=coarse_levels,
        rotation=Rotation.random(random_state=remesh).as_matrix() if remesh else None,
        checkpoint_dir=meshes_file.with_suffix(".levels"),  # a stopped fit resumes by level
    )
    save_training_meshes(tm, meshes_file)
    shutil.rmtree(meshes_file.with_suffix(".levels"))
    return reference, tm


def score_transfers(report, section, models, target, start, kind, period, samples):
    """Each model's transfers to ``target`` from ``start`` (None: the default) and matched noise,
    scored against the oracle on the transfer's own base; returns ``(rows, oracle)``."""
    rows = {}
    for name, model in models.items():
        res = transfer(model, target, num_samples=samples, start_level=start, key=jax.random.key(1))
        rows[name] = [res.mesh(i) for i in range(samples)]
    base = (res.base, res.faces)
    oracle = oracle_texture(base, kind, period=period)
    own = texture_scores(oracle, oracle, base=base)
    rows["matched noise"] = [
        matched_noise(base, own.relief, key=jax.random.key(i)) for i in range(samples)
    ]
    score_rows(report, f"{section} (F={len(res.faces)})", rows, oracle, base, {}, period)
    return rows, oracle


def study_models(kind: str, runs: list[str], levels: int, work: pathlib.Path) -> dict:
    """``{run: (model, period in mean edges)}`` for the study models in ``work/<kind>/<run>/``
    (trained by :func:`noise_response`; a ``coarse<K>_…`` name tells its training meshes), and
    untrained weights at the last run's period as ``"untrained"``."""
    from jmeshtex.dgts import load

    models = {}
    for run in runs:
        coarse = int(re.match(r"coarse(\d+)_", run)[1]) if run.startswith("coarse") else 0
        _, tm = depth_meshes(kind, levels, work / kind, coarse)
        models[run] = (load(work / kind / run), period_in_mean_edges(tm, DEPTH_TEXTURES[kind]))
    models["untrained"] = (untrained_weights(tm, Config()), models[runs[-1]][1])
    return models


#: the truth-relative columns of :func:`score_transfers` rows (a study's note adds its own)
TRANSFER_SCORES_NOTE = (
    "density_vs_truth / relief_vs_truth: peak density and relief std over the oracle's on the "
    "transfer's own base"
)


def study_parser(
    doc: str, *, kind: bool = True, runs: bool = False, train_levels: int | None = None
) -> argparse.ArgumentParser:
    """The parser of a study at depth: described by the first line of ``doc``, with the texture
    ``kind`` (positional, when ``kind``), ``--levels`` (default ``train_levels``) and ``--steps``
    of the runs it trains (when ``train_levels`` is given), and :func:`add_study_arguments`."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    if kind:
        ap.add_argument("kind", choices=sorted(DEPTH_TEXTURES))
    if train_levels is not None:
        ap.add_argument("--levels", type=int, default=train_levels)
        ap.add_argument("--steps", type=int, default=2000, help="steps per level")
    add_study_arguments(ap, runs=runs)
    return ap


def study_arguments(args: argparse.Namespace) -> dict:
    """The shared settings a :func:`study_parser` parsed: ``levels``, ``steps`` (where it has them),
    ``work`` and ``samples``, as keywords of the study's function."""
    names = ("levels", "steps", "work", "samples")
    return {name: getattr(args, name) for name in names if hasattr(args, name)}


def add_study_arguments(ap: argparse.ArgumentParser, *, runs: bool = False) -> None:
    """The arguments the studies at depth share: ``--samples``, ``--work`` (the resumable runs, a
    folder per texture) and, for the studies of trained runs, ``--runs`` and ``--levels``."""
    if runs:
        ap.add_argument(
            "--runs",
            nargs="+",
            default=["fake_inputs_sampled_2000"],
            help="study run folders under --work/KIND (trained by dgts_noise_response.py)",
        )
        ap.add_argument("--levels", type=int, default=4, help="levels of the runs at depth")
    ap.add_argument("--samples", type=int, default=3, help="transfer samples per row")
    ap.add_argument(
        "--work",
        type=pathlib.Path,
        default=pathlib.Path(__file__).resolve().parents[1] / "runs" / "dgts_depth",
        help="the resumable runs at depth (folder per texture)",
    )

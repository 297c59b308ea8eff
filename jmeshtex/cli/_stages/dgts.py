"""A small DGTS run for ``jmeshtex demo``: a knobs sphere's texture learned from an icosphere
template, transferred to a torus and scored against its oracle.
"""

from __future__ import annotations

import os
import pathlib
import time

import jax
import numpy as np

from ...dgts import Config, PrepareConfig
from ._views import Progress, say, view


def tiny_configs(quick: bool = True) -> tuple[PrepareConfig, Config]:
    """Small configurations that train in seconds (quick) or in under a minute on a laptop CPU.

    Both share one width at every level and ``shared_levels`` = all levels, so training compiles
    one step for the whole hierarchy; the full one adds a third level (a finer output) and more
    steps. The learning test and the tiny DGTS study use the quick one.
    """
    if quick:  # equal widths at both levels and shared_levels=2: one compiled step for both
        return PrepareConfig.tiny(), Config.tiny()
    return PrepareConfig.tiny(levels=3), Config.tiny(steps=160, shared_levels=3)


#: the demo's reference: knobs on a sphere at this period (2.8 mean edges at level 1 of an
#: icosphere(2) template, 5.7 at level 2: laid out at one level, shaped at the next)
PERIOD = 0.45


def demo_stage(out_dir: str | os.PathLike, *, quick: bool, progress: Progress = None) -> dict:
    """Run a tiny DGTS train + transfer, write ``dgts.png`` and return a summary dict.

    The reference is a knobs sphere (:func:`~jmeshtex.data.textured_sphere`, period ``PERIOD``),
    the template an icosphere(2), the target a 64 × 24 torus (quick: 32 × 12), transferred from
    level 0 (every generator runs: the target is subdivided before the levels that lay the texture
    out, as in training). Each output is scored against its oracle, the reference's knobs at the
    reference's period on the output's own base (:func:`~jmeshtex.dgts.core.oracle_texture`), by
    :func:`~jmeshtex.dgts.core.knob_scores`: knobs per squared period as a ratio to the oracle's,
    and the patch distance to the oracle, beside untrained weights, no displacement and Gaussian
    noise of the oracle's band-passed relief (:func:`~jmeshtex.dgts.core.texture_noise`).
    The figure (:func:`jmeshtex.render.figure`, smooth-shaded geometry): the reference, the finest
    training mesh, the oracle, two transferred samples and two baselines.

    Args:
      out_dir: folder for ``dgts.png``.
      quick: :func:`tiny_configs` preset (two levels; the full one has three and 160 steps).
      progress: called with status lines (fitting levels), or None; with a hook, training shows
        its own tqdm bar per level.

    Returns:
      ``{"png": path, "seconds": ..., "levels": ..., "faces": ..., "density_trained": ...,
      "density_untrained": ..., "density_noise": ..., "density_flat": ..., "relief_trained": ...,
      "distance_trained": ..., "distance_untrained": ..., "distance_noise": ...,
      "distance_flat": ..., "summary": str}``
      (knob densities and relief as ratios to the oracle's, patch distances in periods; means
      over two samples).
    """
    from ...data import icosphere, textured_sphere, torus
    from ...dgts import train, training_meshes, transfer
    from ...dgts.core import (
        knob_scores,
        oracle_texture,
        period_in_mean_edges,
        texture_noise,
        texture_operators,
    )
    from ...render import figure

    t0 = time.perf_counter()
    out = pathlib.Path(out_dir)
    prep, cfg = tiny_configs(quick)
    k_prepare, k_train, k_transfer = jax.random.split(jax.random.key(0), 3)
    ref = textured_sphere("knobs", subdivisions=4, period=PERIOD)

    def fitting(stage: str, done: int, total: int) -> None:
        say(progress, f"training meshes: {stage} {done}/{total}")

    tm = training_meshes(
        ref,
        icosphere(2),
        config=prep,
        key=k_prepare,
        progress=fitting if progress is not None else False,
    )
    say(progress, f"training {tm.num_levels} levels")
    model = train(tm, cfg, key=k_train, progress=progress is not None).model
    untrained = train(tm, cfg.replace(steps=0), key=k_train, progress=False).model
    say(progress, "transfer")
    target = torus(32, 12) if quick else torus(64, 24)
    res = transfer(model, target, num_samples=2, start_level=0, key=k_transfer)
    res_untrained = transfer(untrained, target, num_samples=2, start_level=0, key=k_transfer)
    base = (res.base, res.faces)
    period = period_in_mean_edges(tm, PERIOD)
    ops = texture_operators(base, period=period)
    oracle = oracle_texture(base, "knobs", period=period)
    own = knob_scores(oracle, oracle, ops=ops)
    noise = [texture_noise(base, ops, own.relief, key=jax.random.key(i)) for i in range(2)]

    def ratios(meshes) -> tuple[float, float, float]:
        """Mean knob density and relief of ``meshes`` over the oracle's; mean patch distance."""
        scores = [knob_scores(m, oracle, ops=ops) for m in meshes]
        density = np.mean([s.density for s in scores]) / own.density
        relief = np.mean([s.relief for s in scores]) / own.relief
        return float(density), float(relief), float(np.mean([s.distance for s in scores]))

    trained_r = ratios([res.mesh(0), res.mesh(1)])
    untrained_r = ratios([res_untrained.mesh(0), res_untrained.mesh(1)])
    noise_r = ratios(noise)
    flat_r = ratios([base])  # no displacement: no peak above the oracle's threshold
    say(progress, "rendering")
    figure(
        [
            ("reference", view(ref)),
            (f"training level {tm.num_levels - 1}", view(tm.mesh(-1))),
            ("oracle on the torus", view(oracle)),
            (f"transfer: {trained_r[0]:.2f}x, d {trained_r[2]:.4f}", view(res.mesh(0))),
            ("transfer 2", view(res.mesh(1))),
            (
                f"untrained: {untrained_r[0]:.2f}x, d {untrained_r[2]:.4f}",
                view(res_untrained.mesh(0)),
            ),
            (f"noise: {noise_r[0]:.2f}x, d {noise_r[2]:.4f}", view(noise[0])),
        ],
        columns=7,
        title="DGTS: knobs learnt on a sphere, transferred to a torus "
        "(knob density over the oracle's, patch distance d)",
        path=out / "dgts.png",
    )
    seconds = time.perf_counter() - t0
    summary = (
        f"DGTS: {tm.num_levels} levels, reference {ref.num_faces} F, torus → {len(res.faces)} F, "
        f"knob density / relief over the oracle's {trained_r[0]:.2f} / {trained_r[1]:.2f}, "
        f"patch distance {trained_r[2]:.4f} (untrained {untrained_r[0]:.2f} / "
        f"{untrained_r[1]:.2f} / {untrained_r[2]:.4f}, no displacement {flat_r[2]:.4f}, noise "
        f"{noise_r[0]:.2f} / {noise_r[2]:.4f}), "
        f"{seconds:.1f} s"
    )
    return {
        "png": str(out / "dgts.png"),
        "seconds": seconds,
        "levels": tm.num_levels,
        "faces": int(len(res.faces)),
        "density_trained": trained_r[0],
        "density_untrained": untrained_r[0],
        "density_noise": noise_r[0],
        "density_flat": flat_r[0],
        "relief_trained": trained_r[1],
        "distance_trained": trained_r[2],
        "distance_untrained": untrained_r[2],
        "distance_noise": noise_r[2],
        "distance_flat": flat_r[2],
        "summary": summary,
    }

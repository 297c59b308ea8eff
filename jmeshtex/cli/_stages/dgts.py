"""DGTS for ``jmeshtex demo``: the shipped knobs model transferred to a torus and scored against its
oracle.
"""

from __future__ import annotations

import os
import pathlib
import time

import jax

from ._views import Progress, say, view

#: the level the demo's transfer starts at: the official code's default (``--gen-levels 1 4``)
START_LEVEL = 1


def demo_stage(out_dir: str | os.PathLike, *, quick: bool, progress: Progress = None) -> dict:
    """Transfer the shipped knobs model to a torus, write ``dgts.png`` and return a summary dict.

    The model is :func:`~jmeshtex.dgts.load_pretrained` (the paper's network, 4 levels x 1,000
    steps on a knobs sphere; loaded, not trained). It is transferred to a 64 x 24 torus (quick:
    32 x 12) from level 1, the official default, beside untrained weights of the same architecture
    (the same transfer). Each output is scored against its oracle, the reference's knobs at the
    reference's period on the output's own base (:func:`~jmeshtex.dgts.core.oracle_texture`), by
    :func:`~jmeshtex.dgts.core.knob_scores`: knobs per squared period as a ratio to the oracle's,
    and the patch distance to the oracle, beside untrained weights, no displacement and Gaussian
    noise of the oracle's band-passed relief (:func:`~jmeshtex.dgts.core.texture_noise`).
    The figure (:func:`jmeshtex.render.figure`, smooth-shaded geometry): the finest training mesh,
    the oracle, two transferred samples and two baselines.

    Args:
      out_dir: folder for ``dgts.png``.
      quick: the smaller torus.
      progress: called with status lines, or None.

    Returns:
      ``{"png": path, "seconds": ..., "levels": ..., "faces": ..., "density_trained": ...,
      "density_untrained": ..., "density_noise": ..., "density_flat": ..., "relief_trained": ...,
      "distance_trained": ..., "distance_untrained": ..., "distance_noise": ...,
      "distance_flat": ..., "summary": str}``
      (knob densities and relief as ratios to the oracle's, patch distances in periods; means
      over two samples).
    """
    from ...data import torus
    from ...dgts import (
        load_pretrained,
        pretrained_period,
        pretrained_training_meshes,
        train,
        transfer,
    )
    from ...dgts.core import period_in_mean_edges, scores_beside_baselines

    t0 = time.perf_counter()
    out = pathlib.Path(out_dir)
    k_transfer = jax.random.key(1)
    say(progress, "loading the shipped knobs model")
    model = load_pretrained("knobs")
    tm = pretrained_training_meshes("knobs")
    untrained = train(
        tm, model.config.replace(steps=0), key=jax.random.key(0), progress=False
    ).model
    say(progress, "transfer")
    target = torus(32, 12) if quick else torus(64, 24)
    res = transfer(model, target, num_samples=2, start_level=START_LEVEL, key=k_transfer)
    res_untrained = transfer(
        untrained, target, num_samples=2, start_level=START_LEVEL, key=k_transfer
    )
    scores, oracle, noise = scores_beside_baselines(
        {
            "trained": [res.mesh(0), res.mesh(1)],
            "untrained": [res_untrained.mesh(0), res_untrained.mesh(1)],
        },
        (res.base, res.faces),
        kind="knobs",
        period=period_in_mean_edges(tm, pretrained_period("knobs")),
        key=jax.random.key(0),
    )
    say(progress, "rendering")
    _figure(out / "dgts.png", tm, oracle, res, res_untrained, noise[0], scores)
    return _summary(out / "dgts.png", time.perf_counter() - t0, tm, res, scores)


def _figure(path: pathlib.Path, tm, oracle, res, res_untrained, noise, scores: dict) -> None:
    """``dgts.png``: the finest training mesh, the oracle, two transfers, the untrained weights'
    transfer and the noise baseline, with their knob densities and patch distances."""
    from ...render import figure

    trained_r, untrained_r, noise_r = scores["trained"], scores["untrained"], scores["noise"]
    figure(
        [
            (f"training level {tm.num_levels - 1}", view(tm.mesh(-1))),
            ("oracle on the torus", view(oracle)),
            (f"transfer: {trained_r[0]:.2f}x, d {trained_r[2]:.4f}", view(res.mesh(0))),
            ("transfer 2", view(res.mesh(1))),
            (
                f"untrained: {untrained_r[0]:.2f}x, d {untrained_r[2]:.4f}",
                view(res_untrained.mesh(0)),
            ),
            (f"noise: {noise_r[0]:.2f}x, d {noise_r[2]:.4f}", view(noise)),
        ],
        columns=6,
        title="DGTS: the shipped knobs model (learnt on a sphere) transferred to a torus from "
        f"level {START_LEVEL} (knob density over the oracle's, patch distance d)",
        path=path,
    )


def _summary(png: pathlib.Path, seconds: float, tm, res, scores: dict) -> dict:
    """The stage's summary dict (:func:`demo_stage`'s Returns) from the scores of each row."""
    trained_r, untrained_r = scores["trained"], scores["untrained"]
    noise_r, flat_r = scores["noise"], scores["no displacement"]
    summary = (
        f"DGTS: shipped knobs model ({tm.num_levels} levels), torus from level {START_LEVEL} → "
        f"{len(res.faces)} F, "
        f"knob density / relief over the oracle's {trained_r[0]:.2f} / {trained_r[1]:.2f}, "
        f"patch distance {trained_r[2]:.4f} (untrained {untrained_r[0]:.2f} / "
        f"{untrained_r[1]:.2f} / {untrained_r[2]:.4f}, no displacement {flat_r[2]:.4f}, noise "
        f"{noise_r[0]:.2f} / {noise_r[2]:.4f}), "
        f"{seconds:.1f} s"
    )
    return {
        "png": str(png),
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

"""A small DGTS run for ``jmeshtex demo``, the notebook and the learning check: a bumpy sphere's
texture learned from an icosphere template and transferred to a torus.
"""

from __future__ import annotations

import os
import pathlib
import time

import jax
import numpy as np

from ...data import bumpy_sphere
from ...dgts import Config, PrepareConfig
from ._views import Progress, say, view


def tiny_configs(quick: bool = True) -> tuple[PrepareConfig, Config]:
    """Small configurations that train in seconds (quick) or in under a minute on a laptop CPU.

    Both share one width at every level and ``shared_levels`` = all levels, so training compiles
    one step for the whole hierarchy; the full one adds a third level (a finer output) and more
    steps. The learning test and ``benchmarks/dgts.py`` use the quick one.
    """
    if quick:  # equal widths at both levels and shared_levels=2: one compiled step for both
        return PrepareConfig.tiny(), Config.tiny()
    return PrepareConfig.tiny(levels=3), Config.tiny(steps=160, shared_levels=3)


def demo_stage(out_dir: str | os.PathLike, *, quick: bool, progress: Progress = None) -> dict:
    """Run a tiny DGTS train + transfer, write ``dgts.png`` and return a summary dict.

    The reference is :func:`bumpy_sphere`, the template an icosphere, the target a torus. The
    figure (:func:`jmeshtex.render.figure`, smooth-shaded geometry): the reference (the exemplar),
    the finest training mesh, two transferred samples, and two baselines on the subdivided torus:
    no displacement, and Gaussian normal noise with the reference's height spread.

    Args:
      out_dir: folder for ``dgts.png``.
      quick: :func:`tiny_configs` preset.
      progress: called with status lines (fitting levels), or None; with a hook, training shows
        its own tqdm bar per level.

    Returns:
      ``{"png": path, "seconds": ..., "levels": ..., "faces": ..., "w1_trained": ..., "w1_flat": ...,
      "w1_noise": ..., "summary": str}`` (W1 of the normal-height distributions to the finest
      training mesh's).
    """
    from scipy.stats import wasserstein_distance

    from ...data import icosphere, torus
    from ...dgts import train, training_meshes, transfer
    from ...dgts.core import normal_heights
    from ...render import figure

    t0 = time.perf_counter()
    out = pathlib.Path(out_dir)
    prep, cfg = tiny_configs(quick)
    k_prepare, k_train, k_transfer = jax.random.split(jax.random.key(0), 3)
    ref = bumpy_sphere(subdivisions=3 if quick else 4)

    def fitting(stage: str, done: int, total: int) -> None:
        say(progress, f"training meshes: {stage} {done}/{total}")

    tm = training_meshes(
        ref,
        icosphere(1),
        config=prep,
        key=k_prepare,
        progress=fitting if progress is not None else False,
    )
    say(progress, f"training {tm.num_levels} levels")
    model = train(tm, cfg, key=k_train, progress=progress is not None).model
    say(progress, "transfer")
    target = torus(16, 8) if quick else torus(24, 12)
    # every level, not the default start (level 1 for this target): the two-level bumpy-sphere
    # model's heights are closest to the reference's from level 0 (tests/dgts/test_learning.py)
    res = transfer(model, target, num_samples=2, start_level=0, key=k_transfer)
    h_ref = normal_heights(tm.mesh(-1))
    edge = float(
        np.linalg.norm(res.base[res.faces[:, 0]] - res.base[res.faces[:, 1]], axis=1).mean()
    )
    noisy = res.base + np.random.default_rng(0).standard_normal(res.base.shape) * h_ref.std() * edge
    w1 = wasserstein_distance(h_ref, normal_heights(res.mesh(0)))
    w1_flat = wasserstein_distance(h_ref, normal_heights((res.base, res.faces)))
    w1_noise = wasserstein_distance(h_ref, normal_heights((noisy, res.faces)))
    say(progress, "rendering")
    figure(
        [
            ("reference (exemplar)", view(ref)),
            (f"training level {tm.num_levels - 1}", view(tm.mesh(-1))),
            (f"transfer 1, W1 {w1:.2f}", view(res.mesh(0))),
            ("transfer 2", view(res.mesh(1))),
            (f"baseline: none, W1 {w1_flat:.2f}", view((res.base, res.faces))),
            (f"baseline: noise, W1 {w1_noise:.2f}", view((noisy, res.faces))),
        ],
        columns=6,
        title="DGTS: a bumpy sphere's geometric texture transferred to a torus "
        "(W1 of normal heights to the reference)",
        path=out / "dgts.png",
    )
    seconds = time.perf_counter() - t0
    summary = (
        f"DGTS: {tm.num_levels} levels, reference {ref.num_faces} F, torus → {len(res.faces)} F, "
        f"W1(heights) {w1:.3f} (no displacement {w1_flat:.3f}, noise {w1_noise:.3f}), {seconds:.1f} s"
    )
    return {
        "png": str(out / "dgts.png"),
        "seconds": seconds,
        "levels": tm.num_levels,
        "faces": int(len(res.faces)),
        "w1_trained": float(w1),
        "w1_flat": float(w1_flat),
        "w1_noise": float(w1_noise),
        "summary": summary,
    }

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


def tiny_configs(quick: bool = True) -> tuple[PrepareConfig, Config]:
    """Small configurations that train in seconds on a laptop CPU (quick) or in a few minutes."""
    if quick:
        prep = PrepareConfig(levels=2, steps=150, samples_per_level=800)
        # equal widths at both levels and shared_levels=2: one compiled training step for both
        train = Config(num_layers=4, start_features=16, min_features=16, max_features=16, steps=120,
                       learning_rate_decay_every=100, shared_levels=2)
    else:
        prep = PrepareConfig(levels=3, steps=400, samples_per_level=1500)
        train = Config(num_layers=5, start_features=32, min_features=16, max_features=64, steps=400,
                       learning_rate_decay_every=200)
    return prep, train


def demo_stage(out_dir: str | os.PathLike, *, quick: bool) -> dict:
    """Run a tiny DGTS train + transfer, write ``dgts.png`` and return a summary dict.

    The reference is :func:`bumpy_sphere`, the template an icosphere, the target a torus. The panel
    shows the reference, the finest training mesh, and two transferred samples coloured by their
    displacement along the normal.

    Returns:
      ``{"png": path, "seconds": ..., "levels": ..., "faces": ..., "w1_trained": ..., "summary": str}``.
    """
    from ...data import icosphere, torus
    from ...dgts import normal_heights, train, training_meshes, transfer
    from ...render import render_grid, render_mesh

    t0 = time.perf_counter()
    out = pathlib.Path(out_dir)
    prep, cfg = tiny_configs(quick)
    k_prepare, k_train, k_transfer = jax.random.split(jax.random.key(0), 3)
    ref = bumpy_sphere(subdivisions=3 if quick else 4)
    tm = training_meshes(ref, icosphere(1), config=prep, key=k_prepare, progress=False)
    model = train(tm, cfg, key=k_train, progress=False).model
    target = torus(16, 8) if quick else torus(24, 12)
    res = transfer(model, target, num_samples=2, key=k_transfer)
    size = (300, 300)
    lim = float(np.abs(res.heights).max()) or 1.0
    images = [
        render_mesh(*ref, size=size),
        render_mesh(*tm.mesh(-1), size=size),
    ] + [
        render_mesh(*res.mesh(i), scalars=h, cmap="coolwarm", clim=(-lim, lim), size=size)
        for i, h in enumerate(res.heights)
    ]
    png = render_grid(images, out / "dgts.png", titles=["reference", f"training level {tm.num_levels - 1}",
                                                         "transfer 1", "transfer 2"], columns=4)
    del png
    from scipy.stats import wasserstein_distance

    w1 = wasserstein_distance(normal_heights(tm.mesh(-1)), normal_heights(res.mesh(0)))
    seconds = time.perf_counter() - t0
    summary = (f"DGTS: {tm.num_levels} levels, reference {ref.num_faces} F, torus → {len(res.faces)} F, "
               f"W1(heights) {w1:.3f}, {seconds:.1f} s")
    return {"png": str(out / "dgts.png"), "seconds": seconds, "levels": tm.num_levels,
            "faces": int(len(res.faces)), "w1_trained": float(w1), "summary": summary}

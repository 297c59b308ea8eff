"""The MeshMatch stage of ``jmeshtex demo``: a tiny self-transfer with renders and a summary."""

from __future__ import annotations

import time

import numpy as np

from ._views import Progress, folder, say, view


def demo_meshes(quick: bool = True):
    """:func:`jmeshtex.data.coloured_sphere_pair` at the demo's size: ``(source, target, truth)``."""
    from ...data import coloured_sphere_pair

    return coloured_sphere_pair(3 if quick else 4)


def demo_stage(out_dir, *, quick: bool, progress: Progress = None) -> dict:
    """Run a tiny MeshMatch self-transfer and write ``meshmatch.png``; summarise it.

    The figure (:func:`jmeshtex.render.figure`): the source with its colours (the exemplar), the
    target with the transferred colours, the nearest-neighbour field, and the two baselines of the
    evaluation protocol on the target: the source's mean colour everywhere
    (:func:`~jmeshtex.metrics.flat_baseline`) and the source's colours at random source vertices
    (a permuted field).

    Args:
      out_dir: folder for ``meshmatch.png``.
      quick: the small setting (642-vertex source, 2562-vertex target).
      progress: called with a status line per pyramid level (the demo's bar), or None.

    Returns:
      ``{"summary": str, "psnr_db": float, "random_psnr_db": float, "flat_psnr_db": float,
      "seconds": float, "files": [...]}``.
    """
    import jax

    from ... import render
    from ...meshmatch import Config, meshmatch
    from ...meshmatch.core import nnf_colors
    from ...metrics import flat_baseline, psnr

    out = folder(out_dir)
    t0 = time.perf_counter()
    source, target, truth = demo_meshes(quick)
    sc = source.vertex_colors
    result = meshmatch(
        source,
        sc,
        target,
        key=jax.random.key(0),
        config=Config(),
        progress=(lambda line: say(progress, line)) if progress is not None else False,
    )
    rng = np.random.default_rng(0)
    random_colors = sc[rng.integers(0, source.num_vertices, target.num_vertices)]
    flat_colors = np.broadcast_to(flat_baseline(sc)[0], truth.shape)
    geometry = (target.vertices, target.faces)
    value, baseline, flat = (
        psnr(result.colors, truth),
        psnr(random_colors, truth),
        psnr(flat_colors, truth),
    )
    render.figure(
        [
            ("source (exemplar)", view(source)),
            (
                f"transferred, {value:.1f} dB",
                view(geometry, vertex_colors=np.clip(result.colors, 0, 1)),
            ),
            (
                "nearest-neighbour field",
                view(geometry, vertex_colors=nnf_colors(source, result.nnf)),
            ),
            (f"baseline: flat, {flat:.1f} dB", view(geometry, vertex_colors=flat_colors)),
            (f"baseline: random, {baseline:.1f} dB", view(geometry, vertex_colors=random_colors)),
        ],
        columns=5,
        title="MeshMatch: self-transfer to a 4x finer mesh (PSNR vs the true colours)",
        path=out / "meshmatch.png",
    )
    seconds = time.perf_counter() - t0
    return {
        "summary": (
            f"MeshMatch self-transfer {source.num_vertices} → {target.num_vertices} vertices: PSNR "
            f"{value:.1f} dB (random field {baseline:.1f} dB, flat {flat:.1f} dB), {seconds:.1f} s"
        ),
        "psnr_db": value,
        "random_psnr_db": baseline,
        "flat_psnr_db": flat,
        "seconds": seconds,
        "files": [str(out / "meshmatch.png")],
    }

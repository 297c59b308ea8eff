"""The MeshMatch stage of ``jmeshtex demo``: a tiny self-transfer with renders and a summary."""

from __future__ import annotations

import pathlib
import time

import numpy as np


def demo_meshes(quick: bool = True):
    """A bumpy sphere with a procedural colour field (source) and its subdivided copy (target).

    Returns ``(source_vertices, source_faces, source_colors, target_vertices, target_faces,
    target_truth)``: the truth is the same colour field evaluated at the target's vertices.

    Example:
      >>> sv, sf, sc, tv, tf, truth = demo_meshes(quick=True)
      >>> sv.shape, tv.shape, truth.shape
      ((642, 3), (2562, 3), (2562, 3))
    """
    from ...data import icosphere
    from ...geometry import subdivide_midpoint

    v, f = icosphere(3 if quick else 4)
    fine = subdivide_midpoint(v, f)
    tv = fine.vertices / np.linalg.norm(fine.vertices, axis=1, keepdims=True)

    def bumpy(p):
        r = 1 + 0.25 * np.sin(3 * p[:, 0] + 1) * np.cos(2 * p[:, 1]) + 0.15 * np.sin(4 * p[:, 2] + 0.5)
        return p * r[:, None]

    def colour(p):
        return np.stack([
            0.5 + 0.4 * np.sin(6 * p[:, 0]) * np.cos(5 * p[:, 1]),
            0.5 + 0.4 * np.sin(7 * p[:, 2] + 1),
            0.5 + 0.3 * np.cos(4 * p[:, 0] + 3 * p[:, 1]),
        ], axis=1)

    return bumpy(v), f, colour(v), bumpy(tv), fine.faces, colour(tv)


def psnr(a, b) -> float:
    """Peak signal-to-noise ratio of colours in [0, 1]: ``10 log10(1 / MSE)`` (dB).

    Example:
      >>> round(psnr(np.zeros(4), np.full(4, 0.1)), 6)
      20.0
    """
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return float("inf") if mse == 0 else float(10.0 * np.log10(1.0 / mse))


def nnf_colors(source_vertices, nnf) -> np.ndarray:
    """Colour-code a nearest-neighbour field: each target vertex shows its match's source position.

    Example:
      >>> nnf_colors(np.array([[0.0, 0, 0], [1, 2, 3]]), np.array([1, 0])).tolist()
      [[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]]
    """
    v = np.asarray(source_vertices, np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    return ((v - lo) / np.where(hi > lo, hi - lo, 1.0))[np.asarray(nnf)]


def demo_stage(out_dir, *, quick: bool) -> dict:
    """Run a tiny MeshMatch self-transfer, write PNGs (source, target, NN field) and summarise it.

    Args:
      out_dir: folder for ``meshmatch_source.png``, ``meshmatch_target.png``, ``meshmatch_nnf.png``
        and ``meshmatch.png`` (the three side by side).
      quick: the small setting (642-vertex source, 2562-vertex target).

    Returns:
      ``{"summary": str, "psnr_db": float, "random_psnr_db": float, "seconds": float, "files": [...]}``.

    Example:
      >>> import tempfile
      >>> out = demo_stage(tempfile.mkdtemp(), quick=True)  # doctest: +SKIP
    """
    from ... import render
    from ...meshmatch import MeshMatchConfig, meshmatch

    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    sv, sf, sc, tv, tf, truth = demo_meshes(quick)
    result = meshmatch(sv, sf, sc, tv, tf, config=MeshMatchConfig(), seed=0)
    rng = np.random.default_rng(0)
    random_colors = sc[rng.integers(0, len(sv), len(tv))]
    size = (320, 300)
    images = [
        render.render_mesh(sv, sf, out / "meshmatch_source.png", vertex_colors=sc, size=size, title="source"),
        render.render_mesh(tv, tf, out / "meshmatch_target.png", vertex_colors=np.clip(result.colors, 0, 1),
                           size=size, title="target (transferred)"),
        render.render_mesh(tv, tf, out / "meshmatch_nnf.png", vertex_colors=nnf_colors(sv, result.nnf),
                           size=size, title="nearest-neighbour field"),
    ]
    render.render_grid(images, out / "meshmatch.png", columns=3)
    seconds = time.perf_counter() - t0
    value, baseline = psnr(result.colors, truth), psnr(random_colors, truth)
    return {
        "summary": (f"MeshMatch self-transfer {len(sv)} → {len(tv)} vertices: PSNR {value:.1f} dB "
                    f"(random field {baseline:.1f} dB), {seconds:.1f} s"),
        "psnr_db": value,
        "random_psnr_db": baseline,
        "seconds": seconds,
        "files": [str(out / n) for n in ("meshmatch_source.png", "meshmatch_target.png",
                                         "meshmatch_nnf.png", "meshmatch.png")],
    }

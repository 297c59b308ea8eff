"""The FL-VAE stage of ``jmeshtex demo``: encode a textured sheet, reconstruct its atlas, render."""

from __future__ import annotations

import pathlib
import time

import numpy as np


def demo_mesh(quick: bool = True):
    """A gently curved sheet textured with scikit-image's ``coffee`` image (UV = the flat layout).

    Example:
      >>> m = demo_mesh(quick=True)
      >>> m.num_vertices, m.texture.shape
      (600, (100, 150, 3))
    """
    from ...fl import builtin_images, planar_mesh

    image = builtin_images(max_size=150 if quick else 300, names=("coffee",))[0]
    mesh = planar_mesh(image, 600 if quick else 3000, rng=np.random.default_rng(0))
    v = mesh.vertices.copy()
    v[:, 2] = 0.15 * np.sin(2.0 * v[:, 0]) * np.cos(1.5 * v[:, 1])  # bend it: the latents are intrinsic
    return mesh.replace(vertices=v, name="coffee_sheet")


def demo_stage(out_dir, *, quick: bool) -> dict:
    """Encode a textured sheet with the shipped FL-VAE, reconstruct its texture, write PNGs.

    Args:
      out_dir: folder for ``fl_texture.png`` (reconstructed atlas) and ``fl.png`` (original and
        reconstruction rendered side by side).
      quick: the small setting (600 vertices, 150-pixel texture, no LPIPS).

    Returns:
      ``{"summary": str, "psnr_db": float, "dssim": float, "seconds": float, "files": [...]}``.

    Example:
      >>> import tempfile
      >>> out = demo_stage(tempfile.mkdtemp(), quick=True)  # doctest: +SKIP
    """
    import jax

    from ...fl import load_pretrained, reconstruct, side_by_side
    from ...io import save_png

    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    model = load_pretrained()
    config = model.config
    mesh = demo_mesh(quick)
    result = reconstruct(model, mesh, key=jax.random.key(0), lpips=not quick)
    files = [out / "fl_texture.png", out / "fl.png"]
    save_png(result.texture, files[0])
    side_by_side(mesh, result, files[1], y_up=False, view=(60.0, -90.0))
    seconds = time.perf_counter() - t0
    m = result.metrics
    summary = (f"FL-VAE: {mesh.num_vertices}-vertex sheet, {config.latent_dim} complex latents per vertex, "
               f"atlas PSNR {m['psnr']:.2f} dB, DSSIM {m['dssim']:.3f}"
               + (f", LPIPS {m['lpips']:.3f}" if "lpips" in m else "") + f" ({seconds:.1f} s)")
    return {"summary": summary, "psnr_db": m["psnr"], "dssim": m["dssim"], "seconds": seconds,
            "files": [str(f) for f in files]}

"""The FL-VAE stage of ``jmeshtex demo``: encode a textured sheet, reconstruct its atlas, render."""

from __future__ import annotations

import time

import numpy as np

from ._views import Progress, folder, say, view


def demo_mesh(quick: bool = True):
    """A gently curved sheet textured with scikit-image's ``coffee`` image (UV = the flat layout).

    Example:
      >>> m = demo_mesh(quick=True)
      >>> m.num_vertices, m.texture.shape
      (600, (100, 150, 3))
    """
    from ...fl.core import builtin_images, planar_mesh

    image = builtin_images(max_size=150 if quick else 300, names=("coffee",))[0]
    mesh = planar_mesh(image, 600 if quick else 3000, rng=np.random.default_rng(0))
    v = mesh.vertices.copy()
    v[:, 2] = (
        0.15 * np.sin(2.0 * v[:, 0]) * np.cos(1.5 * v[:, 1])
    )  # bend it: the latents are intrinsic
    return mesh.replace(vertices=v, name="coffee_sheet")


def demo_stage(out_dir, *, quick: bool, progress: Progress = None) -> dict:
    """Encode a textured sheet with the shipped FL-VAE, reconstruct its texture, write PNGs.

    The figure (:func:`jmeshtex.render.figure`, textured renders): the exemplar image, the sheet
    with its original texture, with the reconstructed atlas, and with the protocol's two
    baselines (:func:`~jmeshtex.metrics.flat_baseline`: the mean colour on every used texel;
    :func:`~jmeshtex.metrics.permuted_baseline`: the used texels shuffled) and the P1 oracle (the
    true colour at each vertex, interpolated linearly: :func:`~jmeshtex.fl.core.p1_baselines`),
    each with its atlas PSNR; the summary also gives the least-squares P1 fit.

    Args:
      out_dir: folder for ``fl_texture.png`` (reconstructed atlas) and ``fl.png`` (the figure).
      quick: the small setting (600 vertices, 150-pixel texture, no LPIPS).
      progress: called with status lines, or None.

    Returns:
      ``{"summary": str, "psnr_db": float, "dssim": float, "flat_psnr_db": float,
      "permuted_psnr_db": float, "p1_oracle_psnr_db": float, "p1_fit_psnr_db": float,
      "seconds": float, "files": [...]}``.
    """
    import jax

    from ...fl import load_pretrained, reconstruct
    from ...fl.core import atlas_metrics, p1_baselines
    from ...io import save_png
    from ...metrics import flat_baseline, permuted_baseline
    from ...render import figure

    out = folder(out_dir)
    t0 = time.perf_counter()
    model = load_pretrained()
    config = model.config
    mesh = demo_mesh(quick)
    say(progress, "encode / decode")
    result = reconstruct(model, mesh, key=jax.random.key(0), lpips=not quick)
    files = [out / "fl_texture.png", out / "fl.png"]
    save_png(result.texture, files[0])
    say(progress, "rendering")
    flat = flat_baseline(result.target, mask=result.valid)
    shuffled = permuted_baseline(result.target, key=jax.random.key(1), mask=result.valid)
    m = result.metrics
    m_flat = atlas_metrics(flat, result.target, result.valid, lpips=False)
    m_perm = atlas_metrics(shuffled, result.target, result.valid, lpips=False)
    p1 = p1_baselines(mesh, result)
    m_p1 = {k: atlas_metrics(a, result.target, result.valid, lpips=False) for k, a in p1.items()}
    geometry = (mesh.vertices, mesh.faces)

    scale = max(
        1, 280 // max(mesh.texture.shape[:2])
    )  # nearest-neighbour enlargement to the panel size

    def sheet(texture):
        return view(
            geometry, uv=mesh.uv, texture=np.clip(texture, 0.0, 1.0), azimuth=-90.0, elevation=40.0
        )

    figure(
        [
            ("exemplar image", np.kron(mesh.texture, np.ones((scale, scale, 1)))),
            ("original texture", sheet(result.target)),
            (f"FL-VAE, {m['psnr']:.1f} dB", sheet(result.texture)),
            (f"baseline: flat, {m_flat['psnr']:.1f} dB", sheet(flat)),
            (f"baseline: shuffled, {m_perm['psnr']:.1f} dB", sheet(shuffled)),
            (f"P1 oracle, {m_p1['p1_oracle']['psnr']:.1f} dB", sheet(p1["p1_oracle"])),
        ],
        columns=6,
        title="FL-VAE: a textured sheet encoded to field latents and decoded (atlas PSNR)",
        path=files[1],
    )
    seconds = time.perf_counter() - t0
    summary = (
        f"FL-VAE: {mesh.num_vertices}-vertex sheet, {config.latent_dim} complex latents per vertex, "
        f"atlas PSNR {m['psnr']:.2f} dB (flat {m_flat['psnr']:.2f}, shuffled {m_perm['psnr']:.2f}, "
        f"P1 oracle {m_p1['p1_oracle']['psnr']:.2f}, least-squares P1 {m_p1['p1_fit']['psnr']:.2f}), "
        f"DSSIM {m['dssim']:.3f}"
        + (f", LPIPS {m['lpips']:.3f}" if "lpips" in m else "")
        + f" ({seconds:.1f} s)"
    )
    return {
        "summary": summary,
        "psnr_db": m["psnr"],
        "dssim": m["dssim"],
        "flat_psnr_db": m_flat["psnr"],
        "permuted_psnr_db": m_perm["psnr"],
        "p1_oracle_psnr_db": m_p1["p1_oracle"]["psnr"],
        "p1_fit_psnr_db": m_p1["p1_fit"]["psnr"],
        "seconds": seconds,
        "files": [str(f) for f in files],
    }

"""FLDM for ``jmeshtex demo``: the shipped Spot model sampled, inpainted and transferred (no training).

The model is :func:`jmeshtex.fldm.load_pretrained` (trained on the shipped FL-VAE's latents of
re-triangulated copies of Spot); its samples are decoded with that
FL-VAE (:func:`jmeshtex.fl.load_pretrained`) to Spot's own UV atlas. Beside them: Spot's texture,
its encoding decoded (the codec's ceiling: what a perfect model's sample of *this* texture could
look like), and the protocol's two do-nothing baselines, the best flat colour over the atlas' used
texels and the encoding's latents permuted over vertices (the right marginal, no structure). The
numbers behind the figure (the surface-patch measure, the decoder-free statistics, DDPM) are
``benchmarks/fldm.py``'s, in ``docs/results.md``.
"""

from __future__ import annotations

import os
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np

from ._views import Progress, say

#: the camera (elevation, azimuth in degrees, Spot z-up) of every panel
VIEW = (15.0, 35.0)


def _spot_z_up(subdivide: bool):
    """Spot turned from y-up to the renderer's z-up (the same surface, atlas and texture),
    midpoint-subdivided once if ``subdivide`` (11.7K vertices: the model's training density)."""
    from ...data import spot
    from ...geometry import subdivide_midpoint, subdivide_uv

    mesh = spot()
    v, f, uv = np.asarray(mesh.vertices), mesh.faces, mesh.uv
    if subdivide:
        s = subdivide_midpoint(v, f)
        v, f, uv = s.vertices, s.faces, subdivide_uv(uv)
    up = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)
    return mesh.replace(vertices=up, faces=f, uv=uv)


def _atlases(vae, mesh, fields: dict, atlas: int) -> dict[str, np.ndarray]:
    """Every field decoded to ``mesh``'s atlas (unused texels filled), plus ``"baseline: flat"``:
    the best constant colour over the texels the atlas uses."""
    from ... import fldm
    from ...geometry import fill_unused_texels
    from ...metrics import flat_baseline

    decoded = fldm.decode_samples(vae, mesh, np.stack(list(fields.values())), size=atlas)
    textures = {
        k: fill_unused_texels(d["texture"], d["valid"])
        for k, d in zip(fields, decoded, strict=True)
    }
    valid = decoded[0]["valid"]
    full = np.asarray(mesh.texture)
    truth = full[:: full.shape[0] // atlas, :: full.shape[1] // atlas]
    flat = flat_baseline(truth, mask=valid)[valid][0]
    textures["baseline: flat"] = np.broadcast_to(flat, truth.shape).astype(np.float32)
    return textures


def _figure(path: pathlib.Path, mesh, ring, textures: dict, size: tuple[int, int]) -> None:
    """``fldm.png``: Spot, the samples and the inpainting, the torus transfer (its vertex
    colours), the encoding decoded and the baselines, one view each."""
    from ...render import figure, render_mesh

    def draw(texture) -> np.ndarray:
        return render_mesh(mesh.replace(texture=texture), view=VIEW, size=size)

    panels = [("Spot", draw(mesh.texture))]
    panels += [
        (name, draw(textures[name])) for name in ("sample 1", "sample 2", "inpaint (rear kept)")
    ]
    panels += [(f"transfer: torus {ring.num_vertices} V", render_mesh(ring, view=VIEW, size=size))]
    panels += [
        (name, draw(textures[name]))
        for name in ("encoding decoded", "baseline: flat", "baseline: shuffled")
    ]
    figure(
        panels,
        columns=4,
        title="FLDM: the shipped Spot model (samples, inpainting, transfer) and its baselines",
        path=path,
    )


def demo_stage(out_dir: str | os.PathLike, *, quick: bool, progress: Progress = None) -> dict:
    """Sample the shipped FLDM Spot model, write ``fldm.png``, return a summary dict.

    The figure (:func:`jmeshtex.render.figure`, Spot z-up, one view): Spot, two samples on Spot
    midpoint-subdivided once (the model's training density), an inpainting (the rear half kept
    from Spot's encoding, the front half generated), a transfer to a torus (vertex colours), the
    encoding decoded, and the two baselines. DDIM with 50 steps (``quick``: Spot's own 2,930
    vertices, 10 steps and a 256² atlas, a smoke run).

    Args:
      out_dir: folder for ``fldm.png``.
      quick: a smoke run (fewer sampling steps, smaller atlas and panels).
      progress: called with status lines, or None.

    Returns:
      ``{"png", "seconds", "steps", "vertices", "summary"}``; the summary gives the neighbour
      correlation of ``|z|²`` (:func:`~jmeshtex.fldm.core.latent_statistics`) of a sample, of
      Spot's encoding and of the shuffled baseline.
    """
    from ... import fl, fldm
    from ...data import torus
    from ...fldm import core

    t0 = time.perf_counter()
    out = pathlib.Path(out_dir)
    steps, atlas, size = (10, 256, (240, 240)) if quick else (50, 512, (256, 256))
    say(progress, "loading the shipped FLDM and FL-VAE models")
    model, vae = fldm.load_pretrained(), fl.load_pretrained()
    mesh = _spot_z_up(subdivide=not quick)
    geometry = core.sampling_geometry(mesh, model)
    k_sample, k_inpaint, k_transfer, k_codec, k_shuffle = jax.random.split(jax.random.key(0), 5)
    say(progress, f"sampling 2 textures on Spot (DDIM, {steps} steps)")
    z = np.asarray(fldm.sample(model, geometry, key=k_sample, num_samples=2, steps=steps).latents)
    say(progress, "encoding Spot and inpainting its front half")
    known = fldm.encode(vae, mesh, model.config, key=k_codec, geometry=geometry)
    rear = mesh.vertices[:, 1] < np.median(mesh.vertices[:, 1])  # Spot (z-up) faces +y
    inpainted = fldm.inpaint(
        model, geometry, known, rear, key=k_inpaint, method="ddim", steps=steps
    ).latents[0]
    say(progress, "transfer to a torus")
    # Spot's area (5.7) at the sampling mesh's density: the textures' scale carries over
    n_major, n_minor = (80, 36) if quick else (160, 72)
    ring = torus(n_major, n_minor, major_radius=0.6, minor_radius=0.24)
    zt = fldm.sample(model, ring, key=k_transfer, num_samples=1, steps=steps).latents[0]
    shuffled = np.asarray(core.shuffle_latents(known, key=k_shuffle))
    say(progress, "decoding and rendering")
    fields = {"sample 1": z[0], "sample 2": z[1], "inpaint (rear kept)": inpainted}
    fields |= {"encoding decoded": known, "baseline: shuffled": shuffled}
    textures = _atlases(vae, mesh, fields, atlas)
    ring = ring.replace(vertex_colors=fldm.decode_samples(vae, ring, zt[None])[0]["vertex_colors"])
    _figure(out / "fldm.png", mesh, ring, textures, size)
    seconds = time.perf_counter() - t0
    corr = {
        name: float(core.latent_statistics(jnp.asarray(field), geometry.fine)["energy_correlation"])
        for name, field in (("samples", z[0]), ("encoding", known), ("shuffled", shuffled))
    }
    summary = (
        f"FLDM: shipped Spot model, 2 samples + inpaint + torus transfer on {mesh.num_vertices} V, "
        f"DDIM-{steps}; |z|² neighbour corr.: sample {corr['samples']:.2f}, Spot's encoding "
        f"{corr['encoding']:.2f}, shuffled {corr['shuffled']:.2f} (flat colour in the figure), "
        f"{seconds:.1f} s"
    )
    return {
        "png": str(out / "fldm.png"),
        "seconds": seconds,
        "steps": steps,
        "vertices": mesh.num_vertices,
        "summary": summary,
    }

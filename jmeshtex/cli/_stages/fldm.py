"""A small FLDM run for ``jmeshtex demo`` and the notebook: a striped sphere.

The exemplar is a unit sphere with latitudinal stripes, ``s(p) = ½ + ½ sin(ω p_z)``. To keep the
check about the *diffusion model* (and fast, with no pre-trained FL-VAE needed), the latents come
from a small analytic codec with the FL-VAE's contract (complex ``[V, d]`` in the one-ring frames):

.. math:: z_{v,0} = (a + s_v)\\, \\hat g_v, \\qquad z_{v,1} = i\\,(a + 1 - s_v)\\, \\hat g_v

with ``ĝ_v`` the unit tangent direction of the meridian (the stripes' gradient direction) in v's
frame, and decoding ``s = ½ (|z_0| − a) + ½ (1 + a − |z_1|)`` clipped to [0, 1]. Magnitudes carry the
colour, phases the stripes' orientation: a model must learn both the stripe statistics and a
coherent direction field. With a trained FL-VAE (:func:`jmeshtex.fldm.fl_vae_encoder`) the same
pipeline runs on real textures (``docs/results.md``).

The learning check on the same sphere is :func:`jmeshtex.testing.fldm_learning_check`.
"""

from __future__ import annotations

import os
import pathlib
import time

import jax
import numpy as np

from ...data import (
    intensity_to_rgb,
    rgb_to_intensity,
    stripe_decoder,
    stripe_encoder,
    striped_sphere,
)
from ._views import Progress, say, view

VIEWS = ((20.0, -60.0), (-30.0, 60.0))


def tiny_config(quick: bool = True):
    """The demo configuration (seconds on a CPU)."""
    from ...fldm import Config

    if quick:
        return Config.demo()
    return Config.cpu(  # the stripe codec is deterministic: one encoding per copy
        latent_channels=2,
        n_copies=8,
        copy_vertices=1500,
        steps=1500,
        diffusion_steps=1000,
        encodings_per_copy=1,
        invariants=False,  # the stripe codec's phases are coherent; the demo's bounds were measured without
    )


def demo_stage(out_dir: str | os.PathLike, *, quick: bool, progress: Progress = None) -> dict:
    """Run a tiny FLDM train + sample + inpaint + transfer, write ``fldm.png``, return a summary dict.

    The figure (:func:`jmeshtex.render.figure`, vertex colours, smooth-shaded): the exemplar, two
    samples on a training copy, an inpainting (upper half kept), a transfer to a finer
    re-triangulation (more vertices: smaller stripes, §6.6), and the protocol's two baselines on
    the copy: the exemplar's mean colour (:func:`~jmeshtex.metrics.flat_baseline`) and the copy's
    training latents permuted over vertices, decoded (the right marginal, no structure).

    Args:
      out_dir: folder for ``fldm.png``.
      quick: a smoke run (2 copies, 120 steps); else the learning check's configuration.
      progress: called with status lines, or None; with a hook, dataset building, training and
        sampling show their own tqdm bars.

    Returns:
      ``{"png", "seconds", "loss_first", "loss_last", "summary"}``.
    """
    from ... import fldm
    from ...geometry import remesh
    from ...metrics import flat_baseline, permuted_baseline
    from ...render import figure

    t0 = time.perf_counter()
    out = pathlib.Path(out_dir)
    bars = progress is not None
    cfg = tiny_config(True)  # full: the learning check's configuration (300 steps)
    if quick:  # a smoke run: a few seconds of training
        cfg = cfg.replace(n_copies=2, copy_vertices=300, steps=120)
    exemplar = striped_sphere(subdivisions=3)
    k_data, k_train, key = jax.random.split(jax.random.key(0), 3)
    say(progress, "building the dataset")
    data = fldm.build_dataset(exemplar, cfg, encode=stripe_encoder, key=k_data, progress=bars)
    say(progress, f"training {cfg.steps} steps")
    result = fldm.train(data, cfg, key=k_train, progress=bars)
    model = result.model
    target = data.meshes[0]
    say(progress, "sampling")
    z = fldm.sample(model, target, key=key, num_samples=2, steps=25).latents
    known = stripe_encoder(target)
    mask = target.vertices[:, 2] > 0
    say(progress, "inpainting")
    zi = fldm.inpaint(model, target, known, mask, key=key, method="ddim", steps=25).latents[0]
    say(progress, "transfer")
    fine = remesh(exemplar, n_vertices=2 * target.num_vertices, key=jax.random.key(99))
    zf = fldm.sample(model, fine, key=key, num_samples=1, steps=25).latents[0]
    say(progress, "rendering")
    # the copy's training latents decoded (per vertex, so permuting them = permuting this)
    copy = stripe_decoder(np.asarray(data.latents[0, : target.num_vertices]))[:, None]
    size = (240, 240)

    def stripes(mesh, intensity):
        return view(
            (mesh.vertices, mesh.faces),
            vertex_colors=intensity_to_rgb(intensity),
            azimuth=VIEWS[0][1],
            elevation=VIEWS[0][0],
            size=size,
        )

    figure(
        [
            ("exemplar", stripes(exemplar, rgb_to_intensity(exemplar.vertex_colors))),
            ("sample 1", stripes(target, stripe_decoder(z[0]))),
            ("sample 2", stripes(target, stripe_decoder(z[1]))),
            ("inpaint (top kept)", stripes(target, stripe_decoder(zi))),
            (f"transfer {fine.num_vertices} V", stripes(fine, stripe_decoder(zf))),
            ("baseline: flat", stripes(target, flat_baseline(copy)[:, 0])),
            ("baseline: shuffled", stripes(target, permuted_baseline(copy, key=key)[:, 0])),
        ],
        columns=4,
        title="FLDM: diffusion on field latents of a striped sphere",
        path=out / "fldm.png",
    )
    seconds = time.perf_counter() - t0
    losses = result.losses["loss"]
    first, last = float(np.mean(losses[:20])), float(np.mean(losses[-20:]))
    summary = (
        f"FLDM: {cfg.n_copies} copies × {cfg.copy_vertices} V, {len(losses)} steps, "
        f"{fldm.core.LOSS_NAMES[cfg.prediction]} {first:.3f} → {last:.3f}, 2 samples + inpaint + transfer, "
        f"{seconds:.1f} s"
    )
    return {
        "png": str(out / "fldm.png"),
        "seconds": seconds,
        "loss_first": first,
        "loss_last": last,
        "summary": summary,
    }

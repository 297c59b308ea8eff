"""A small FLDM run for ``jmeshtex demo``, the notebook and the learning check: a striped sphere.

The exemplar is a unit sphere with latitudinal stripes, ``s(p) = ½ + ½ sin(ω p_z)``. To keep the
check about the *diffusion model* (and fast, with no pre-trained FL-VAE needed), the latents come
from a small analytic codec with the FL-VAE's contract (complex ``[V, d]`` in the one-ring frames):

.. math:: z_{v,0} = (a + s_v)\\, \\hat g_v, \\qquad z_{v,1} = i\\,(a + 1 - s_v)\\, \\hat g_v

with ``ĝ_v`` the unit tangent direction of the meridian (the stripes' gradient direction) in v's
frame, and decoding ``s = ½ (|z_0| − a) + ½ (1 + a − |z_1|)`` clipped to [0, 1]. Magnitudes carry the
colour, phases the stripes' orientation: a model must learn both the stripe statistics and a
coherent direction field. With a trained FL-VAE (:func:`jmeshtex.fldm.fl_vae_encoder`) the same
pipeline runs on real textures (see ``benchmarks/fldm_spot.py``).

:func:`learning_check` trains a tiny model and compares the VGG Gram distance (texture statistics)
of its samples' renders to the exemplar's render with that of an untrained model's samples, and
measures the samples' pairwise LPIPS diversity. ``learning_check(codec="fl_vae")`` runs the same
check through the shipped FL-VAE instead of the analytic codec (encode the copies with
:func:`~jmeshtex.fldm.fl_vae_encoder`, decode sample latents with
:func:`~jmeshtex.fl.decode_vertex_colors`).
"""

from __future__ import annotations

import os
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np

from ..._mesh import Mesh
from ..._random import host_rng
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
    """The demo / learning-check configuration (seconds on a CPU)."""
    from ...fldm import Config

    if quick:
        return Config.demo()
    return Config.cpu(
        latent_channels=2, n_copies=8, copy_vertices=1500, steps=1500, diffusion_steps=1000
    )


def render_views(
    mesh: Mesh, intensity: np.ndarray, *, size: int = 128, crop: bool = False
) -> np.ndarray:
    """``[len(VIEWS), size, size, 3]`` renders (float in [0, 1]) of an intensity field on ``mesh``.

    ``crop``: render at twice the size and keep the central half, where the sphere fills the frame
    (texture statistics without background or silhouette, for the Gram distance).
    """
    return render_rgb_views(mesh, intensity_to_rgb(intensity), size=size, crop=crop)


def render_rgb_views(
    mesh: Mesh, rgb: np.ndarray, *, size: int = 128, crop: bool = False
) -> np.ndarray:
    """:func:`render_views` of per-vertex colours ``rgb [V, 3]`` in [0, 1] instead of an intensity."""
    from ...render import render_mesh

    rgb = np.asarray(rgb, np.float64)
    full = 2 * size if crop else size
    imgs = (
        np.stack(
            [
                render_mesh(
                    Mesh(mesh.vertices, mesh.faces, vertex_colors=rgb), view=v, size=(full, full)
                )
                for v in VIEWS
            ]
        ).astype(np.float32)
        / 255.0
    )
    if crop:
        a = size // 2
        imgs = imgs[:, a : a + size, a : a + size]
    return imgs


def learning_check(
    *,
    quick: bool = True,
    n_samples: int = 2,
    key: jax.Array | None = None,
    progress: bool = False,
    codec: str = "stripes",
    steps: int | None = None,
) -> dict:
    """Train a tiny FLDM on the striped sphere and measure fidelity and diversity of its samples.

    Args:
      quick: :func:`tiny_config` preset (True) or the larger CPU one.
      n_samples: samples of the trained and of the untrained model (same noise).
      key: PRNG key of the copies, the initialisation, training and sampling (default ``key(0)``).
      progress: tqdm bars.
      codec: ``"stripes"``: the analytic codec of the module docstring (2 channels);
        ``"fl_vae"``: the shipped FL-VAE (:func:`~jmeshtex.fl.load_pretrained`): copies encoded with
        :func:`~jmeshtex.fldm.fl_vae_encoder` (colours read on the exemplar), sample latents decoded with
        :func:`~jmeshtex.fl.decode_vertex_colors` and the colours rendered.
      steps: training steps (default: the preset's).

    Returns:
      ``{"gram_trained", "gram_untrained", "gram_codec", "gram_flat", "gram_shuffled",
      "lpips_diversity", "losses", "seconds", ...}``: mean Gram distance of sample renders to the
      exemplar's renders (trained and untrained model, same noise; ``gram_codec``: the codec's own
      reconstruction of the exemplar on the same copy, the floor the codec allows; ``gram_flat``: the
      exemplar's mean colour everywhere; ``gram_shuffled``: the copy's training latents permuted over
      vertices, decoded), mean pairwise LPIPS between trained samples, the loss curve.

    Raises:
      ConfigError: unknown ``codec``.
    """
    from ... import fldm
    from ..._errors import ConfigError
    from ...metrics import gram_distance, load_vgg16, lpips

    t0 = time.perf_counter()
    key = jax.random.key(0) if key is None else key
    k_codec, k_data, k_train, k_sample = jax.random.split(key, 4)
    exemplar = striped_sphere(subdivisions=3)
    cfg = tiny_config(quick)
    if steps is not None:
        cfg = cfg.replace(steps=int(steps))
    if codec == "stripes":
        encode = stripe_encoder

        def decode(mesh: Mesh, z: np.ndarray) -> np.ndarray:
            return intensity_to_rgb(stripe_decoder(z))
    elif codec == "fl_vae":
        from ...fl import decode_vertex_colors, load_pretrained

        vae = load_pretrained()
        encode = fldm.fl_vae_encoder(vae, exemplar, key=k_codec)
        cfg = cfg.replace(latent_channels=vae.config.latent_dim)

        def decode(mesh: Mesh, z: np.ndarray) -> np.ndarray:
            return np.asarray(
                decode_vertex_colors(vae, mesh, jnp.asarray(z, jnp.complex64)), np.float64
            )
    else:
        raise ConfigError(f"codec must be 'stripes' or 'fl_vae', got {codec!r}")
    data = fldm.build_dataset(exemplar, cfg, encode=encode, key=k_data, progress=progress)
    result = fldm.train(data, cfg, key=k_train, progress=progress)
    target = data.meshes[0]
    geo = fldm.core.sampling_geometry(target, result.model)
    untrained = fldm.init(data, cfg, key=k_train)  # the weights training started from
    steps = 25
    z_tr = fldm.sample(result.model, geo, key=k_sample, num_samples=n_samples, steps=steps).latents
    z_un = fldm.sample(untrained, geo, key=k_sample, num_samples=n_samples, steps=steps).latents
    weights = load_vgg16()
    # the exemplar's stripes on the same copy the samples live on, central crops (texture only)
    ref = render_views(target, rgb_to_intensity(target.vertex_colors), size=96, crop=True)
    tr = [render_rgb_views(target, decode(target, z), size=96, crop=True) for z in z_tr]
    un = [render_rgb_views(target, decode(target, z), size=96, crop=True) for z in z_un]
    z_copy = data.latents[0, : target.num_vertices]
    rec = render_rgb_views(target, decode(target, z_copy), size=96, crop=True)
    # baselines: a flat colour (the exemplar's mean) and the training latents shuffled over vertices
    # (the right marginal, no spatial structure)
    flat = render_rgb_views(
        target,
        np.broadcast_to(np.mean(decode(target, z_copy), axis=0), (target.num_vertices, 3)),
        size=96,
        crop=True,
    )
    perm = host_rng(k_sample, 1).permutation(target.num_vertices)
    shuffled = render_rgb_views(target, decode(target, z_copy[perm]), size=96, crop=True)

    def gram(imgs):
        return float(
            np.mean(
                [
                    np.asarray(gram_distance(jnp.asarray(i), jnp.asarray(ref), weights=weights))
                    for i in imgs
                ]
            )
        )

    pairs = [(a, b) for a in range(n_samples) for b in range(a + 1, n_samples)]
    div = (
        float(
            np.mean(
                [
                    np.asarray(lpips(jnp.asarray(tr[a]), jnp.asarray(tr[b]), weights=weights))
                    for a, b in pairs
                ]
            )
        )
        if pairs
        else 0.0
    )
    return {
        "gram_trained": gram(tr),
        "gram_untrained": gram(un),
        "gram_codec": gram([rec]),
        "gram_flat": gram([flat]),
        "gram_shuffled": gram([shuffled]),
        "lpips_diversity": div,
        "losses": result.losses["loss"],
        "seconds": time.perf_counter() - t0,
        "model": result.model,
        "target": target,
        "samples": z_tr,
        "untrained_samples": z_un,
        "exemplar": exemplar,
        "codec": codec,
    }


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

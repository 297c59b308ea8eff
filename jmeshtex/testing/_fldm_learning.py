"""The FLDM learning check: a short CPU training on a striped sphere, scored against baselines.

The exemplar is :func:`jmeshtex.data.striped_sphere`; its latents come from the analytic stripe
codec (:func:`jmeshtex.data.stripe_encoder` / :func:`~jmeshtex.data.stripe_decoder`: magnitudes
carry the colour, phases the stripes' orientation) or from the shipped FL-VAE. The check trains a
tiny model (:meth:`jmeshtex.fldm.Config.demo`), samples it and compares the VGG Gram distance
(texture statistics) of the samples' renders to the exemplar's with those of an untrained model's
samples, a flat colour, the codec's own reconstruction and the training latents shuffled over
vertices; it also measures the samples' pairwise LPIPS diversity. The renders
(:func:`render_intensity_views`, :func:`render_color_views`) come from two fixed views,
``(elevation, azimuth) = (20°, −60°)`` and ``(−30°, 60°)``.
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from .._mesh import Mesh
from .._random import host_rng

#: the two ``(elevation, azimuth)`` views (degrees) of the learning check's renders
VIEWS: tuple[tuple[float, float], ...] = ((20.0, -60.0), (-30.0, 60.0))


def render_intensity_views(
    mesh: Mesh, intensity: np.ndarray, *, size: int = 128, crop: bool = False
) -> np.ndarray:
    """Renders of an intensity field on ``mesh`` from the learning check's two views.

    Args:
      mesh: the mesh.
      intensity: ``[V]`` values in [0, 1], shown with :func:`jmeshtex.data.intensity_to_rgb`.
      size: side of each square render in pixels.
      crop: render at twice the size and keep the central half, where a unit sphere fills the frame
        (texture statistics without background or silhouette, for the Gram distance).

    Returns:
      ``[2, size, size, 3]`` float32 in [0, 1].
    """
    from ..data import intensity_to_rgb

    return render_color_views(mesh, intensity_to_rgb(intensity), size=size, crop=crop)


def render_color_views(
    mesh: Mesh, rgb: np.ndarray, *, size: int = 128, crop: bool = False
) -> np.ndarray:
    """:func:`render_intensity_views` of per-vertex colours ``rgb [V, 3]`` in [0, 1]."""
    from ..render import render_mesh

    rgb = np.asarray(rgb, np.float64)
    full = 2 * size if crop else size
    coloured = Mesh(mesh.vertices, mesh.faces, vertex_colors=rgb)
    imgs = np.stack([render_mesh(coloured, view=v, size=(full, full)) for v in VIEWS])
    imgs = imgs.astype(np.float32) / 255.0
    if crop:
        a = size // 2
        imgs = imgs[:, a : a + size, a : a + size]
    return imgs


def fldm_learning_check(
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
      quick: :meth:`jmeshtex.fldm.Config.demo` (True) or a larger CPU preset (8 copies of 1500
        vertices, 1500 steps).
      n_samples: samples of the trained and of the untrained model (same noise).
      key: PRNG key of the copies, the initialisation, training and sampling (default ``key(0)``).
      progress: tqdm bars.
      codec: ``"stripes"``: the analytic stripe codec (2 channels); ``"fl_vae"``: the shipped
        FL-VAE (:func:`~jmeshtex.fl.load_pretrained`): copies encoded with
        :func:`~jmeshtex.fldm.fl_vae_encoder` (colours read on the exemplar), sample latents decoded
        with :func:`~jmeshtex.fl.decode_vertex_colors`.
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
    from .. import fldm
    from ..data import striped_sphere

    t0 = time.perf_counter()
    key = jax.random.key(0) if key is None else key
    k_codec, k_data, k_train, k_sample = jax.random.split(key, 4)
    exemplar = striped_sphere(subdivisions=3)
    cfg = _learning_config(quick, steps)
    encode, decode, cfg = _learning_codec(codec, exemplar, cfg, key=k_codec)
    data = fldm.build_dataset(exemplar, cfg, encode=encode, key=k_data, progress=progress)
    result = fldm.train(data, cfg, key=k_train, progress=progress)
    target = data.meshes[0]
    geo = fldm.core.sampling_geometry(target, result.model)
    untrained = fldm.init(data, cfg, key=k_train)  # the weights training started from
    sample_steps = 25
    z_tr = fldm.sample(
        result.model, geo, key=k_sample, num_samples=n_samples, steps=sample_steps
    ).latents
    z_un = fldm.sample(untrained, geo, key=k_sample, num_samples=n_samples, steps=sample_steps)
    z_un = z_un.latents
    scores = _learning_scores(
        target, decode, z_tr, z_un, data.latents[0, : target.num_vertices], key=k_sample
    )
    return {
        **scores,
        "losses": result.losses["loss"],
        "seconds": time.perf_counter() - t0,
        "model": result.model,
        "target": target,
        "samples": z_tr,
        "untrained_samples": z_un,
        "exemplar": exemplar,
        "codec": codec,
    }


def _learning_config(quick: bool, steps: int | None):
    """The check's :class:`~jmeshtex.fldm.Config`: the demo preset, or a larger CPU one."""
    from .. import fldm

    cfg = (
        fldm.Config.demo()
        if quick
        else fldm.Config.cpu(  # the bounds were measured without the invariant stream
            latent_channels=2,
            n_copies=8,
            copy_vertices=1500,
            steps=1500,
            diffusion_steps=1000,
            invariants=False,
        )
    )
    return cfg if steps is None else cfg.replace(steps=int(steps))


def _learning_codec(codec: str, exemplar: Mesh, cfg, *, key: jax.Array):
    """``(encode, decode, config)`` of ``codec``: the stripe codec, or the shipped FL-VAE (the
    config's latent channels set to its latent size); ``decode(mesh, z)`` gives ``[V, 3]`` RGB."""
    from .. import fldm
    from .._errors import ConfigError
    from ..data import intensity_to_rgb, stripe_decoder, stripe_encoder

    if codec == "stripes":

        def decode(mesh: Mesh, z: np.ndarray) -> np.ndarray:
            return intensity_to_rgb(stripe_decoder(z))

        return stripe_encoder, decode, cfg
    if codec == "fl_vae":
        from ..fl import decode_vertex_colors, load_pretrained

        vae = load_pretrained()
        encode = fldm.fl_vae_encoder(vae, exemplar, key=key)

        def decode(mesh: Mesh, z: np.ndarray) -> np.ndarray:
            return np.asarray(
                decode_vertex_colors(vae, mesh, jnp.asarray(z, jnp.complex64)), np.float64
            )

        return encode, decode, cfg.replace(latent_channels=vae.config.latent_dim)
    raise ConfigError(f"codec must be 'stripes' or 'fl_vae', got {codec!r}")


def _learning_scores(target: Mesh, decode, z_tr, z_un, z_copy, *, key: jax.Array) -> dict:
    """The Gram distances of the trained and untrained samples ``z_tr`` / ``z_un`` and of the
    baselines (the codec's reconstruction of the copy's latents ``z_copy``, a flat colour, the
    latents shuffled over vertices with ``key``) to the exemplar's renders, and the trained
    samples' pairwise LPIPS diversity."""
    from ..data import rgb_to_intensity
    from ..metrics import gram_distance, load_vgg16, lpips

    weights = load_vgg16()

    def views(rgb):  # central crops (texture only) on the copy the samples live on
        return render_color_views(target, rgb, size=96, crop=True)

    ref = render_intensity_views(target, rgb_to_intensity(target.vertex_colors), size=96, crop=True)
    tr = [views(decode(target, z)) for z in z_tr]
    un = [views(decode(target, z)) for z in z_un]
    rec = views(decode(target, z_copy))
    # baselines: a flat colour (the exemplar's mean) and the training latents shuffled over vertices
    # (the right marginal, no spatial structure)
    mean = np.mean(decode(target, z_copy), axis=0)
    flat = views(np.broadcast_to(mean, (target.num_vertices, 3)))
    perm = host_rng(key, 1).permutation(target.num_vertices)
    shuffled = views(decode(target, z_copy[perm]))

    def gram(imgs):
        d = [gram_distance(jnp.asarray(i), jnp.asarray(ref), weights=weights) for i in imgs]
        return float(np.mean([np.asarray(x) for x in d]))

    n = len(tr)
    pairs = [(a, b) for a in range(n) for b in range(a + 1, n)]
    div = [lpips(jnp.asarray(tr[a]), jnp.asarray(tr[b]), weights=weights) for a, b in pairs]
    return {
        "gram_trained": gram(tr),
        "gram_untrained": gram(un),
        "gram_codec": gram([rec]),
        "gram_flat": gram([flat]),
        "gram_shuffled": gram([shuffled]),
        "lpips_diversity": float(np.mean([np.asarray(x) for x in div])) if div else 0.0,
    }

"""Sampling a trained FLDM: generation, inpainting, label guidance, transfer to new meshes, decoding.

All sampling runs on a :class:`DenoiserGeometry` built for the mesh the samples live on, so the same
model samples on its training surface, on a re-triangulation of it, or on a completely different
mesh (*generative transfer*, §6.6). The denoiser's filters see log maps in units of that mesh's
mean edge length, so the resolution of the target mesh sets the textural scale: the same model on a
mesh with twice the vertex density gives a texture about √2 times smaller in world units.

- :func:`sample`: ``num_samples`` samples (:class:`Samples`) with DDIM (default, 50 steps) or
  ancestral DDPM (all ``T``);
  label-guided when the model was trained with labels (pass a per-vertex ``labels`` map);
- :func:`inpaint`: keeps given latents where ``mask`` is True (eq. 14), ancestral DDPM by default;
  a model trained with ``Config.mask_conditioning`` also sees the mask and the known latents at
  every step (the replacement stays, so the kept region is exact either way);
- :func:`decode_samples`: FL-VAE decoding to a UV atlas (meshes with UVs) or vertex colours;
- :func:`render_samples`: one PNG per sample (:func:`jmeshtex.render.render_mesh`).

Every function takes an explicit ``key``; the same key gives bit-identical samples.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib

import jax
import jax.numpy as jnp
import numpy as np

from .._config import is_finite_number, is_int
from .._errors import InputError
from .._jit import jit_loop
from .._mesh import Mesh, as_mesh
from ._denoiser import (
    DenoiserGeometry,
    _bucketed_vertices,
    _round_up,
    denoise,
    denoiser_geometry,
    geometry_sizes,
    pad_geometry,
)
from ._diffusion import (
    Inpaint,
    draw_sampling_noise,
    epsilon_from_output,
    sample_from_noise,
)
from ._model import Model


@dataclasses.dataclass(frozen=True)
class Samples:
    """Latent fields drawn by :func:`sample` or :func:`inpaint` on one mesh.

    Attributes:
      latents: ``[num_samples, V, d]`` complex128 unscaled latents (ready for the FL-VAE decoder,
        :func:`decode_samples`) in the one-ring frames of the mesh they were drawn on.
      known_mask: ``[V]`` bool, True where given latents were kept (inpainting); None for plain
        sampling.
      method: the sampler, ``"ddim"`` or ``"ddpm"``.
      steps: the number of denoising steps each sample ran.

    Example:
      >>> s = Samples(np.zeros((2, 5, 3), np.complex128), None, "ddim", 4)
      >>> s.num_samples, s.num_vertices
      (2, 5)
    """

    latents: np.ndarray
    known_mask: np.ndarray | None
    method: str
    steps: int

    @property
    def num_samples(self) -> int:
        """Number of samples."""
        return int(self.latents.shape[0])

    @property
    def num_vertices(self) -> int:
        """Number of vertices of the mesh the samples live on."""
        return int(self.latents.shape[1])


def sampling_geometry(mesh: Mesh, model: Model) -> DenoiserGeometry:
    """The denoiser geometry of ``mesh`` with the model's ``knn`` and ``pool_ratio``.

    Build it once to sample several times on the same mesh (:func:`~jmeshtex.fldm.sample` accepts it as ``target``).

    Args:
      mesh: a :class:`~jmeshtex.Mesh` (or a ``(vertices, faces)`` pair).
      model: the :class:`~jmeshtex.fldm.Model` to sample with.

    Returns:
      :class:`DenoiserGeometry` (:func:`denoiser_geometry`).
    """
    mesh = as_mesh(mesh, what="target")
    return denoiser_geometry(mesh, knn=model.config.knn, pool_ratio=model.config.pool_ratio)


@jit_loop(static_argnames=("config", "method", "num_steps", "eta"))
def _run(
    params,
    config,
    geo,
    labels,
    z_T,
    step_noise,
    known,
    mask,
    known_noise,
    *,
    method,
    num_steps,
    eta,
):
    schedule = config.noise_schedule()

    cond = dict(mask=mask, known=known) if config.mask_conditioning else {}

    def eps(z, t):
        out = denoise(params, config, z, t, geo, labels=labels, **cond)
        return epsilon_from_output(schedule, config.prediction, z, t, out)

    inpaint = Inpaint(known, mask)
    return sample_from_noise(
        eps,
        schedule,
        z_T,
        step_noise,
        method=method,
        num_steps=num_steps,
        eta=eta,
        inpaint=inpaint,
        inpaint_noise=known_noise,
    )


def _check_labels(model: Model, labels, V: int):
    if model.config.num_labels:
        if labels is None:
            raise InputError(
                f"this model is label-guided (num_labels={model.config.num_labels}); pass labels [V] int"
            )
        labels = np.asarray(labels)
        if labels.shape != (V,) or labels.min() < 0 or labels.max() >= model.config.num_labels:
            raise InputError(f"labels must be ints [V] = ({V},) in [0, {model.config.num_labels})")
        return jnp.asarray(labels, jnp.int32)
    if labels is not None:
        raise InputError("labels given but the model is unconditional (trained without labels)")
    return None


def sample(
    model: Model,
    target: Mesh | DenoiserGeometry,
    *,
    key: jax.Array,
    num_samples: int = 1,
    method: str = "ddim",
    steps: int = 50,
    eta: float = 0.0,
    labels: np.ndarray | None = None,
    known: np.ndarray | None = None,
    mask: np.ndarray | None = None,
    progress: bool = False,
    dtype=jnp.complex64,
) -> Samples:
    """Draw ``num_samples`` latent fields on ``target`` (unscaled: ready for the FL-VAE decoder).

    .. math:: z_T \\sim \\mathcal{CN}(0, I) \\xrightarrow{\\text{DDIM / DDPM (eq. 11, 29–31)}} z_0,
       \\qquad \\mu = z_0 / s

    Args:
      model: a trained :class:`Model`.
      target: the :class:`~jmeshtex.Mesh` to sample on (any mesh: generative transfer; a
        ``(vertices, faces)`` pair also works) or its prebuilt geometry (:func:`~jmeshtex.fldm.core.sampling_geometry`).
      key: PRNG key; the same key gives the same samples.
      num_samples: number of samples.
      method: ``"ddim"`` (``steps`` steps, ``eta``) or ``"ddpm"`` (all ``T`` steps, ancestral).
      steps: DDIM steps.
      eta: DDIM stochasticity.
      labels: ``[V]`` label map for a label-guided model.
      known, mask: inpainting: ``[V, d]`` unscaled latents kept where ``mask [V]`` is True.
      progress: tqdm bar over samples.
      dtype: complex dtype.

    Returns:
      :class:`Samples`: ``latents`` ``[num_samples, V, d]`` complex128 in the target's one-ring
      frames.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.fldm import Config
      >>> from jmeshtex.fldm.core import init_denoiser
      >>> cfg = Config.tiny(latent_channels=2, diffusion_steps=20)
      >>> model = Model(init_denoiser(jax.random.key(0), cfg), cfg, np.ones(2))
      >>> geo = sampling_geometry(icosphere(1), model)
      >>> a = sample(model, geo, key=jax.random.key(1), num_samples=2, steps=4)
      >>> b = sample(model, geo, key=jax.random.key(1), num_samples=2, steps=4)
      >>> a.latents.shape, bool(np.array_equal(a.latents, b.latents))
      ((2, 42, 2), True)
    """
    from tqdm.auto import tqdm

    if not _is_count(num_samples):
        raise InputError(f"num_samples must be an integer >= 1, got {num_samples!r}")
    if not (is_finite_number(eta) and 0.0 <= eta <= 1.0):
        raise InputError(f"eta must be a number in [0, 1] (0: deterministic DDIM), got {eta!r}")
    geo = target if isinstance(target, DenoiserGeometry) else sampling_geometry(target, model)
    V, d = geo.num_vertices, model.config.latent_channels
    lab = _check_labels(model, labels, V)
    scale = np.asarray(model.scale, np.float64)
    inpainting = known is not None
    known, mask = _known_region(known, mask, V, d)
    # pad to bucketed sizes (padding never changes real outputs): nearby sizes share one compilation
    geo, Vp = _bucketed_geometry(geo, model.config.bucket)
    kn = jnp.asarray(np.pad(known * scale, ((0, Vp - V), (0, 0))), dtype)
    mk = jnp.asarray(np.pad(mask, (0, Vp - V)))
    if lab is not None:
        lab = jnp.pad(lab, (0, Vp - V))
    from ..geometry import to_jax

    rdt = jnp.float64 if jnp.dtype(dtype) == jnp.complex128 else jnp.float32
    geo_j = to_jax(geo, rdt)
    params = jax.tree.map(
        lambda p: (
            jnp.asarray(p).astype(dtype) if jnp.iscomplexobj(p) else jnp.asarray(p).astype(rdt)
        ),
        model.params,
    )
    out = []
    for i in tqdm(range(int(num_samples)), desc="FLDM sample", unit="sample", disable=not progress):
        z_T, noise, known_noise = draw_sampling_noise(
            jax.random.fold_in(key, i),
            (Vp, d),
            method=method,
            num_steps=steps,
            diffusion_steps=model.config.diffusion_steps,
            inpaint=True,
            dtype=dtype,
        )
        z = _run(
            params,
            model.config,
            geo_j,
            lab,
            z_T,
            noise,
            kn,
            mk,
            known_noise,
            method=method,
            num_steps=int(steps),
            eta=float(eta),
        )
        out.append(np.asarray(z, np.complex128)[:V] / scale)
    ran = model.config.diffusion_steps if method == "ddpm" else int(steps)
    return Samples(np.stack(out), mask.copy() if inpainting else None, str(method), ran)


def _known_region(known, mask, V: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """The inpainting inputs checked, ``(known [V, d], mask [V] bool)``; plain sampling is
    inpainting with an empty mask (one compiled program for both)."""
    if (known is None) != (mask is None):
        raise InputError("inpainting needs both known [V, d] latents and mask [V]")
    if known is None:
        known, mask = np.zeros((V, d), np.complex128), np.zeros(V, bool)
    known = np.asarray(known)
    mask = np.asarray(mask, bool)
    if known.shape != (V, d) or mask.shape != (V,):
        raise InputError(
            f"known must be [V, d] = ({V}, {d}) and mask [V], got {known.shape} and {mask.shape}"
        )
    return known, mask


def _bucketed_geometry(geo: DenoiserGeometry, bucket: int) -> tuple[DenoiserGeometry, int]:
    """``geo`` padded to sizes rounded up to ``bucket`` (``bucket // 4`` for the coarse level, 4 for
    the pooling width), and the padded vertex count."""
    sizes = geometry_sizes(geo)
    Vp, V1 = _bucketed_vertices(geo.num_vertices, sizes["V1"], bucket)
    return pad_geometry(geo, V0=Vp, V1=V1, M=_round_up(sizes["M"], 4)), Vp


def _is_count(value) -> bool:
    return is_int(value, 1)


def inpaint(
    model: Model,
    mesh: Mesh,
    known: np.ndarray,
    mask: np.ndarray,
    *,
    key: jax.Array,
    num_samples: int = 1,
    **kwargs,
) -> Samples:
    """Inpaint: sample the latents where ``mask`` is False, keep ``known`` where it is True (eq. 14).

    A thin wrapper of :func:`sample` (same keyword arguments) whose default sampler is ancestral
    DDPM over all ``T`` steps (the paper's: at every step the kept region is replaced by the known
    latents noised to that step's level, and the fresh noise of each ancestral step lets the
    generated region settle against it; ``method="ddim"`` is faster). The returned latents equal
    ``known`` exactly on the mask.

    Two forms, chosen by how the model was trained: the default (``Config.mask_conditioning =
    False``) is replacement alone (eq. 14); a mask-conditioned model (``mask_conditioning=True``,
    trained on random masks) also receives the mask as a filter input and the known latents as
    extra input channels at every step, on top of the same replacement.

    Args:
      model: a trained :class:`Model`.
      mesh: the :class:`~jmeshtex.Mesh` (or its :func:`~jmeshtex.fldm.core.sampling_geometry`).
      known: ``[V, d]`` unscaled latents (e.g. the FL-VAE's encoding of the mesh's own colours).
      mask: ``[V]`` True where ``known`` is kept.
      key: PRNG key; the same key gives the same inpaintings.
      num_samples: number of inpaintings.
      **kwargs: :func:`sample`'s other keywords (``method``, ``steps``, ``eta``, ``labels``, ...).

    Returns:
      :class:`Samples`: ``latents`` ``[num_samples, V, d]`` complex128, equal to ``known``
      where ``known_mask`` (= ``mask``) is True.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.fldm import Config
      >>> from jmeshtex.fldm.core import init_denoiser
      >>> cfg = Config.tiny(latent_channels=2, diffusion_steps=20)
      >>> model = Model(init_denoiser(jax.random.key(0), cfg), cfg, np.ones(2))
      >>> mesh = icosphere(1)
      >>> known, mask = np.ones((42, 2), np.complex128), mesh.vertices[:, 2] > 0
      >>> out = inpaint(model, mesh, known, mask, key=jax.random.key(1), method="ddim", steps=3)
      >>> out.latents.shape, bool(np.allclose(out.latents[0][mask], 1.0, atol=1e-6))
      ((1, 42, 2), True)
    """
    kwargs.setdefault("method", "ddpm")
    return sample(model, mesh, key=key, num_samples=num_samples, known=known, mask=mask, **kwargs)


def decode_samples(
    vae, mesh: Mesh, latents: Samples | np.ndarray, *, size: int = 256
) -> list[dict]:
    """Decode latent samples with the FL-VAE: a texture atlas if ``mesh`` has UVs, else vertex colours.

    Args:
      vae: the FL-VAE (:class:`jmeshtex.fl.Model`) the training latents were encoded with.
      mesh: the :class:`~jmeshtex.Mesh` the latents live on.
      latents: :class:`Samples` (:func:`sample`, :func:`inpaint`) or their ``[n, V, d]``
        unscaled latents.
      size: atlas size in texels (meshes with UVs).

    Returns:
      A list with a dict per sample, ``{"texture": [size, size, 3], "valid": [size, size]}`` or
      ``{"vertex_colors": [V, 3]}`` (float in [0, 1]).
    """
    from ..fl import decode_texture, decode_vertex_colors

    mesh = as_mesh(mesh)
    if isinstance(latents, Samples):
        latents = latents.latents
    out = []
    for mu in np.asarray(latents):
        mu_j = jnp.asarray(mu, jnp.complex64)
        if mesh.uv is not None:
            tex, valid = decode_texture(vae, mesh, mu_j, size=size)
            out.append({"texture": np.asarray(tex), "valid": np.asarray(valid)})
        else:
            out.append({"vertex_colors": np.asarray(decode_vertex_colors(vae, mesh, mu_j))})
    return out


def render_samples(
    mesh: Mesh,
    decoded: list[dict],
    out_dir: str | os.PathLike,
    *,
    prefix: str = "sample",
    views: tuple[tuple[float, float], ...] = ((25.0, -60.0),),
    size: tuple[int, int] = (384, 384),
) -> list[pathlib.Path]:
    """Write one PNG per sample and view (``{prefix}_{i:02d}_{view}.png``); returns the paths.

    Args:
      mesh: the :class:`~jmeshtex.Mesh` the samples live on.
      decoded: :func:`decode_samples` output.
      out_dir: the folder.
      prefix: file name prefix.
      views: ``(elevation, azimuth)`` degrees of each view.
      size: image size in pixels.
    """
    from ..render import render_mesh

    mesh = as_mesh(mesh)

    out = pathlib.Path(out_dir)
    paths = []
    for i, d in enumerate(decoded):
        for j, view in enumerate(views):
            path = out / f"{prefix}_{i:02d}_{j}.png"
            if "texture" in d:
                render_mesh(
                    Mesh(mesh.vertices, mesh.faces, uv=mesh.uv, texture=d["texture"]),
                    path,
                    view=view,
                    size=size,
                )
            else:
                render_mesh(
                    Mesh(mesh.vertices, mesh.faces, vertex_colors=d["vertex_colors"]),
                    path,
                    view=view,
                    size=size,
                )
            paths.append(path)
    return paths

"""Gram-matching texture synthesis and style transfer on a mesh (Kovács et al. 2024, Sec. 5–6).

The texel colours ``x`` are optimised so that the Gram matrices of the mesh CNN's feature maps
match those of the 2D exemplar run through the 2D network (:mod:`jmeshtex.surfacecnn`'s style
loss, after Gatys et al. 2015), with Adam (lr 0.1, halved every 200 steps, 500 steps), colours
clipped to [0, 1] after every step and initialised uniformly in [0, 0.2]. Style transfer adds
``w_c · mean((F^c(x) − F^c(x_content))²)`` at one content layer and starts from the content texture.
"""

from __future__ import annotations

import hashlib
import os
import time
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._random import key_ints
from .._types import Float
from ..geometry import check_mesh_scale, to_jax
from ..metrics import VGGWeights, load_vgg16, load_vgg19
from ._atlas import image_to_texels, texels_to_image
from ._config import Config
from ._image import as_rgb
from ._loss import (
    default_content_weight,
    default_layers,
    gram_targets,
    gram_term,
    style_loss,
    style_transfer_layers,
)
from ._neighborhood import apply_tie
from ._network import mesh_cnn_features, required_levels
from ._optimize import optimize_colors
from ._surface import Surface, prepare_surface


class SynthesisResult(NamedTuple):
    """Outcome of :func:`~jmeshtex.surfacecnn.synthesize` / :func:`~jmeshtex.surfacecnn.stylize`.

    Attributes:
      texture: ``[size, size, 3]`` float32 image in the mesh's UV layout (row 0 = v 1), invalid
        texels filled with the nearest valid colour.
      colors: ``[N, 3]`` float32 colours of the valid texels.
      mesh: the input :class:`~jmeshtex.Mesh` with ``uv`` (unwrapped if it had none) and ``texture``.
      losses: ``[steps]`` float64 loss before each step's update.
      final_loss: loss of the returned colours.
      surface: the :class:`~jmeshtex.surfacecnn.Surface` used (None for a result read back by
        :func:`~jmeshtex.surfacecnn.load`).
      stats: timings (seconds) and sizes.
    """

    texture: Float[np.ndarray, "S S 3"]
    colors: Float[np.ndarray, "N 3"]
    mesh: Mesh
    losses: np.ndarray
    final_loss: float
    surface: Surface | None
    stats: dict


def _digest(*images: np.ndarray) -> str:
    h = hashlib.sha256()
    for image in images:
        h.update(repr(image.shape).encode())
        h.update(np.ascontiguousarray(image, np.float64).tobytes())
    return h.hexdigest()[:16]


def network_weights(config: Config) -> VGGWeights:
    """The CNN ``config`` names: the embedded VGG-16, or VGG-19 from ``config.weights_path`` (Caffe
    preprocessing, the paper's network).

    Example:
      >>> network_weights(Config()).names[:2]
      ('conv1_1', 'conv1_2')
    """
    if config.network == "vgg19":
        return load_vgg19(config.weights_path, preprocess="caffe")
    return load_vgg16()


def _setup(
    mesh: Mesh, config: Config, weights, layers, surface, extra_layers=(), task="synthesize"
):
    weights = network_weights(config) if weights is None else weights
    if (layers or config.layers) is None:
        layers = default_layers(weights) if task == "synthesize" else style_transfer_layers(weights)
    else:
        layers = tuple(layers or config.layers)
    levels = required_levels(weights, tuple(layers) + tuple(extra_layers))
    if surface is None:
        surface = prepare_surface(
            mesh,
            size=config.size,
            levels=levels,
            boundary=config.boundary,
            frames=config.frames,
            frame_vector=config.frame_vector,
            frame_smoothing=config.frame_smoothing,
        )
    elif surface.pyramid.levels < levels or surface.atlas.size != config.size:
        raise InputError(
            f"surface was prepared with size {surface.atlas.size} and {surface.pyramid.levels} levels; this run "
            f"needs size {config.size} and {levels} levels"
        )
    dtype = jnp.dtype(config.dtype)
    arrays = to_jax(surface.pyramid.network_arrays(), dtype)
    weights = jax.tree.map(lambda a: jnp.asarray(a, dtype), weights)
    return weights, layers, surface, arrays, dtype


def _fingerprint(task: str, config: Config, layers, data: str, **extra) -> dict:
    """What a checkpoint must share with this run to be resumed: the config apart from its
    resumable fields (:meth:`~jmeshtex._config.ConfigBase.fingerprint`), the Gram layers, the
    images' digest; a run on a surface adds its ``texels``."""
    return {
        "task": task,
        "config": config.fingerprint(),
        "layers": list(layers),
        "data": data,
        **extra,
    }


def _exemplar_targets(image, weights: VGGWeights, layers, config: Config, dtype) -> dict:
    """The exemplar's Gram targets through the 2D network, with ``config``'s pooling and padding."""
    return gram_targets(
        image,
        weights,
        layers=layers,
        pool=config.pool,
        padding=config.exemplar_padding,
        dtype=dtype,
    )


def _run_optimization(
    x0, loss_fn, aux, config: Config, task: str, progress: bool, checkpoint_dir, fingerprint: dict
) -> tuple:
    """:func:`~jmeshtex.surfacecnn.core.optimize_colors` of one task, checkpointed every
    ``config.checkpoint_every`` steps into ``checkpoint_dir`` under ``fingerprint``."""
    return optimize_colors(
        x0,
        loss_fn,
        aux,
        config,
        progress=progress,
        desc=f"surfacecnn {task}",
        checkpoint=checkpoint_dir,
        checkpoint_every=config.checkpoint_every,
        fingerprint=fingerprint,
    )


def _result(mesh: Mesh, surface: Surface, x, losses, final, stats, *, tie=True) -> SynthesisResult:
    """The result of optimised texel colours ``x``; ``tie``: tied texels show their tie (the
    surface network never reads their own values)."""
    tied = apply_tie(np.asarray(x), surface.pyramid.tie) if tie else np.asarray(x)
    colors = np.asarray(tied, np.float32)
    texture = texels_to_image(surface.atlas, colors).astype(np.float32)
    textured = mesh.replace(uv=surface.atlas.uv, texture=texture)
    stats = {
        **stats,
        **{f"{k}_s": v for k, v in surface.seconds.items()},
        "texels": surface.atlas.num_texels,
        "size": surface.atlas.size,
        "initial_loss": float(losses[0]) if len(losses) else final,
        "final_loss": final,
    }
    return SynthesisResult(texture, colors, textured, losses, final, surface, stats)


def synthesize(
    mesh: Mesh | tuple,
    exemplar: Float[np.ndarray, "H W 3"],
    config: Config | None = None,
    *,
    key: jax.Array,
    weights: VGGWeights | None = None,
    layers: tuple[str, ...] | None = None,
    surface: Surface | None = None,
    progress: bool = True,
    checkpoint_dir: str | os.PathLike | None = None,
) -> SynthesisResult:
    """Synthesise a texture for a mesh whose CNN Gram statistics match a 2D exemplar's.

    Minimises :func:`~jmeshtex.surfacecnn.core.style_loss` over the texel colours (Kovács et al. 2024,
    eq. 1, after Gatys et al. 2015) with Adam, lr ``config.learning_rate`` halved every
    ``config.halve_every`` steps, clipped to [0, 1], from uniform(``init_low``, ``init_high``) colours.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or a ``(vertices, faces)`` pair. The texture's layout is an
        xatlas unwrap (``config.unwrap = "xatlas"``, the reference's) or the mesh's own UVs
        (``"mesh"``; a mesh without UVs is unwrapped either way); the result's ``mesh`` carries the
        layout used. With ``surface``, the surface's layout.
      exemplar: ``[H, W, 3]`` RGB image in [0, 1] (or uint8).
      config: :class:`~jmeshtex.surfacecnn.Config` (default: the paper's settings).
      key: PRNG key of the initial colours.
      weights: CNN weights (default: ``config.network``, :func:`~jmeshtex.surfacecnn.core.network_weights`; the embedded
        VGG-16 unless VGG-19's file is given).
      layers: Gram layers (default ``config.layers``, else every ReLU and pool output).
      surface: a precomputed :class:`~jmeshtex.surfacecnn.Surface` to reuse.
      progress: show a tqdm bar with the loss.
      checkpoint_dir: a folder (:class:`jmeshtex.io.Checkpoints`): colours, Adam state and losses
        are saved there every ``config.checkpoint_every`` steps and at the end; if it already holds this run
        (same texels, exemplar, key, layers and optimiser settings), the optimisation resumes from it and
        gives the result of an uninterrupted run (a different run raises
        :class:`~jmeshtex.CheckpointMismatchError`).

    Returns:
      :class:`~jmeshtex.surfacecnn.SynthesisResult`.

    Example:
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> ex = np.random.default_rng(0).uniform(size=(16, 16, 3))
      >>> r = synthesize(Mesh(v, f, uv=v[f][..., :2]), ex, Config(size=16, steps=20), key=jax.random.key(0),
      ...                layers=("relu1_1",), progress=False)
      >>> r.texture.shape, bool(r.final_loss < r.losses[0])
      ((16, 16, 3), True)
    """
    config = Config() if config is None else config
    mesh = as_mesh(mesh)
    check_mesh_scale(mesh, what="mesh")  # before xatlas or float32 geometry can loop or fail
    image = as_rgb(exemplar, "exemplar")
    if surface is None and config.unwrap == "xatlas":
        mesh = mesh.replace(uv=None, texture=None)  # prepare_surface unwraps it
    weights, layers, surface, arrays, dtype = _setup(mesh, config, weights, layers, surface)
    t0 = time.perf_counter()
    targets = _exemplar_targets(image, weights, layers, config, dtype)
    targets = jax.block_until_ready(targets)
    target_s = time.perf_counter() - t0
    x0 = jax.random.uniform(
        key, (surface.atlas.num_texels, 3), dtype, config.init_low, config.init_high
    )

    def loss_fn(x, aux):
        arrays, weights, targets = aux
        return style_loss(x, arrays, weights, targets, pool=config.pool)

    fingerprint = _fingerprint(
        "synthesize",
        config,
        layers,
        _digest(image),
        texels=surface.atlas.num_texels,
        key=key_ints(key),
    )
    x, losses, final, stats = _run_optimization(
        x0,
        loss_fn,
        (arrays, weights, targets),
        config,
        "synthesize",
        progress,
        checkpoint_dir,
        fingerprint,
    )
    return _result(mesh, surface, x, losses, final, {**stats, "targets_s": target_s})


def stylize(
    mesh: Mesh | tuple,
    content: Float[np.ndarray, "H W 3"],
    style: Float[np.ndarray, "H2 W2 3"],
    config: Config | None = None,
    *,
    key: jax.Array | None = None,
    weights: VGGWeights | None = None,
    layers: tuple[str, ...] | None = None,
    surface: Surface | None = None,
    progress: bool = True,
    checkpoint_dir: str | os.PathLike | None = None,
) -> SynthesisResult:
    """Neural style transfer on a mesh texture: Gram term of ``style`` plus a content term.

    .. math:: \\mathcal L(x) = \\mathcal L_{style}(x) + w_c\\, \\operatorname{mean}\\big(
       (F^c(x) - F^c(x_{content}))^2\\big)

    ``F^c`` is the mesh CNN's feature map ``config.content_layer``; ``x_content`` the content
    texture read at the valid texels (it must be in the mesh's UV layout); optimisation starts from
    it (Gatys et al. 2016; Kovács et al. 2024, Sec. 6).

    Args:
      mesh: a :class:`~jmeshtex.Mesh` with UVs.
      content: ``[H, W, 3]`` texture in the mesh's UV layout (resampled to ``config.size``), e.g.
        ``mesh.texture``.
      style: ``[H2, W2, 3]`` style image.
      config: :class:`~jmeshtex.surfacecnn.Config` (``content_layer``, ``content_weight``; the style
        layers default to ``relu1_1 … relu5_1``, :func:`~jmeshtex.surfacecnn.core.style_transfer_layers`).
      key: accepted for the common task-verb signature; style transfer starts from the content
        texture and draws no random numbers, so the result does not depend on it.
      weights, layers, surface, progress, checkpoint_dir: as in
        :func:`~jmeshtex.surfacecnn.synthesize`.

    Returns:
      :class:`~jmeshtex.surfacecnn.SynthesisResult`.

    Raises:
      InputError: the mesh has no UVs.

    Example:
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> rng = np.random.default_rng(0)
      >>> r = stylize(Mesh(v, f, uv=v[f][..., :2]), rng.uniform(size=(16, 16, 3)), rng.uniform(size=(16, 16, 3)),
      ...             Config(size=16, steps=5, content_layer="relu1_2"), layers=("relu1_1",), progress=False)
      >>> r.colors.shape
      (256, 3)
    """
    config = Config() if config is None else config
    mesh = as_mesh(mesh)
    if mesh.uv is None:
        raise InputError(
            "stylize: the mesh has no UVs, so a content texture cannot be placed on it; "
            "use synthesize or give a mesh with UVs"
        )
    content_image, style_image = as_rgb(content, "content"), as_rgb(style, "style")
    weights, layers, surface, arrays, dtype = _setup(
        mesh, config, weights, layers, surface, extra_layers=(config.content_layer,), task="stylize"
    )
    content_colors = jnp.asarray(image_to_texels(surface.atlas, content_image), dtype)
    targets = _exemplar_targets(style_image, weights, layers, config, dtype)
    content_feats = mesh_cnn_features(
        content_colors, arrays, weights, layers=(config.content_layer,), pool=config.pool
    )[config.content_layer]
    content_weight = (
        default_content_weight(weights) if config.content_weight is None else config.content_weight
    )
    loss_fn = _style_transfer_loss(layers, config, jnp.asarray(content_weight, dtype))
    aux = (arrays, weights, targets, content_feats)
    fingerprint = _fingerprint(
        "stylize",
        config,
        layers,
        _digest(content_image, style_image),
        content_layer=config.content_layer,
        content_weight=content_weight,
        texels=surface.atlas.num_texels,
    )
    x, losses, final, stats = _run_optimization(
        content_colors, loss_fn, aux, config, "stylize", progress, checkpoint_dir, fingerprint
    )
    return _result(mesh, surface, x, losses, final, stats)


def _style_transfer_loss(layers: tuple[str, ...], config: Config, weight: jax.Array):
    """``loss_fn(x, (arrays, weights, targets, content_feats))``: the Gram term plus ``weight``
    times the content term at ``config.content_layer`` (:func:`stylize`)."""

    def loss_fn(x, aux):
        arrays, weights, targets, content_feats = aux
        feats = mesh_cnn_features(
            x,
            arrays,
            weights,
            layers=tuple(dict.fromkeys((*layers, config.content_layer))),
            pool=config.pool,
        )
        content_term = jnp.mean((feats[config.content_layer] - content_feats) ** 2)
        return gram_term(feats, targets) + weight * content_term

    return loss_fn

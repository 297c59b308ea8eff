"""The baseline the surface CNN exists to beat: Gram-matching synthesis of the flat UV image.

The same optimisation as :func:`~jmeshtex.surfacecnn.synthesize` (loss, layers, Adam schedule,
clipping, initial colours, exemplar targets), but the network runs on the ``size × size`` texture
image as a 2D picture (Gatys et al. 2015), ignoring the surface: texels that touch across a chart
seam are unrelated in the image, so the seams show and the pattern's orientation follows each
chart's layout (Kovács et al. 2024, Fig. 1 and Sec. 7's comparison).
"""

from __future__ import annotations

import os
import time

import jax
import jax.numpy as jnp
import numpy as np

from .._mesh import Mesh, as_mesh
from .._random import key_ints
from .._types import Float
from ..metrics import VGGWeights, vgg_features
from ..ops import gram_matrix
from ._config import Config
from ._image import as_rgb
from ._loss import default_layers, vgg_features_centre_padded
from ._surface import Surface
from ._synthesis import (
    SynthesisResult,
    _digest,
    _exemplar_targets,
    _fingerprint,
    _result,
    _run_optimization,
    network_weights,
)


def synthesize_uv(
    mesh: Mesh | tuple,
    exemplar: Float[np.ndarray, "H W 3"],
    config: Config | None = None,
    *,
    key: jax.Array,
    surface: Surface,
    weights: VGGWeights | None = None,
    layers: tuple[str, ...] | None = None,
    progress: bool = True,
    checkpoint_dir: str | os.PathLike | None = None,
) -> SynthesisResult:
    """UV-space 2D texture synthesis: Gram matching on the flat texture image (the baseline).

    .. math:: \\min_{I \\in [0,1]^{S\\times S\\times 3}} \\frac{1}{|L|} \\sum_{l\\in L}
       \\operatorname{mean}\\big(G^l_{2D}(I) - G^l_{2D}(E)\\big)^2

    with the 2D network of the exemplar targets (same padding, ``config.exemplar_padding``), then
    the texture is read at the atlas' valid texels.

    Args:
      mesh: the :class:`~jmeshtex.Mesh` (its UVs, as in ``surface``).
      exemplar: ``[H, W, 3]`` RGB in [0, 1].
      config: :class:`~jmeshtex.surfacecnn.Config` (size, steps, schedule, layers, padding).
      key: PRNG key of the initial colours (the whole image, uniform in ``[init_low, init_high]``).
      surface: the :class:`~jmeshtex.surfacecnn.Surface` of the surface-CNN run (its atlas places
        the result; sharing it makes the two results directly comparable).
      weights: CNN weights (default ``config.network``).
      layers: Gram layers (default ``config.layers``, else every ReLU and pool output).
      progress: tqdm bar.
      checkpoint_dir: as in :func:`~jmeshtex.surfacecnn.synthesize` (the image,
        Adam state and losses are saved there; a folder holding this run resumes it). The image
        does not depend on the mesh, so a finished folder serves every mesh at the same size,
        exemplar, layers and key: it only has to be read at the new atlas' texels.

    Returns:
      :class:`~jmeshtex.surfacecnn.SynthesisResult` (``colors`` at the valid texels; ``texture``
      the optimised image, invalid pixels refilled from the nearest valid texel).

    Example:
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn import prepare_surface
      >>> v, f = grid(2)
      >>> mesh = Mesh(v, f, uv=v[f][..., :2])
      >>> ex = np.random.default_rng(0).uniform(size=(16, 16, 3))
      >>> s = prepare_surface(mesh, size=16, levels=0)
      >>> r = synthesize_uv(mesh, ex, Config(size=16, steps=20), key=jax.random.key(0), surface=s,
      ...                   layers=("relu1_1",), progress=False)
      >>> r.colors.shape, bool(r.final_loss < r.losses[0])
      ((256, 3), True)
    """
    config = Config() if config is None else config
    mesh = as_mesh(mesh)
    image = as_rgb(exemplar, "exemplar")
    weights = network_weights(config) if weights is None else weights
    layers = tuple(layers or config.layers or default_layers(weights))
    dtype = jnp.dtype(config.dtype)
    weights = jax.tree.map(lambda a: jnp.asarray(a, dtype), weights)
    targets = _exemplar_targets(image, weights, layers, config, dtype)
    size = config.size
    x0 = jax.random.uniform(key, (size * size, 3), dtype, config.init_low, config.init_high)
    loss_fn = _image_gram_loss(size, config)
    t0 = time.perf_counter()
    fingerprint = _fingerprint(  # the image does not depend on the surface: any mesh may resume it
        "synthesize_uv",
        config,
        layers,
        _digest(image),
        key=key_ints(key),
    )
    x, losses, final, stats = _run_optimization(
        x0,
        loss_fn,
        (weights, targets),
        config,
        "synthesize_uv",
        progress,
        checkpoint_dir,
        fingerprint,
    )
    pixels = np.asarray(x).reshape(size * size, 3)[surface.atlas.texel]
    result = _result(  # a 2D image: every pixel was optimised, no tie
        mesh,
        surface,
        pixels,
        losses,
        final,
        {**stats, "uv_total_s": time.perf_counter() - t0},
        tie=False,
    )
    return result


def _image_gram_loss(size: int, config: Config):
    """``loss_fn(x, (weights, targets))``: the mean Gram loss of the flat image ``x`` (``[size², 3]``)
    through the 2D network, padded as the exemplar was (``config.exemplar_padding``)."""
    centre = config.exemplar_padding == "centre"
    pool = config.pool

    def loss_fn(x, aux):
        weights, targets = aux
        img = x.reshape(size, size, 3)
        if centre:
            feats = vgg_features_centre_padded(img, weights, layers=tuple(targets), pool=pool)
        else:
            feats = {
                k: v[0]
                for k, v in vgg_features(
                    img[None], weights, layers=tuple(targets), pool=pool, ceil_mode=True
                ).items()
            }
        terms = [
            jnp.mean((gram_matrix(feats[k].reshape(-1, feats[k].shape[-1])) - targets[k]) ** 2)
            for k in targets
        ]
        return sum(terms) / len(terms)

    return loss_fn

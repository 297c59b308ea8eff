"""The Gram-matching style loss of the mesh CNN against a 2D exemplar (Kovács et al. 2024, eq. 1).

.. math:: \\mathcal L_{style}(x) = \\frac{1}{|L|} \\sum_{l \\in L} \\operatorname{mean}_{c,d}
   \\big(G^l(x) - G^l(E)\\big)_{cd}^2, \\qquad G^l_{cd} = \\frac{1}{N_l} \\sum_n F^l_{nc} F^l_{nd}

``G^l(x)`` from the mesh CNN's feature maps of the texel colours ``x``, ``G^l(E)`` from the 2D
network on the exemplar (Gatys et al. 2015).
"""

from __future__ import annotations

import jax.numpy as jnp

from .._types import Array, Float
from ..metrics import VGGWeights, vgg_features, vgg_layer_names
from ..ops import gram_matrix
from ._image import as_rgb
from ._network import mesh_cnn_features


def default_layers(weights: VGGWeights) -> tuple[str, ...]:
    """Every ReLU and pooling output of the network, in order: the reference tool's style layers.

    Args:
      weights: the network.

    Returns:
      The ``relu<b>_<i>`` and ``pool<b>`` names of :func:`jmeshtex.metrics.vgg_layer_names`.

    Example:
      >>> from jmeshtex.metrics import load_vgg16
      >>> default_layers(load_vgg16())[:4]
      ('relu1_1', 'relu1_2', 'pool1', 'relu2_1')
    """
    return tuple(n for n in vgg_layer_names(weights) if not n.startswith("conv"))


def gram_targets(
    exemplar: Float[Array, "H W 3"],
    weights: VGGWeights,
    *,
    layers: tuple[str, ...],
    pool: str = "mean",
    dtype=jnp.float32,
) -> dict[str, Float[Array, "C C"]]:
    """Gram matrices of the exemplar's 2D feature maps, ``G_cd = mean_pixels F_c F_d``.

    The 2D network pools like the texel pyramid (:func:`jmeshtex.metrics.vgg_features` with
    ``ceil_mode=True``).

    Args:
      exemplar: ``[H, W, 3]`` RGB in [0, 1] (or uint8, grey, RGBA).
      weights: the network.
      layers: activation names.
      pool: ``"mean"`` or ``"max"``.
      dtype: dtype of the forward pass.

    Returns:
      ``{name: [C, C]}``.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.metrics import load_vgg16
      >>> g = gram_targets(np.full((8, 8, 3), 0.5), load_vgg16(), layers=("relu1_1",))
      >>> g["relu1_1"].shape
      (64, 64)
    """
    image = as_rgb(exemplar, "exemplar")
    feats = vgg_features(jnp.asarray(image, dtype)[None], weights, layers=tuple(layers), pool=pool, ceil_mode=True)
    return {k: gram_matrix(v[0].reshape(-1, v.shape[-1])) for k, v in feats.items()}


def style_loss(
    colors: Float[Array, "N 3"],
    network_arrays,
    weights: VGGWeights,
    targets: dict[str, Array],
    *,
    pool: str = "mean",
) -> Float[Array, ""]:
    """Layer-averaged mean squared Gram difference of the mesh CNN's feature maps (module docstring).

    Args:
      colors: ``[N, 3]`` texel colours.
      network_arrays: ``TexelPyramid.network_arrays()``.
      weights: the network.
      targets: :func:`gram_targets` of the exemplar (its keys are the style layers).
      pool: ``"mean"`` or ``"max"``.

    Returns:
      The scalar loss.

    Example:
      >>> import numpy as np
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.metrics import load_vgg16
      >>> from jmeshtex.surfacecnn import prepare_surface
      >>> v, f = grid(2)
      >>> s = prepare_surface(Mesh(v, f, uv=v[f][..., :2]), size=8, levels=0)
      >>> w = load_vgg16()
      >>> t = gram_targets(np.full((8, 8, 3), 0.5), w, layers=("relu1_1", "relu1_2"))
      >>> float(style_loss(jnp.full((64, 3), 0.5, jnp.float32), s.pyramid.network_arrays(), w, t)) < 1e-9
      True
    """
    feats = mesh_cnn_features(colors, network_arrays, weights, layers=tuple(targets), pool=pool)
    return gram_term(feats, targets)


def gram_term(feats: dict[str, Array], targets: dict[str, Array]) -> Array:
    """The style loss from already computed feature maps ``{name: [N_l, C]}``."""
    terms = [jnp.mean((gram_matrix(feats[k]) - targets[k].astype(feats[k].dtype)) ** 2) for k in targets]
    return sum(terms) / len(terms)

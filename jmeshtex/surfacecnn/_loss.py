"""The Gram-matching style loss of the mesh CNN against a 2D exemplar (Kovács et al. 2024, eq. 1).

.. math:: \\mathcal L_{style}(x) = \\frac{1}{|L|} \\sum_{l \\in L} \\operatorname{mean}_{c,d}
   \\big(G^l(x) - G^l(E)\\big)_{cd}^2, \\qquad G^l_{cd} = \\frac{1}{N_l} \\sum_n F^l_{nc} F^l_{nd}

``G^l(x)`` from the mesh CNN's feature maps of the texel colours ``x``, ``G^l(E)`` from the 2D
network on the exemplar (Gatys et al. 2015).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._types import Array, Float
from ..metrics import VGGWeights, vgg_features, vgg_layer_names, vgg_plan
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


def style_transfer_layers(weights: VGGWeights) -> tuple[str, ...]:
    """The first ReLU of every block (``relu1_1 … relu5_1``): the reference's style-transfer layers
    (Keras ``block{1..5}_conv1``, whose outputs are after the ReLU).

    Example:
      >>> from jmeshtex.metrics import load_vgg16
      >>> style_transfer_layers(load_vgg16())
      ('relu1_1', 'relu2_1', 'relu3_1', 'relu4_1', 'relu5_1')
    """
    return tuple(n for n in vgg_layer_names(weights) if n.startswith("relu") and n.endswith("_1"))


def default_content_weight(weights: VGGWeights) -> float:
    """The reference's content weight (1000, for Keras VGG-19 with Caffe preprocessing) rescaled to
    the network's input scale.

    Features grow about linearly with the input scale ``k = scale / mean(std)`` (255 for Caffe
    inputs, ≈4.42 for torchvision's), so the Gram term grows as ``k⁴`` and the content term as
    ``k²``; keeping their balance gives

    .. math:: w_c = 1000\\, (k / 255)^2

    (≈0.30 for the embedded VGG-16). A derived equivalence, not a value tuned on results.

    Example:
      >>> from jmeshtex.metrics import load_vgg16
      >>> round(default_content_weight(load_vgg16()), 3)
      0.3
    """
    k = float(weights.scale) / float(np.mean(weights.std))
    return 1000.0 * (k / 255.0) ** 2


def vgg_features_centre_padded(
    image: Float[Array, "H W 3"],
    weights: VGGWeights,
    *,
    layers: tuple[str, ...],
    pool: str = "mean",
) -> dict[str, Float[Array, "h w C"]]:
    """The 2D network on an image whose out-of-image 3×3 taps read the centre pixel (the reference's
    plane neighbourhoods, ``create_plane_neighborhoods``), with ceil-mode pooling.

    .. math:: y_{ij} = b + \\sum_t K_t^\\top x_{(i,j)+t} \\ \\text{(zero padding)} \\;+\\;
       \\sum_{t\\ \\text{outside}} K_t^\\top x_{ij}

    Returns:
      ``{name: [h, w, C]}``.

    Example:
      >>> from jmeshtex.metrics import load_vgg16
      >>> f = vgg_features_centre_padded(jnp.full((4, 4, 3), 0.5), load_vgg16(), layers=("relu1_1",))
      >>> bool(jnp.allclose(f["relu1_1"][0, 0], f["relu1_1"][1, 1], atol=1e-5))    # constant stays constant
      True
    """
    x = weights.preprocess(image)
    out = {}
    for step in vgg_plan(weights, tuple(layers)):
        if step.kind == "conv":
            kernel, bias = weights.convs[step.conv]
            kernel = kernel.astype(x.dtype)
            y = jax.lax.conv_general_dilated(
                x[None], kernel, (1, 1), "SAME", dimension_numbers=("NHWC", "HWIO", "NHWC")
            )[0]
            x = _read_centre_outside(y, x, kernel) + bias.astype(x.dtype)
        elif step.kind == "relu":
            x = jax.nn.relu(x)
        else:
            x = _pool_ceil(x, pool)
        if step.name in layers:
            out[step.name] = x
    return out


def _read_centre_outside(y: Array, x: Array, kernel: Array) -> Array:
    """Adds to the zero-padded convolution ``y`` of ``x`` the taps that leave the image, each
    reading the centre pixel: only border rows and columns change, so the work is O(border).

    A border row gains its centre times the sum of the kernel row that leaves (likewise columns);
    a corner pixel's leaving corner tap is in both sums and is taken off once.
    """
    H, W = x.shape[:2]
    y = y.at[0].add(x[0] @ kernel[0].sum(0))
    y = y.at[H - 1].add(x[H - 1] @ kernel[2].sum(0))
    y = y.at[:, 0].add(x[:, 0] @ kernel[:, 0].sum(0))
    y = y.at[:, W - 1].add(x[:, W - 1] @ kernel[:, 2].sum(0))
    for i, j, ky, kx in ((0, 0, 0, 0), (0, W - 1, 0, 2), (H - 1, 0, 2, 0), (H - 1, W - 1, 2, 2)):
        y = y.at[i, j].add(-(x[i, j] @ kernel[ky, kx]))
    return y


def _pool_ceil(x: Array, mode: str) -> Array:
    """2×2 stride-2 pool of ``[H, W, C]`` over the real members of partial windows (ceil mode)."""
    H, W, C = x.shape
    pad = ((0, H % 2), (0, W % 2), (0, 0))
    fill = -jnp.inf if mode == "max" else 0.0
    blocks = jnp.pad(x, pad, constant_values=fill).reshape((H + 1) // 2, 2, (W + 1) // 2, 2, C)
    if mode == "max":
        return blocks.max(axis=(1, 3))
    count = (
        np.pad(np.ones((H, W)), pad[:2]).reshape((H + 1) // 2, 2, (W + 1) // 2, 2).sum(axis=(1, 3))
    )
    return blocks.sum(axis=(1, 3)) / jnp.asarray(count, x.dtype)[..., None]


def gram_targets(
    exemplar: Float[Array, "H W 3"],
    weights: VGGWeights,
    *,
    layers: tuple[str, ...],
    pool: str = "mean",
    padding: str = "zero",
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
      padding: out-of-image taps read zero (``"zero"``, ``"SAME"`` convolutions) or the centre
        pixel (``"centre"``, the reference's; :func:`vgg_features_centre_padded`).
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
    if padding == "centre":
        weights = jax.tree.map(lambda a: jnp.asarray(a, dtype), weights)
        feats = vgg_features_centre_padded(
            jnp.asarray(image, dtype), weights, layers=tuple(layers), pool=pool
        )
        return {k: gram_matrix(v.reshape(-1, v.shape[-1])) for k, v in feats.items()}
    if padding != "zero":
        raise InputError(f"gram_targets: padding must be 'zero' or 'centre', got {padding!r}")
    feats = vgg_features(
        jnp.asarray(image, dtype)[None], weights, layers=tuple(layers), pool=pool, ceil_mode=True
    )
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
      >>> # a constant image: the surface's opposite-tap boundary and the 2D centre padding agree
      >>> t = gram_targets(np.full((8, 8, 3), 0.5), w, layers=("relu1_1", "relu1_2"), padding="centre")
      >>> float(style_loss(jnp.full((64, 3), 0.5, jnp.float32), s.pyramid.network_arrays(), w, t)) < 1e-9
      True
    """
    feats = mesh_cnn_features(colors, network_arrays, weights, layers=tuple(targets), pool=pool)
    return gram_term(feats, targets)


def gram_term(feats: dict[str, Array], targets: dict[str, Array]) -> Array:
    """The style loss from already computed feature maps ``{name: [N_l, C]}``."""
    terms = [
        jnp.mean((gram_matrix(feats[k]) - targets[k].astype(feats[k].dtype)) ** 2) for k in targets
    ]
    return sum(terms) / len(terms)

"""A pre-trained 2D CNN run on a mesh texture (Kovács et al. 2024).

The mesh CNN has exactly the 2D network's layers and weights: every 3×3 convolution becomes a
:func:`~jmeshtex.ops.texel_conv` over the pyramid's taps of the current level (bilinear taps in the
first layer, nearest taps in all later ones, the paper's best setting), every 2×2 pool a
:func:`~jmeshtex.ops.grouped_pool` over the next level's groups. On a flat sheet with the identity UV
map it computes the same numbers as :func:`jmeshtex.metrics.vgg_features` with average pooling
(tested). The layer sequence is the one :func:`jmeshtex.metrics.vgg_plan` gives for the 2D network.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._errors import InputError
from .._types import Array, Float
from ..metrics import VGGWeights, vgg_plan
from ..ops import PoolGroups, grouped_pool, texel_conv


def required_levels(weights: VGGWeights, layers: tuple[str, ...]) -> int:
    """Pooling levels needed to compute ``layers``: the number of pools before the deepest one.

    Args:
      weights: the network (:func:`jmeshtex.metrics.load_vgg16` or :func:`~jmeshtex.metrics.load_vgg19`).
      layers: activation names (:func:`jmeshtex.metrics.vgg_layer_names`).

    Returns:
      The ``levels`` to build the :class:`~jmeshtex.surfacecnn.core.TexelPyramid` with.

    Example:
      >>> from jmeshtex.metrics import load_vgg16
      >>> required_levels(load_vgg16(), ("relu1_1", "pool1", "relu3_1"))
      2
    """
    return sum(step.kind == "pool" for step in vgg_plan(weights, tuple(layers)))


def mesh_cnn_features(
    colors: Float[Array, "N 3"],
    network_arrays: tuple,
    weights: VGGWeights,
    *,
    layers: tuple[str, ...],
    pool: str = "mean",
) -> dict[str, Float[Array, "M C"]]:
    """Feature maps of the 2D CNN run on texel colours through the surface taps and pooling groups.

    .. math:: x^{(k+1)} = \\operatorname{ReLU}\\big(\\textstyle\\sum_{t} K_t^\\top s_t(x^{(k)}) + b\\big),
       \\qquad s_t(x)_n = \\sum_j w_{ntj}\\, x_{i_{ntj}}

    with bilinear taps for the first convolution and nearest taps afterwards, and
    ``pool_l(x)_g = mean_{n ∈ S_g} x_n`` (or max) between blocks (Kovács et al. 2024, Sec. 4); a
    ``conv<b>_<i>`` name gives the activation before its ReLU.

    Args:
      colors: ``[N, 3]`` RGB in [0, 1] of the valid texels (atlas order).
      network_arrays: ``TexelPyramid.network_arrays()``: ``(bilinear, nearest, pools, parent)``
        (NumPy or JAX arrays).
      weights: :class:`~jmeshtex.metrics.VGGWeights` (cast to ``colors``' dtype).
      layers: activation names (``"relu1_1"``, ``"pool1"``, ...; :func:`jmeshtex.metrics.vgg_layer_names`).
      pool: ``"mean"`` (the paper's average pooling) or ``"max"``.

    Returns:
      ``{name: [N_level, C]}`` for every requested layer.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.metrics import load_vgg16
      >>> from jmeshtex.surfacecnn.core import texture_atlas, texel_pyramid
      >>> v, f = grid(2)
      >>> atlas = texture_atlas(v, f, v[f][..., :2], size=8)
      >>> pyr = texel_pyramid(v, f, atlas, levels=1)
      >>> out = mesh_cnn_features(jnp.full((64, 3), 0.5), pyr.network_arrays(), load_vgg16(),
      ...                         layers=("relu1_1", "pool1"))
      >>> out["relu1_1"].shape, out["pool1"].shape
      ((64, 64), (16, 64))
    """
    if colors.ndim != 2 or colors.shape[1] != 3:
        raise InputError(f"mesh_cnn_features: colors must be [N, 3], got {tuple(colors.shape)}")
    bilinear, nearest, pools, parent = network_arrays
    steps = vgg_plan(weights, tuple(layers))
    n_pools = sum(step.kind == "pool" for step in steps)
    if n_pools > len(pools):
        raise InputError(
            f"mesh_cnn_features: layers {layers} need {n_pools} pooling levels but the pyramid has {len(pools)}; "
            f"build it with texel_pyramid(..., levels={n_pools})"
        )
    x = weights.preprocess(colors)
    out, level = {}, 0
    for step in steps:
        if step.kind == "conv":
            kernel, bias = weights.convs[step.conv]
            x = texel_conv(x, bilinear if step.conv == 0 else nearest[level], kernel, bias)
        elif step.kind == "relu":
            x = jax.nn.relu(x)
        else:
            x = _pool_groups(x, pools[level], parent[level], pool)
            level += 1
        if step.name in layers:
            out[step.name] = x
    return out


#: groups padded to more members than this are pooled with segment sums instead of padded gathers
SEGMENT_POOL_ABOVE = 8


def _pool_groups(x: Array, groups: PoolGroups, parent: Array, mode: str) -> Array:
    """Grouped pooling: padded gathers (:func:`~jmeshtex.ops.grouped_pool`) for small groups; for
    very uneven groups (strongly varying texel density, e.g. Spot's atlas) segment reductions, whose
    cost does not grow with the largest group."""
    G, S = groups.index.shape
    if S <= SEGMENT_POOL_ABOVE:
        return grouped_pool(x, groups, mode=mode)
    if mode == "max":
        return jax.ops.segment_max(x, parent, num_segments=G)
    total = jax.ops.segment_sum(x, parent, num_segments=G)
    count = jax.ops.segment_sum(jnp.ones((x.shape[0], 1), x.dtype), parent, num_segments=G)
    return total / jnp.maximum(count, jnp.ones((), x.dtype))

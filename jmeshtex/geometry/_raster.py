"""Rasterise a UV layout: which texels of a ``size × size`` atlas each UV triangle covers, and where.

Texel convention (the same as :mod:`jmeshtex.geometry._texture` and :class:`jmeshtex.Mesh`): row 0
is the top of the image (``v = 1``), column 0 its left edge (``u = 0``). Texel ``(row, col)`` is the
square ``[col, col + 1] × [row, row + 1]`` of the texel plane ``(x, y) = (u · size, (1 − v) · size)``
and its centre is

.. math:: (u, v) = \\left(\\frac{col + ½}{size},\\; 1 - \\frac{row + ½}{size}\\right).

Everything is vectorised over (triangle, texel of its bounding box) pairs; nothing loops per face or
per texel. Which face "owns" a texel two triangles share is the caller's policy, not this module's.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from jaxtyping import Bool, Float, Int, Real

from .._config import is_int
from .._errors import InputError

_COVERAGES = ("center", "overlap")
# "center": a texel centre counts as inside when every barycentric coordinate is >= -_INSIDE
_INSIDE = 1e-9
# "overlap": a square and a triangle that overlap by less than this (texel units) only touch
_TOUCH = 1e-9
# a UV triangle whose texel-space cross product is below this times its edges' extents is degenerate
_DEGENERATE = 1e-12


class Raster(NamedTuple):
    """Texels covered by UV triangles, one entry per (face, texel) pair.

    Entries are sorted by face, then row, then column; a texel two triangles cover appears twice.

    Attributes:
      face: ``[N]`` int64 UV triangle (index into ``uv``'s first axis).
      row: ``[N]`` int64 texel row (0 at the top, ``v = 1``).
      col: ``[N]`` int64 texel column (0 at ``u = 0``).
      bary: ``[N, 3]`` float64 barycentric coordinates in ``face`` of the point the texel maps to,
        non-negative and summing to 1.
      distance: ``[N]`` float64 distance in texels from the texel centre to that point: 0 for
        centres inside the triangle (always 0 with ``coverage="center"``).
    """

    face: Int[np.ndarray, " N"]
    row: Int[np.ndarray, " N"]
    col: Int[np.ndarray, " N"]
    bary: Float[np.ndarray, "N 3"]
    distance: Float[np.ndarray, " N"]


def rasterize_uv(uv: Real[np.ndarray, "F 3 2"], size: int, *, coverage: str = "center") -> Raster:
    """Texels of a ``size × size`` atlas covered by UV triangles, with barycentric coordinates.

    With corners ``P_k = (u_k · size, (1 − v_k) · size)`` in the texel plane and texel centres
    ``c = (col + ½, row + ½)``:

    - ``coverage="center"``: texel ``(row, col)`` is covered by triangle ``f`` when ``c`` lies in
      it, i.e. ``c = Σ_k b_k P_k`` with every ``b_k ≥ −10⁻⁹`` (centres on a shared edge belong to
      both triangles). ``bary`` is ``b`` clipped to ``[0, 1]`` and renormalised to sum 1.
    - ``coverage="overlap"``: covered when the texel's square and the triangle overlap with positive
      area (separating axes: the square's two and the triangle's three edge normals; overlaps
      thinner than 10⁻⁹ texel only touch). ``bary`` locates the point of the triangle closest to
      ``c`` (``c`` itself when inside), and ``distance`` is how far that point is from ``c``. This
      is a superset of ``"center"``: border texels whose centre falls just outside a chart too.

    Degenerate UV triangles (zero texel-space area, relative to their edges) cover nothing.

    Args:
      uv: ``[F, 3, 2]`` per-corner texture coordinates ``(u, v)`` (``Mesh.uv``); values outside
        ``[0, 1]`` are allowed (only the part inside the atlas is rasterised).
      size: atlas side in texels, ``>= 1``.
      coverage: ``"center"`` or ``"overlap"`` (see above).

    Returns:
      :class:`Raster` ``(face, row, col, bary, distance)``, sorted by face, row, column.

    Raises:
      InputError: ``uv`` not ``[F, 3, 2]`` or not finite, ``size < 1``, unknown ``coverage``.

    Example:
      >>> uv = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]])    # lower-left half of the atlas
      >>> r = rasterize_uv(uv, 2)
      >>> r.row.tolist(), r.col.tolist()                       # centres on the diagonal count
      ([0, 1, 1], [0, 0, 1])
      >>> r.bary[1].tolist()                                   # centre (1/4, 1/4)
      [0.5, 0.25, 0.25]
      >>> len(rasterize_uv(uv, 2, coverage="overlap").face)    # the top-right square touches only
      3
    """
    uv = _check(uv, size, coverage)
    size = int(size)
    # texel plane: x = u · size (column), y = (1 − v) · size (row); texel squares have unit side
    tex = np.stack([uv[..., 0] * size, (1.0 - uv[..., 1]) * size], axis=-1)
    e1, e2 = tex[:, 1] - tex[:, 0], tex[:, 2] - tex[:, 0]
    cross = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    scale = np.abs(e1).max(axis=1, initial=0.0) * np.abs(e2).max(axis=1, initial=0.0)
    usable = np.abs(cross) > _DEGENERATE * np.maximum(scale, 1e-300)
    if coverage == "center":
        return _center(tex, usable, size)
    return _overlap(tex, usable, size)


def fill_unused_texels(
    image: Float[np.ndarray, "H W C"], used: Bool[np.ndarray, "H W"]
) -> np.ndarray:
    """Give every unused texel of an atlas the value of the nearest used one (Euclidean, in texels).

    Keeps texture filtering and mip-mapping from reading background colour across chart borders.
    The image is returned unchanged when every texel, or none, is used.

    Args:
      image: ``[H, W, C]`` atlas.
      used: ``[H, W]`` True where a texel belongs to a chart.

    Returns:
      ``[H, W, C]`` image, same dtype.

    Example:
      >>> img = np.array([[[1.0], [0.0], [0.0]]])
      >>> fill_unused_texels(img, np.array([[True, False, False]]))[..., 0].tolist()
      [[1.0, 1.0, 1.0]]
    """
    used = np.asarray(used, bool)
    if used.shape != np.shape(image)[:2]:
        raise InputError(
            f"fill_unused_texels: used must be [H, W] = {np.shape(image)[:2]}, got {used.shape}"
        )
    if used.all() or not used.any():
        return image
    from scipy.ndimage import distance_transform_edt

    _, (rows, cols) = distance_transform_edt(~used, return_indices=True)
    return image[rows, cols]


def _check(uv, size, coverage) -> np.ndarray:
    if not is_int(size, 1):
        raise InputError(
            f"rasterize_uv: size must be a positive int (texels per atlas side), got {size!r}"
        )
    if coverage not in _COVERAGES:
        raise InputError(f"rasterize_uv: coverage must be one of {_COVERAGES}, got {coverage!r}")
    uv = np.asarray(uv)
    if (
        uv.ndim != 3
        or uv.shape[1:] != (3, 2)
        or not (np.issubdtype(uv.dtype, np.floating) or np.issubdtype(uv.dtype, np.integer))
    ):
        raise InputError(
            f"rasterize_uv: uv must be a real [F, 3, 2] array of per-corner (u, v) (Mesh.uv), got shape "
            f"{uv.shape} and dtype {uv.dtype}"
        )
    uv = uv.astype(np.float64)
    if not np.isfinite(uv).all():
        bad = np.nonzero(~np.isfinite(uv).all(axis=(1, 2)))[0]
        raise InputError(
            f"rasterize_uv: uv is NaN or infinite at faces {bad[:10].tolist()}"
            f"{' ...' if len(bad) > 10 else ''} ({len(bad)} faces); fix or drop those UVs"
        )
    return uv


def _box_pairs(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (triangle, row, col) with ``lo <= (col, row) <= hi`` (``lo, hi [F, 2]`` as (x, y)),
    triangle-major then row-major, without a per-triangle loop."""
    nx, ny = np.maximum(hi[:, 0] - lo[:, 0] + 1, 0), np.maximum(hi[:, 1] - lo[:, 1] + 1, 0)
    count = nx * ny
    tri = np.repeat(np.arange(len(lo)), count)
    local = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    dy, dx = np.divmod(local, np.maximum(nx, 1)[tri])
    return tri, lo[tri, 1] + dy, lo[tri, 0] + dx


def _center(tex: np.ndarray, usable: np.ndarray, size: int) -> Raster:
    """``coverage="center"``: barycentrics of texel centres, in the plane where centres are integers."""
    p = tex - 0.5  # texel (row, col) has its centre at (x, y) = (col, row)
    lo, hi = p.min(axis=1), p.max(axis=1)
    # the tolerant triangle (all b_k >= -_INSIDE) reaches 2·_INSIDE·extent past the bounding box
    margin = 1e-9 + 2 * _INSIDE * (hi - lo)
    first = np.clip(np.ceil(lo - margin), 0, size - 1).astype(np.int64)
    last = np.clip(np.floor(hi + margin), -1, size - 1).astype(np.int64)
    last[~usable] = -1  # empty box
    tri, row, col = _box_pairs(first, last)
    a = p[tri, 0]
    e1, e2 = p[tri, 1] - a, p[tri, 2] - a
    px, py = col - a[:, 0], row - a[:, 1]
    den = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    b1 = (px * e2[:, 1] - py * e2[:, 0]) / den
    b2 = (e1[:, 0] * py - e1[:, 1] * px) / den
    bary = np.stack([1.0 - b1 - b2, b1, b2], axis=1)
    inside = bary.min(axis=1, initial=np.inf) >= -_INSIDE
    bary = np.clip(bary[inside], 0.0, 1.0)
    bary /= bary.sum(axis=1, keepdims=True)
    return Raster(tri[inside], row[inside], col[inside], bary, np.zeros(len(bary)))


def _overlap(tex: np.ndarray, usable: np.ndarray, size: int) -> Raster:
    """``coverage="overlap"``: separating-axis test of texel squares, closest-point barycentrics."""
    lo = np.clip(np.floor(tex.min(axis=1)), 0, size - 1).astype(np.int64)  # squares meeting the box
    hi = np.clip(np.floor(tex.max(axis=1)), 0, size - 1).astype(np.int64)
    hi[~usable] = -1
    tri, row, col = _box_pairs(lo, hi)
    keep = _square_overlaps(np.take(_separating_axes(tex), tri, axis=0), col, row)
    tri, row, col = tri[keep], row[keep], col[keep]
    bary, dist2 = _closest_barycentric(tex[tri], np.stack([col + 0.5, row + 0.5], axis=1))
    return Raster(tri, row, col, bary, np.sqrt(dist2))


def _separating_axes(p: np.ndarray) -> np.ndarray:
    """Per-triangle separating-axis constants ``[F, 19]`` of triangles ``p [F, 3, 2]``: inward edge
    normals (x, y), their edge and apex projections, the unit square's half extent along them, and
    the bounding box (min x, min y, max x, max y)."""
    edge = np.roll(p, -1, axis=1) - p  # edge k: corner k -> k+1
    normal = np.stack([-edge[..., 1], edge[..., 0]], axis=-1)
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-300)
    det = edge[:, 0, 0] * edge[:, 1, 1] - edge[:, 0, 1] * edge[:, 1, 0]
    normal *= np.where(det < 0, -1.0, 1.0)[:, None, None]  # inward for either orientation
    at_edge = np.einsum("fkd,fkd->fk", normal, p)
    at_apex = np.einsum("fkd,fkd->fk", normal, np.roll(p, -2, axis=1))
    half = 0.5 * (np.abs(normal[..., 0]) + np.abs(normal[..., 1]))
    return np.concatenate(
        [normal[..., 0], normal[..., 1], at_edge, at_apex, half, p.min(axis=1), p.max(axis=1)],
        axis=1,
    )


def _square_overlaps(axes: np.ndarray, col: np.ndarray, row: np.ndarray) -> np.ndarray:
    """Whether unit squares ``[col, col+1] × [row, row+1]`` overlap the triangles whose
    :func:`_separating_axes` rows are ``axes [M, 19]`` by more than ``_TOUCH`` on all five axes."""
    cx, cy = col + 0.5, row + 0.5
    nx, ny, at_edge, at_apex, half = (axes[:, 3 * i : 3 * i + 3] for i in range(5))
    centre = nx * cx[:, None] + ny * cy[:, None]
    ok = ((centre + half > at_edge + _TOUCH) & (centre - half < at_apex - _TOUCH)).all(axis=1)
    lo, hi = axes[:, 15:17], axes[:, 17:19]
    ok &= (cx - 0.5 < hi[:, 0] - _TOUCH) & (cx + 0.5 > lo[:, 0] + _TOUCH)
    ok &= (cy - 0.5 < hi[:, 1] - _TOUCH) & (cy + 0.5 > lo[:, 1] + _TOUCH)
    return ok


def _closest_barycentric(p: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric coordinates ``[M, 3]`` of the point of triangle ``p [M, 3, 2]`` nearest ``x [M, 2]``
    and the squared distance ``[M]`` (exactly 0 inside)."""
    a, b, c = p[:, 0], p[:, 1], p[:, 2]
    e1, e2, w = b - a, c - a, x - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    l1 = (w[:, 0] * e2[:, 1] - w[:, 1] * e2[:, 0]) / det
    l2 = (e1[:, 0] * w[:, 1] - e1[:, 1] * w[:, 0]) / det
    bary = np.stack([1.0 - l1 - l2, l1, l2], axis=1)
    inside = bary.min(axis=1, initial=np.inf) >= 0.0
    # nearest point on each edge k (corner k -> corner k+1), clamped to the segment
    seg = np.roll(p, -1, axis=1) - p
    t = np.einsum("mkd,mkd->mk", x[:, None, :] - p, seg) / np.maximum(
        np.einsum("mkd,mkd->mk", seg, seg), 1e-300
    )
    t = np.clip(t, 0.0, 1.0)
    dist2 = np.sum((p + t[..., None] * seg - x[:, None, :]) ** 2, axis=-1)
    k = np.argmin(dist2, axis=1) if len(p) else np.zeros(0, np.int64)
    rows = np.arange(len(p))
    edge_bary = np.zeros_like(bary)
    edge_bary[rows, k] = 1.0 - t[rows, k]
    edge_bary[rows, (k + 1) % 3] = t[rows, k]
    return np.where(inside[:, None], bary, edge_bary), np.where(inside, 0.0, dist2[rows, k])

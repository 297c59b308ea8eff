"""3×3 exponential-map neighbourhoods of texels (Kovács et al. 2024, Sec. 4.2).

Tap ``(dx, dy)`` of texel n walks the surface from the texel's point along ``dx·t + dy·d`` (its
tangent frame, :class:`~jmeshtex.surfacecnn.core.TextureAtlas`) for ``|(dx, dy)|`` texel sizes (one
texel, √2 on the diagonals) with the straightest-geodesic tracer
(:func:`jmeshtex.geometry.trace_geodesics`, which crosses faces and UV seams: the walk happens on
the merged surface, the end point is read in the UV chart of the face it ends in). The end point's
UV then names the texels the tap reads:

- ``bilinear``: the 4 texels around it with bilinear weights (``J = 4``); invalid texels (outside
  every chart) are dropped and the weights renormalised;
- ``nearest``: the texel whose square contains it (``J = 1``).

If neither finds a valid texel (rounding on a chart border), the valid bilinear corner with the
largest weight is used, else the centre texel. The centre tap reads the texel itself.

**Coupling** (``couple=True``). A chart-border texel whose centre lies outside its UV triangle
covers only a sliver of its chart, and the walks that pass over it continue into the next chart, so
often no tap ends in it: read by no other texel, its colour reaches the Gram loss only through its
own feature rows and drifts to saturated noise (specks along every seam). Such a texel takes over
the nearest read of the tap whose bilinear corners weight it most (that tap ends within one texel of
its centre), as long as the texel the tap read keeps another reader; a texel without such a tap
takes over, in both samplings, the tap of an image 8-neighbour that ends nearest to its centre in
UV. A redirected read alone leaves such a texel's colour weakly constrained, so in addition every
texel whose centre lies outside its UV triangle is *tied* (:func:`border_ties`): it shows the
bilinear sample, at its surface point, of the abutting texels whose centres lie inside; the bilinear
taps read tied texels through the tie and results show it (:func:`apply_tie`).
:func:`unread_share` reports the free texels still unread (0 on the meshes tested; border chroma
in ``docs/results.md``).

**Failed walks.** A walk that reaches a mesh boundary before its full length stops there
(``stopped``). Its tap then reads what the opposite tap (``8 − t``) reads if that walk succeeded,
else the centre (``boundary="opposite"``, the reference tool's rule and
:class:`~jmeshtex.surfacecnn.Config`'s default; :func:`opposite_source`), zero (``"zero"``, this
function's default: the zero padding a 2D CNN applies at the image border, which makes a flat
sheet reproduce the 2D network exactly) or the texel where the walk stopped (``"clamp"``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from jaxtyping import Bool, Float, Int

from .._errors import InputError
from ..geometry import TracerGeometry, trace_geodesics, tracer_geometry
from ..ops import TexelNeighborhood
from ._atlas import TextureAtlas
from ._config import BOUNDARY_MODES

#: tap t holds the offset (dx, dy) = (t % 3 - 1, t // 3 - 1) (jmeshtex.ops texel convention)
TAP_DX = np.tile(np.arange(3) - 1, 3)
TAP_DY = np.repeat(np.arange(3) - 1, 3)
# an end point this far outside its start face (barycentric units) is still taken as inside it
_INSIDE_TOL = -1e-12


class TexelTaps(NamedTuple):
    """Level-0 neighbourhoods of a texel atlas, both samplings from one set of traces.

    Attributes:
      bilinear: :class:`~jmeshtex.TexelNeighborhood` with ``J = 4`` (first convolution).
      nearest: :class:`~jmeshtex.TexelNeighborhood` with ``J = 1`` (later convolutions).
      end_uv: ``[N, 9, 2]`` float64 UV of every tap's end point (the texel's own centre UV for tap 4).
      stopped: ``[N, 9]`` bool, True where the walk hit a mesh boundary.
      tie: ``(index [N, K], weight [N, K])`` or None: the colour every texel shows, as a convex
        combination of texel colours (identity rows for free texels; :func:`border_ties`). The
        bilinear taps already read through it; apply it to the optimised colours with
        :func:`apply_tie`.
    """

    bilinear: TexelNeighborhood
    nearest: TexelNeighborhood
    end_uv: Float[np.ndarray, "N 9 2"]
    stopped: Bool[np.ndarray, "N 9"]
    tie: tuple[Int[np.ndarray, "N K"], Float[np.ndarray, "N K"]] | None = None


def trace_taps(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    atlas: TextureAtlas,
    start: Int[np.ndarray, " M"],
    step: float,
    *,
    rotation: float | Float[np.ndarray, " M"] = 0.0,
    fraction: float = 1.0,
    geometry: TracerGeometry | None = None,
) -> tuple[Float[np.ndarray, "M 8 2"], Bool[np.ndarray, "M 8"]]:
    """Walk the 8 non-centre taps from texels ``start`` and return the end UVs and boundary stops.

    .. math:: \\text{end}_{n,t} = \\exp_{p_n}\\!\\big(\\text{fraction}\\cdot \\text{step}\\,
       e^{i\\alpha_n} (dx_t\\, t_n + dy_t\\, d_n)\\big)

    Args:
      vertices, faces: the mesh.
      atlas: from :func:`~jmeshtex.surfacecnn.core.texture_atlas`.
      start: ``[M]`` valid-texel numbers to walk from.
      step: world length of one tap step (the texel size at level 0, ``2^l`` texel sizes at level l).
      rotation: angle α (radians, scalar or ``[M]``) by which the tap frame is turned
        counter-clockwise (0: the atlas frame); a gauge change of the frames.
      fraction: scales every walk (the pyramid's overshoot correction walks back with it).
      geometry: tracer tables.

    Returns:
      ``(end_uv [M, 8, 2], stopped [M, 8])`` for taps 0–3 and 5–8 (tap 4, the centre, is left out).

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn.core import texture_atlas
      >>> v, f = grid(2)
      >>> atlas = texture_atlas(v, f, v[f][..., :2], size=4)
      >>> end, stopped = trace_taps(v, f, atlas, np.array([5]), atlas.texel_size)
      >>> (end[0, 4] * 8).round(6).tolist(), stopped[0].tolist()  # tap (dx, dy) = (1, 0)
      ([5.0, 5.0], [False, False, False, False, False, False, False, False])
    """
    start = np.asarray(start, dtype=np.int64)
    if geometry is None:
        geometry = tracer_geometry(vertices, faces)
    other = np.array([t for t in range(9) if t != 4])
    offset = TAP_DX[other] + 1j * TAP_DY[other]  # [8] complex, in (t, d) coordinates
    turn = np.exp(1j * np.broadcast_to(np.asarray(rotation, dtype=np.float64), start.shape))
    t_dir = (atlas.tangent[start] * turn)[:, None]
    d_dir = (atlas.down[start] * turn)[:, None]
    unit = (offset.real[None, :] * t_dir + offset.imag[None, :] * d_dir) / np.abs(offset)[None, :]
    length = np.broadcast_to(fraction * step * np.abs(offset)[None, :], unit.shape).ravel()
    face = np.repeat(atlas.face[start], 8)
    bary = np.repeat(atlas.bary[start], 8, axis=0)
    unit = unit.ravel()
    # fast path: walks that end inside their start face need no tracing (most, for texel-sized steps)
    position = np.einsum("nk,nk->n", bary, np.take(geometry.corners, face, axis=0)) + unit * length
    n0x, n0y, n1x, n1y, c0 = np.take(geometry.exit_table, face, axis=0).T
    x, y = position.real, position.imag
    end_bary = np.stack([n0x * x + n0y * y - c0, n1x * x + n1y * y, y], axis=1) / np.take(
        geometry.altitude, face, axis=0
    )
    inside = end_bary.min(axis=1) >= _INSIDE_TOL
    end_bary = np.maximum(end_bary, 0.0)
    end_bary /= end_bary.sum(axis=1, keepdims=True)
    end_face = face.copy()
    stopped = np.zeros(len(face), bool)
    walk = np.nonzero(~inside)[0]
    if walk.size:
        result = trace_geodesics(
            vertices, faces, face[walk], bary[walk], unit[walk], length[walk], geometry=geometry
        )
        end_face[walk] = result.face
        end_bary[walk] = result.bary
        stopped[walk] = result.stopped
    end_uv = _uv_of(atlas, end_face, end_bary)
    return end_uv.reshape(len(start), 8, 2), stopped.reshape(len(start), 8)


def _uv_of(atlas: TextureAtlas, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """UV ``[M, 2]`` of surface points (``uv_at`` with one gather per coordinate)."""
    flat = atlas.uv.reshape(len(atlas.uv), 6)
    rows = np.take(flat, face, axis=0)
    return np.stack(
        [np.einsum("nk,nk->n", bary, rows[:, 0::2]), np.einsum("nk,nk->n", bary, rows[:, 1::2])], 1
    )


def uv_to_texels(
    atlas: TextureAtlas, uv: Float[np.ndarray, "M 2"], fallback: Int[np.ndarray, " M"]
) -> tuple[Int[np.ndarray, "M 4"], Float[np.ndarray, "M 4"], Int[np.ndarray, " M"]]:
    """Bilinear corners (valid ones, renormalised) and the nearest valid texel of UV points.

    With ``x = u S − 0.5``, ``y = (1 − v) S − 0.5`` (``u, v`` clamped to [0, 1]) the corners are
    ``(⌊y⌋ + a, ⌊x⌋ + b)``, ``a, b ∈ {0, 1}``, with weights ``(1 − β, β) ⊗ (1 − α, α)`` (``α, β`` the
    fractional parts); the nearest texel is the corner whose square contains the point. Invalid
    corners are dropped and the weights renormalised; an invalid nearest texel is replaced by the
    valid corner of largest weight. Points without any valid corner read ``fallback`` (weight 1).

    Returns:
      ``(index [M, 4], weight [M, 4], nearest [M])`` in valid-texel numbers (index 0 and weight 0 on
      dropped corners).

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn.core import texture_atlas
      >>> v, f = grid(1)
      >>> atlas = texture_atlas(v, f, v[f][..., :2], size=2)
      >>> idx, w, near = uv_to_texels(atlas, np.array([[0.5, 0.5]]), np.array([0]))
      >>> idx.tolist(), w.tolist(), near.tolist()
      ([[0, 1, 2, 3]], [[0.25, 0.25, 0.25, 0.25]], [3])
    """
    size = atlas.size
    x = np.clip(uv[:, 0], 0.0, 1.0) * size - 0.5
    y = (1.0 - np.clip(uv[:, 1], 0.0, 1.0)) * size - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    ax, ay = x - x0, y - y0
    # pixels with a border of invalid ones: corners at row/col -1 or size need no range checks
    padded = np.full((size + 2, size + 2), -1, np.int64)
    padded[1:-1, 1:-1] = atlas.index_of.reshape(size, size)
    base = (y0.astype(np.int64) + 1) * (size + 2) + (x0.astype(np.int64) + 1)
    index = np.take(padded.ravel(), base[:, None] + np.array([0, 1, size + 2, size + 3]))
    bx, by = 1.0 - ax, 1.0 - ay
    weight = np.stack([by * bx, by * ax, ay * bx, ay * ax], axis=1)
    valid = index >= 0
    weight *= valid
    total = weight.sum(axis=1)
    corner = 2 * (ay >= 0.5) + (ax >= 0.5)
    rows = np.arange(len(uv))
    nearest = index[rows, corner]
    bad = nearest < 0
    if bad.any():
        best = index[rows[bad], np.argmax(weight[bad], axis=1)]
        nearest[bad] = np.where(total[bad] > 0, best, np.asarray(fallback)[bad])
    empty = total <= 0
    weight /= np.where(empty, 1.0, total)[:, None]
    index = np.where(valid, index, 0)
    if empty.any():
        index[empty] = 0
        index[empty, 0] = nearest[empty]
        weight[empty] = np.array([1.0, 0.0, 0.0, 0.0])
    return index, weight, nearest


def opposite_source(stopped: Bool[np.ndarray, "N 9"]) -> Int[np.ndarray, "N 9"]:
    """Which tap each tap reads under the reference tool's boundary rule (``boundary="opposite"``).

    A tap whose walk hit a mesh boundary reads the point-mirrored tap ``8 − t`` (the tap on the
    opposite side of the centre) when that walk succeeded, else the centre tap 4; every other tap
    reads itself (Kovács et al.'s reference tool, ``create_curved_neighborhoods``).

    Args:
      stopped: ``[N, 9]`` True where tap t's walk stopped at a boundary (False at the centre).

    Returns:
      ``[N, 9]`` int64 tap numbers.

    Example:
      >>> s = np.zeros((1, 9), bool)
      >>> s[0, [0, 1, 7]] = True                     # taps (−1, −1), (0, −1) and (0, 1) failed
      >>> opposite_source(s)[0].tolist()
      [8, 4, 2, 3, 4, 5, 6, 4, 8]
    """
    stopped = np.asarray(stopped, bool)
    taps = np.broadcast_to(np.arange(9), stopped.shape)
    mirrored = 8 - taps
    replacement = np.where(np.take_along_axis(stopped, mirrored, axis=1), 4, mirrored)
    return np.where(stopped, replacement, taps)


def texel_taps(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    atlas: TextureAtlas,
    *,
    boundary: str = "zero",
    rotation: float | Float[np.ndarray, " N"] = 0.0,
    couple: bool = True,
    geometry: TracerGeometry | None = None,
) -> TexelTaps:
    """The 3×3 exp-map neighbourhood of every valid texel, as bilinear and as nearest taps.

    See the module docstring for the walk, the UV → texel mapping and the failed-walk rule.

    Args:
      vertices, faces: the mesh.
      atlas: from :func:`~jmeshtex.surfacecnn.core.texture_atlas`.
      boundary: ``"zero"`` (default), ``"opposite"`` or ``"clamp"``: what a tap whose walk hit a
        boundary reads (module docstring).
      rotation: turn every texel's tap frame by this angle (radians, scalar or ``[N]``); 0 keeps the
        atlas frame. Turning by π/2 reads the texture rotated by 90° (the gauge check).
      couple: True (default) so that every texel is read by another texel's taps: chart-border
        texels that no walk ends in take over nearby taps (module docstring; measured in
        ``docs/results.md``); False keeps the pure geometric reads.
      geometry: tracer tables (:func:`~jmeshtex.geometry.tracer_geometry`).

    Returns:
      :class:`TexelTaps`.

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn.core import texture_atlas
      >>> v, f = grid(2)
      >>> atlas = texture_atlas(v, f, v[f][..., :2], size=4)
      >>> taps = texel_taps(v, f, atlas)
      >>> taps.nearest.index[5, :, 0].tolist()       # texel (row 1, col 1): rows 0-2, cols 0-2
      [0, 1, 2, 4, 5, 6, 8, 9, 10]
      >>> taps.nearest.weight[0, :, 0].tolist()      # the corner texel: zero padding off the sheet
      [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0]
    """
    if boundary not in BOUNDARY_MODES:
        raise InputError(f"texel_taps: boundary must be one of {BOUNDARY_MODES}, got {boundary!r}")
    N = atlas.num_texels
    centre = np.arange(N)
    end8, stop8 = trace_taps(
        vertices, faces, atlas, centre, atlas.texel_size, rotation=rotation, geometry=geometry
    )
    idx8, w8, near8 = uv_to_texels(atlas, end8.reshape(-1, 2), np.repeat(centre, 8))
    row, col = atlas.rows_cols()
    own_uv = np.stack([(col + 0.5) / atlas.size, 1.0 - (row + 0.5) / atlas.size], axis=1)

    def with_centre(a8, a4):
        a8 = a8.reshape(N, 8, *a8.shape[1:])
        return np.concatenate([a8[:, :4], a4[:, None], a8[:, 4:]], axis=1)

    end_uv = with_centre(end8.reshape(-1, 2), own_uv)
    stopped = with_centre(stop8.ravel(), np.zeros(N, bool))
    own_index = np.zeros((N, 4), np.int64)
    own_index[:, 0] = centre
    index = with_centre(idx8, own_index)
    weight = with_centre(w8, np.tile([1.0, 0.0, 0.0, 0.0], (N, 1)))
    nearest = with_centre(near8, centre)
    if boundary == "opposite":
        source = opposite_source(stopped)
        rows = np.arange(N)[:, None]
        index, weight, nearest = index[rows, source], weight[rows, source], nearest[rows, source]
    off = stopped if boundary == "zero" else np.zeros_like(stopped)
    weight = np.where(off[..., None], 0.0, weight)
    index = np.where(off[..., None], 0, index)
    nearest = np.where(off, 0, nearest)
    tie = None
    if couple:
        index, weight, nearest = _couple_unread(atlas, end_uv, index, weight, nearest, ~off)
        tie = border_ties(atlas)
        index, weight = _read_through(index, weight, tie)
    mask = np.ones(N, bool)
    return TexelTaps(
        bilinear=TexelNeighborhood(index=index.astype(np.int32), weight=weight, texel_mask=mask),
        nearest=TexelNeighborhood(
            index=nearest.astype(np.int32)[..., None],
            weight=(~off).astype(np.float64)[..., None],
            texel_mask=mask,
        ),
        end_uv=end_uv,
        stopped=stopped,
        tie=tie,
    )


def border_ties(atlas: TextureAtlas) -> tuple[Int[np.ndarray, "N 4"], Float[np.ndarray, "N 4"]]:
    """Tie every chart-border texel whose centre lies outside its UV triangle to the texels it abuts.

    Such a texel covers a sliver of its chart; its surface point is its centre snapped onto the
    triangle. It shows the bilinear sample, at that point's UV, of the texels whose centres lie
    inside their triangles (tied corners dropped, weights renormalised); where none of the four
    corners qualifies, the mean of its untied valid 8-neighbours within two texel sizes on the
    surface; where none exists it stays free. Every other texel shows its own colour.

    Returns:
      ``(index [N, 4], weight [N, 4])`` valid-texel numbers and convex weights (row n: texel n with
      weight 1 for a free texel).

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn.core import texture_atlas
      >>> v, f = grid(2)
      >>> index, weight = border_ties(texture_atlas(v, f, v[f][..., :2], size=4))
      >>> bool((index[:, 0] == np.arange(16)).all() and (weight[:, 0] == 1).all())
      True
    """
    N, size = atlas.num_texels, atlas.size
    row, col = atlas.rows_cols()
    centre = np.stack([(col + 0.5) / size, 1.0 - (row + 0.5) / size], axis=1)
    snapped = _uv_of(atlas, atlas.face, atlas.bary)
    tied = np.linalg.norm(snapped - centre, axis=1) * size > 1e-6
    index = np.zeros((N, 4), np.int64)
    index[:, 0] = np.arange(N)
    weight = np.zeros((N, 4))
    weight[:, 0] = 1.0
    todo = np.nonzero(tied)[0]
    if not todo.size:
        return index, weight
    idx, w, _ = uv_to_texels(atlas, snapped[todo], todo)
    w = np.where(tied[idx], 0.0, w)
    total = w.sum(axis=1)
    good = total > 0
    index[todo[good]] = idx[good]
    weight[todo[good]] = w[good] / total[good, None]
    rest = todo[~good]
    if rest.size:  # no untied corner: the untied 8-neighbours close on the surface
        r, c = row[rest], col[rest]
        near_index, near_weight = [], []
        for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)):
            rr, cc = r + dr, c + dc
            inside = (rr >= 0) & (rr < size) & (cc >= 0) & (cc < size)
            pixel = np.clip(rr, 0, size - 1) * size + np.clip(cc, 0, size - 1)
            v = np.where(inside, atlas.index_of[pixel], -1)
            vv = np.maximum(v, 0)
            dist = np.linalg.norm(atlas.point[vv] - atlas.point[rest], axis=1)
            ok = (v >= 0) & ~tied[vv] & (dist <= 2.0 * atlas.local_size[rest])
            near_index.append(vv)
            near_weight.append(ok.astype(np.float64))
        ni, nw = np.stack(near_index, axis=1), np.stack(near_weight, axis=1)
        keep = np.argsort(-nw, axis=1, kind="stable")[:, :4]  # up to 4 of them
        ni, nw = np.take_along_axis(ni, keep, 1), np.take_along_axis(nw, keep, 1)
        found = nw.sum(axis=1) > 0
        index[rest[found]] = ni[found]
        weight[rest[found]] = nw[found] / nw[found].sum(axis=1, keepdims=True)
    return index, weight


def apply_tie(colors, tie):
    """The colours texels show under a tie (:func:`border_ties`): ``out_n = Σ_k w_nk colors[i_nk]``.

    Works on NumPy and JAX arrays; ``tie=None`` returns ``colors`` unchanged.

    Example:
      >>> tie = (np.array([[0, 0], [0, 2], [2, 0]]), np.array([[1.0, 0], [0.5, 0.5], [1.0, 0]]))
      >>> apply_tie(np.array([[0.0], [9.0], [1.0]]), tie).ravel().tolist()
      [0.0, 0.5, 1.0]
    """
    if tie is None:
        return colors
    index, weight = tie
    return (colors[index] * weight[..., None].astype(colors.dtype)).sum(axis=1)


def _read_through(index, weight, tie):
    """Bilinear taps composed with the tie: a corner on a tied texel reads its tie's texels (the
    weights of a texel reached twice are summed; width ``max(J, most texels one tap reads)``)."""
    tie_index, tie_weight = tie
    if (tie_weight[:, 0] == 1.0).all() and (tie_index[:, 0] == np.arange(len(tie_index))).all():
        return index, weight
    N, T, J = index.shape
    M = len(tie_index)
    free = (tie_index[:, 0] == np.arange(M)) & (tie_weight[:, 0] == 1.0)
    flat_index, flat_weight = index.reshape(N * T, J), weight.reshape(N * T, J)
    touched = np.nonzero(((~free[flat_index]) & (flat_weight != 0)).any(axis=1))[0]
    idx = tie_index[flat_index[touched]].reshape(len(touched), -1)
    w = (flat_weight[touched, :, None] * tie_weight[flat_index[touched]]).reshape(len(touched), -1)
    row, col = np.nonzero(w)
    key, inverse = np.unique(row * M + idx[row, col], return_inverse=True)
    total = np.bincount(inverse.ravel(), weights=w[row, col], minlength=len(key))
    tap, texel = np.divmod(key, M)
    slot = np.arange(len(key)) - np.searchsorted(tap, np.arange(len(touched)))[tap]
    width = max(J, int(slot.max(initial=0)) + 1)
    out_index = np.zeros((N * T, width), np.int64)
    out_weight = np.zeros((N * T, width))
    out_index[:, :J], out_weight[:, :J] = flat_index, flat_weight
    out_index[touched], out_weight[touched] = 0, 0.0
    out_index[touched[tap], slot] = texel
    out_weight[touched[tap], slot] = total
    return out_index.reshape(N, T, width), out_weight.reshape(N, T, width)


def read_counts(nbhd: TexelNeighborhood) -> Int[np.ndarray, " N"]:
    """How many taps of *other* texels read each texel with a non-zero weight (its in-degree).

    Args:
      nbhd: a level-0 :class:`~jmeshtex.TexelNeighborhood` (``index``/``weight`` ``[N, 9, J]``).

    Returns:
      ``[N]`` int64: for every texel the number of (texel ≠ it, tap, corner) slots reading it.

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn.core import texture_atlas
      >>> v, f = grid(2)
      >>> taps = texel_taps(v, f, texture_atlas(v, f, v[f][..., :2], size=4))
      >>> read_counts(taps.nearest).reshape(4, 4).tolist()    # zero padding off the sheet
      [[3, 5, 5, 3], [5, 8, 8, 5], [5, 8, 8, 5], [3, 5, 5, 3]]
    """
    index = np.asarray(nbhd.index).astype(np.int64)
    weight = np.asarray(nbhd.weight)
    N = index.shape[0]
    reads = (weight != 0) & (index != np.arange(N).reshape((N,) + (1,) * (index.ndim - 1)))
    return np.bincount(index[reads], minlength=N)


def unread_share(taps: TexelTaps) -> dict[str, float]:
    """Share of texels with a free colour that no other texel's taps read (in-degree 0).

    A texel nobody reads reaches the loss only through its own feature rows, so the Gram match
    leaves its colour free (the chart-border specks that :func:`texel_taps` ``couple=True``
    removes). Texels tied to others (``taps.tie``) have no free colour and are not counted.

    Returns:
      ``{"nearest": share, "bilinear": share, "either": share}`` in [0, 1] (``"either"``: unread
      by one sampling or the other).

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn.core import texture_atlas
      >>> v, f = grid(2)
      >>> unread_share(texel_taps(v, f, texture_atlas(v, f, v[f][..., :2], size=4)))["either"]
      0.0
    """
    near = read_counts(taps.nearest) == 0
    bil = read_counts(taps.bilinear) == 0
    if taps.tie is not None:  # a tied texel shows other texels' colours: it has no free value
        index, weight = taps.tie
        free = (index[:, 0] == np.arange(len(index))) & (weight[:, 0] == 1.0)
        near, bil = near & free, bil & free
    return {
        "nearest": float(near.mean()),
        "bilinear": float(bil.mean()),
        "either": float((near | bil).mean()),
    }


def _couple_unread(atlas, end_uv, index, weight, nearest, live, rounds: int = 4):
    """Redirect taps so that every texel is read by another texel's nearest and bilinear taps.

    A texel no nearest tap reads (a chart-border texel whose centre lies outside its UV triangle:
    the walks that pass over it continue into the next chart) takes over the nearest read of the
    tap whose bilinear corners give it the largest weight (its end point lies within one texel of
    the texel's centre), provided the texel that tap read keeps another reader. A texel with no such
    tap (no end point within its bilinear support) takes over, in both samplings, the tap of a valid
    8-neighbour in the image whose end point is nearest to its centre in UV.
    """
    N = len(nearest)
    own = np.arange(N)

    def counts():
        reads = live & (nearest != own[:, None])
        return np.bincount(nearest[reads], minlength=N)

    for _ in range(rounds):
        count = counts()
        unread = count == 0
        cand = (weight > 0) & unread[index] & (index != own[:, None, None]) & live[..., None]
        n, t, j = np.nonzero(cand)
        u, w = index[n, t, j], weight[n, t, j]
        ok = (count[nearest[n, t]] >= 2) & ~unread[nearest[n, t]]
        n, t, u, w = n[ok], t[ok], u[ok], w[ok]
        if not len(u):
            break
        order = np.lexsort((-w, u))  # per unread texel, the heaviest corner first
        n, t, u = n[order], t[order], u[order]
        first = np.unique(u, return_index=True)[1]
        n, t, u = n[first], t[first], u[first]
        tap = n * 9 + t  # one redirect per tap and per donor texel in a round
        keep = np.unique(tap, return_index=True)[1]
        n, t, u = n[keep], t[keep], u[keep]
        keep = np.unique(nearest[n, t], return_index=True)[1]
        n, t, u = n[keep], t[keep], u[keep]
        nearest[n, t] = u
    _adopt_by_neighbour(atlas, end_uv, index, weight, nearest, live, counts)
    return index, weight, nearest


def _adopt_by_neighbour(atlas, end_uv, index, weight, nearest, live, counts) -> None:
    """Texels still unread take the closest-ending tap of a valid image 8-neighbour (in place)."""
    unread = (counts() == 0) | (read_counts(TexelNeighborhood(index, weight, None)) == 0)
    todo = np.nonzero(unread)[0]
    if not todo.size:
        return
    size = atlas.size
    row, col = np.divmod(atlas.texel[todo], size)
    centre = np.stack([(col + 0.5) / size, 1.0 - (row + 0.5) / size], axis=1)
    best = np.full(len(todo), np.inf)
    pick = np.full((len(todo), 2), -1)
    count = counts()
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            r, c = row + dr, col + dc
            inside = (r >= 0) & (r < size) & (c >= 0) & (c < size) & ((dr, dc) != (0, 0))
            pixel = np.clip(r, 0, size - 1) * size + np.clip(c, 0, size - 1)
            v = np.where(inside, atlas.index_of[pixel], -1)
            for t in (0, 1, 2, 3, 5, 6, 7, 8):
                donor = nearest[np.maximum(v, 0), t]
                d = np.linalg.norm(end_uv[np.maximum(v, 0), t] - centre, axis=1)
                good = (v >= 0) & live[np.maximum(v, 0), t] & (count[donor] >= 2) & (d < best)
                best = np.where(good, d, best)
                pick[good] = np.stack([v[good], np.full(good.sum(), t)], axis=1)
    found = pick[:, 0] >= 0
    # one adoption per tap (two unread texels may pick the same one: the first keeps it)
    taps = pick[found, 0] * 9 + pick[found, 1]
    first = np.unique(taps, return_index=True)[1]
    u = todo[found][first]
    v, t = pick[found][first].T
    nearest[v, t] = u
    index[v, t] = 0
    index[v, t, 0] = u
    weight[v, t] = 0.0
    weight[v, t, 0] = 1.0

"""UV chart seams: which faces form a chart, how much the texel frames turn across a seam, and how
visible a texture's seams are.

A *seam edge* is an interior mesh edge whose two faces place it differently in UV (the charts are
cut there). Two measurements answer the surface CNN's whole point (Kovács et al. 2024, Sec. 1):

- :func:`frame_seam_turn`: the angle by which the tangent frame turns across each seam edge, the
  frame on one side carried to the other by unfolding the two faces (the tracer's crossing
  rotation). UV frames jump by whatever the two charts' layouts differ (often tens of degrees);
  surface frames (``"global"``, ``"smooth"``) turn only by the small change of the projection plane.
- :func:`seam_ratio`: colour difference across chart seams relative to inside charts. The texel
  pairs are the level-0 axial taps (texel ``n`` and the texel its one-texel walk along ``±t``,
  ``±d`` reads): a pair whose texels lie in different charts touches on the surface across a seam;
  a pair inside one chart that are image neighbours is an interior pair. A seamless texture scores
  ≈ 1; a texture synthesised in UV space, ignoring the surface, puts unrelated colours on the two
  sides of every seam and scores well above 1.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Float, Int
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from ..geometry import TracerGeometry, tracer_geometry
from ..ops import TexelNeighborhood
from ._atlas import TextureAtlas, surface_tangents, uv_face_tangents, vertex_directions
from ._config import FRAME_MODES

#: UV coordinates closer than this are the same point (charts are glued there)
_UV_TOL = 1e-9
#: axial taps (dx, dy) = (0, −1), (−1, 0), (1, 0), (0, 1)
_AXIAL = (1, 3, 5, 7)


def _interior_edges(geometry: TracerGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Every interior edge once: ``(face [E], edge k [E])`` with ``face < neighbour``."""
    f, k = np.nonzero(geometry.neighbor >= 0)
    keep = f < geometry.neighbor[f, k]
    return f[keep], k[keep]


def seam_edges(
    geometry: TracerGeometry, uv: Float[np.ndarray, "F 3 2"]
) -> tuple[Int[np.ndarray, " E"], Int[np.ndarray, " E"]]:
    """Interior edges whose two faces give them different UVs: ``(face [E], edge k [E])``.

    Edge ``k`` of face ``f`` runs from corner ``k`` to ``k + 1``; in the neighbour ``g`` it is edge
    ``m = geometry.neighbor_edge[f, k]``, from corner ``m + 1`` to ``m``.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(1)
      >>> seam_edges(tracer_geometry(v, f), v[f][..., :2])[0].size     # one chart: no seam
      0
    """
    f, k = _interior_edges(geometry)
    g = geometry.neighbor[f, k]
    m = geometry.neighbor_edge[f, k]
    a_f, b_f = uv[f, k], uv[f, (k + 1) % 3]
    a_g, b_g = uv[g, (m + 1) % 3], uv[g, m]
    differs = (np.abs(a_f - a_g).max(axis=1) > _UV_TOL) | (np.abs(b_f - b_g).max(axis=1) > _UV_TOL)
    return f[differs], k[differs]


def chart_labels(geometry: TracerGeometry, uv: Float[np.ndarray, "F 3 2"]) -> Int[np.ndarray, " F"]:
    """The UV chart of every face: connected components of faces glued along non-seam edges.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> uv = v[f][..., :2].copy()
      >>> uv[f[:, 0] == 0] += 2.0                    # move the faces at vertex 0 away: a second chart
      >>> np.unique(chart_labels(tracer_geometry(v, f), uv)).size
      2
    """
    f, k = _interior_edges(geometry)
    sf, sk = seam_edges(geometry, uv)
    F = len(geometry.faces)
    seam = np.zeros((F, 3), bool)
    seam[sf, sk] = True
    glued = ~seam[f, k]
    a, b = f[glued], geometry.neighbor[f, k][glued]
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(F, F))
    return connected_components(graph, directed=False)[1].astype(np.int64)


def frame_seam_turn(
    mesh: Mesh | tuple,
    *,
    frames: str = "global",
    frame_vector=(1.0, 0.0, 0.0),
    geometry: TracerGeometry | None = None,
) -> Float[np.ndarray, " E"]:
    """How far the texel frames ``(t, d)`` turn across every seam edge of the mesh's UV layout.

    At the midpoint of seam edge ``(f, k)`` the frame of face ``f`` (carried into the neighbour's
    plane by unfolding, ``c_{fk}`` the tracer's crossing rotation) is compared with the neighbour's:

    .. math:: \\delta = \\max\\big(\\lvert\\arg(t_g / (c_{fk} t_f))\\rvert,\\
       \\lvert\\arg(d_g / (c_{fk} d_f))\\rvert\\big)

    Args:
      mesh: a :class:`~jmeshtex.Mesh` with ``uv`` (a mesh without, or a ``(vertices, faces)`` pair,
        is unwrapped with xatlas).
      frames: ``"global"``, ``"smooth"`` or ``"uv"`` (:func:`~jmeshtex.surfacecnn.core.texture_atlas`).
      frame_vector: the global vector of the surface frames.
      geometry: tracer tables.

    Returns:
      ``[E]`` float64 angles in radians, in [0, π], one per seam edge (:func:`seam_edges` order).

    Example:
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> uv = v[f][..., :2].copy()
      >>> uv[f[:, 0] == 0] = 1.0 - uv[f[:, 0] == 0]  # turn two faces' chart by 180°
      >>> frame_seam_turn(Mesh(v, f, uv=uv), frames="uv").round(6).tolist()
      [3.141593, 3.141593]
      >>> frame_seam_turn(Mesh(v, f, uv=uv)).round(6).tolist()
      [0.0, 0.0]
    """
    from ._atlas import unwrap_uv

    if frames not in FRAME_MODES:
        raise InputError(f"frame_seam_turn: frames must be one of {FRAME_MODES}, got {frames!r}")
    mesh = as_mesh(mesh)
    v, faces = mesh.vertices, mesh.faces
    uv = unwrap_uv(v, faces) if mesh.uv is None else np.asarray(mesh.uv, np.float64)
    geometry = tracer_geometry(v, faces) if geometry is None else geometry
    f, k = seam_edges(geometry, uv)
    g, m = geometry.neighbor[f, k], geometry.neighbor_edge[f, k]
    if frames == "uv":
        t, side = uv_face_tangents(geometry, uv)
        t_f, t_g = t[f], t[g]
        d_f, d_g = 1j * side[f] * t_f, 1j * side[g] * t_g
    else:
        field = vertex_directions(v, faces, frames=frames, frame_vector=frame_vector)
        rows = np.arange(len(f))
        bary_f = np.zeros((len(f), 3))
        bary_f[rows, k] = bary_f[rows, (k + 1) % 3] = 0.5
        bary_g = np.zeros((len(f), 3))
        bary_g[rows, m] = bary_g[rows, (m + 1) % 3] = 0.5
        t_f = surface_tangents(v, faces, field, f, bary_f, frame_vector=frame_vector)
        t_g = surface_tangents(v, faces, field, g, bary_g, frame_vector=frame_vector)
        d_f, d_g = -1j * t_f, -1j * t_g
    c = geometry.crossing[f, k]
    return np.maximum(np.abs(np.angle(t_g / (c * t_f))), np.abs(np.angle(d_g / (c * d_f))))


def seam_pairs(
    atlas: TextureAtlas, nearest: TexelNeighborhood, geometry: TracerGeometry
) -> tuple[np.ndarray, np.ndarray]:
    """Texel pairs across chart seams and inside charts, from the level-0 axial taps.

    Returns:
      ``(seam [P, 2], interior [Q, 2])`` valid-texel numbers: a texel and the texel one of its axial
      taps reads, in different charts (``seam``) or in the same chart and 8-neighbours in the image
      (``interior``). Taps that read the texel itself or read nothing (weight 0) are left out.

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn.core import texel_taps, texture_atlas
      >>> v, f = grid(1)
      >>> atlas = texture_atlas(v, f, v[f][..., :2], size=4)
      >>> seam, inner = seam_pairs(atlas, texel_taps(v, f, atlas).nearest, tracer_geometry(v, f))
      >>> len(seam), len(inner)                     # one chart; 4·4·4 taps minus 16 off the sheet
      (0, 48)
    """
    chart = chart_labels(geometry, atlas.uv)[atlas.face]
    index = np.asarray(nearest.index)[:, _AXIAL, 0].astype(np.int64)
    live = np.asarray(nearest.weight)[:, _AXIAL, 0] > 0
    a = np.broadcast_to(np.arange(atlas.num_texels)[:, None], index.shape)
    keep = live & (index != a)
    a, b = a[keep], index[keep]
    row, col = atlas.rows_cols()
    across = chart[a] != chart[b]
    adjacent = (np.abs(row[a] - row[b]) <= 1) & (np.abs(col[a] - col[b]) <= 1)
    inner = ~across & adjacent
    return np.stack([a[across], b[across]], 1), np.stack([a[inner], b[inner]], 1)


def seam_ratio(
    colors: Float[np.ndarray, "N 3"],
    atlas: TextureAtlas,
    nearest: TexelNeighborhood,
    *,
    geometry: TracerGeometry | None = None,
) -> dict:
    """Mean colour difference across chart seams over the mean difference inside charts.

    .. math:: r = \\frac{\\operatorname{mean}_{(a,b) \\in \\text{seam}} \\lVert c_a - c_b\\rVert}
       {\\operatorname{mean}_{(a,b) \\in \\text{interior}} \\lVert c_a - c_b\\rVert}

    over the pairs of :func:`seam_pairs`; ≈ 1 for a seamless texture.

    Args:
      colors: ``[N, 3]`` texel colours (atlas order).
      atlas: the :class:`~jmeshtex.surfacecnn.core.TextureAtlas`.
      nearest: level-0 nearest taps (``Surface.pyramid.nearest[0]`` or ``texel_taps(...).nearest``).
      geometry: tracer tables of the mesh (built from the atlas' mesh if None is impossible: give it).

    Returns:
      ``{"ratio", "seam", "interior", "seam_pairs", "interior_pairs"}``.

    Raises:
      InputError: no seam pair (a single chart) or no interior pair.

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn.core import texel_taps, texture_atlas
      >>> v, f = grid(2)
      >>> uv = v[f][..., :2] * 0.45
      >>> uv[f[:, 0] == 0] += 0.5                    # the faces at vertex 0 in a second chart
      >>> atlas = texture_atlas(v, f, uv, size=16)
      >>> taps = texel_taps(v, f, atlas)
      >>> row, col = atlas.rows_cols()
      >>> r = seam_ratio(np.stack([col / 16.0] * 3, 1), atlas, taps.nearest, geometry=tracer_geometry(v, f))
      >>> r["ratio"] > 2                             # a ramp in UV space: the seam shows
      True
    """
    if geometry is None:
        raise InputError(
            "seam_ratio: give geometry= (jmeshtex.geometry.tracer_geometry of the mesh)"
        )
    colors = np.asarray(colors, np.float64)
    if colors.shape != (atlas.num_texels, colors.shape[-1]) or colors.ndim != 2:
        raise InputError(
            f"seam_ratio: colors must be [N, C] with N = {atlas.num_texels}, got {colors.shape}"
        )
    seam, inner = seam_pairs(atlas, nearest, geometry)
    if not len(seam) or not len(inner):
        raise InputError(
            f"seam_ratio: needs seam and interior texel pairs, got {len(seam)} and {len(inner)} "
            "(a single chart has no seam)"
        )
    d_seam = np.linalg.norm(colors[seam[:, 0]] - colors[seam[:, 1]], axis=1).mean()
    d_inner = np.linalg.norm(colors[inner[:, 0]] - colors[inner[:, 1]], axis=1).mean()
    return {
        "ratio": float(d_seam / max(d_inner, 1e-300)),
        "seam": float(d_seam),
        "interior": float(d_inner),
        "seam_pairs": len(seam),
        "interior_pairs": len(inner),
    }


def border_texels(atlas: TextureAtlas, geometry: TracerGeometry) -> np.ndarray:
    """Chart-border texels: valid texels with an image 8-neighbour that is invalid or in another chart.

    Args:
      atlas: :func:`~jmeshtex.surfacecnn.core.texture_atlas`'s atlas.
      geometry: :func:`~jmeshtex.geometry.tracer_geometry` of the same mesh.

    Returns:
      ``[N]`` bool (atlas order).

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn.core import texture_atlas
      >>> v, f = grid(2)
      >>> atlas = texture_atlas(v, f, v[f][..., :2], size=4)
      >>> border_texels(atlas, tracer_geometry(v, f)).reshape(4, 4).sum(), atlas.num_texels
      (np.int64(12), 16)
    """
    size = atlas.size
    chart = np.full(size * size, -1, np.int64)
    chart[atlas.texel] = chart_labels(geometry, atlas.uv)[atlas.face]
    grid = np.pad(chart.reshape(size, size), 1, constant_values=-1)
    row, col = atlas.rows_cols()
    own = chart[atlas.texel]
    border = np.zeros(atlas.num_texels, bool)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            border |= grid[row + 1 + dr, col + 1 + dc] != own
    return border


def seam_chroma(
    atlas: TextureAtlas,
    colors: Float[np.ndarray, "N 3"],
    geometry: TracerGeometry,
) -> dict[str, float]:
    """Mean chroma (``max − min`` of RGB) of chart-border texels against interior texels.

    On a grey exemplar every colour in the result is error; texels that no other texel reads
    (:func:`~jmeshtex.surfacecnn.core.unread_share`) drift to saturated colours, so their chroma is
    the seam-speck measure. A ratio near 1 means the chart borders look like the interior.

    Args:
      atlas: the atlas ``colors`` live on.
      colors: ``[N, 3]`` texel colours in [0, 1].
      geometry: :func:`~jmeshtex.geometry.tracer_geometry` of the mesh.

    Returns:
      ``{"border": mean, "interior": mean, "ratio": border / interior, "border_share": share}``.

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn.core import texture_atlas
      >>> v, f = grid(2)
      >>> atlas = texture_atlas(v, f, v[f][..., :2], size=8)
      >>> c = np.full((64, 3), 0.5)
      >>> c[:, 0] += 0.1
      >>> round(seam_chroma(atlas, c, tracer_geometry(v, f))["ratio"], 6)
      1.0
    """
    colors = np.asarray(colors, np.float64)
    if colors.shape != (atlas.num_texels, 3):
        raise InputError(
            f"seam_chroma: colors must be [{atlas.num_texels}, 3] (one RGB per valid texel), "
            f"got {colors.shape}"
        )
    chroma = colors.max(axis=1) - colors.min(axis=1)
    border = border_texels(atlas, geometry)
    b = float(chroma[border].mean()) if border.any() else float("nan")
    i = float(chroma[~border].mean()) if (~border).any() else float("nan")
    return {
        "border": b,
        "interior": i,
        "ratio": b / i if i > 0 else float("nan"),
        "border_share": float(border.mean()),
    }


def seam_texels(
    mesh: Mesh | tuple, atlas: TextureAtlas, *, geometry: TracerGeometry | None = None
) -> np.ndarray:
    """Chart-border texels that lie at a UV seam: :func:`border_texels` whose surface point is
    within two local texel sizes of a seam edge (mesh-boundary borders are left out).

    Returns:
      ``[N]`` bool (atlas order).

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn.core import texture_atlas
      >>> v, f = grid(2)
      >>> int(seam_texels((v, f), texture_atlas(v, f, v[f][..., :2], size=4)).sum())  # no seam
      0
    """
    from scipy.spatial import cKDTree

    mesh = as_mesh(mesh)
    vertices = np.asarray(mesh.vertices, np.float64)
    if geometry is None:
        geometry = tracer_geometry(vertices, mesh.faces)
    border = border_texels(atlas, geometry)
    f, k = seam_edges(geometry, atlas.uv)
    if not f.size or not border.any():
        return np.zeros(atlas.num_texels, bool)
    faces = np.asarray(mesh.faces)
    a, b = vertices[faces[f, k]], vertices[faces[f, (k + 1) % 3]]
    step = 0.5 * float(atlas.local_size.min())
    count = np.ceil(np.linalg.norm(b - a, axis=1) / step).astype(np.int64) + 1
    s = np.concatenate([np.linspace(0.0, 1.0, c) for c in count])
    edge = np.repeat(np.arange(len(f)), count)
    samples = a[edge] + s[:, None] * (b - a)[edge]
    dist, _ = cKDTree(samples).query(atlas.point[border])
    near = np.zeros(atlas.num_texels, bool)
    near[np.nonzero(border)[0]] = dist <= 2.0 * atlas.local_size[border] + step
    return near


def tap_fidelity(mesh: Mesh | tuple, surface) -> list[dict]:
    """Per pyramid level, where the taps of seam nodes and of inside nodes land, in the node's frame.

    Tap ``t`` of a level-``l`` node should read the node ``(dx_t, dy_t) · 2^l h`` away along its
    frame ``(t, d)``. With ``z`` the displacement from the node's centroid to the read node's
    centroid, in the representative texel's frame and in units of ``2^l h``, each tap has an angle
    error ``|arg(z / (dx + i dy))|`` and a length ``|z| / |dx + i dy|`` (1 is exact). A node is a
    *seam* node when one of its texels is a :func:`seam_texels` texel, else an *inside* node; a
    chart border that builds neighbourhoods as a continuous surface does gives seam nodes the
    inside nodes' errors (the nearest-texel and grouping quantisation every node has).

    Args:
      mesh: the mesh (vertices, faces) of the surface.
      surface: :func:`~jmeshtex.surfacecnn.prepare_surface`'s :class:`~jmeshtex.surfacecnn.Surface`.

    Returns:
      A list with one dict per level, ``{"level": l, "seam": stats, "inside": stats}``, where
      ``stats`` holds ``"nodes"``, ``"angle_deg"`` (median over taps), ``"length"`` (median) and
      ``"self"`` (share of taps that read the node itself); NaN where a class has no tap.

    Example:
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn import prepare_surface
      >>> v, f = grid(2)
      >>> s = prepare_surface(Mesh(v, f, uv=v[f][..., :2]), size=8, levels=1)
      >>> tap_fidelity((v, f), s)[0]["inside"]["length"]
      1.0
    """
    atlas, pyramid = surface.atlas, surface.pyramid
    seam = seam_texels(mesh, atlas)
    dx, dy = np.tile(np.arange(3) - 1, 3), np.repeat(np.arange(3) - 1, 3)
    ideal = (dx + 1j * dy)[[0, 1, 2, 3, 5, 6, 7, 8]]
    out = []
    for level in range(len(pyramid.nearest)):
        of = pyramid.node_of_texel[level]
        rep = pyramid.representative[level]
        G = len(rep)
        count = np.bincount(of, minlength=G)
        centroid = (
            np.stack([np.bincount(of, atlas.point[:, c], minlength=G) for c in range(3)], axis=1)
            / np.maximum(count, 1)[:, None]
        )
        at_seam = np.bincount(of, seam.astype(np.float64), minlength=G) > 0
        taps = [0, 1, 2, 3, 5, 6, 7, 8]
        read = np.asarray(pyramid.nearest[level].index)[:, taps, 0].astype(np.int64)
        live = np.asarray(pyramid.nearest[level].weight)[:, taps, 0] > 0
        frame = atlas.frame[rep]
        disp = centroid[read] - centroid[:, None]
        step = 2.0**level * atlas.texel_size
        z = (
            np.einsum("gtk,gk->gt", disp, frame[:, 0])
            + 1j * np.einsum("gtk,gk->gt", disp, frame[:, 1])
        ) / step
        self_read = read == np.arange(G)[:, None]
        ok = live & ~self_read
        angle = np.degrees(np.abs(np.angle(z / ideal)))
        length = np.abs(z) / np.abs(ideal)
        row = {"level": level}
        for name, sel in (("seam", at_seam), ("inside", ~at_seam)):
            use = ok & sel[:, None]
            row[name] = {
                "nodes": int(sel.sum()),
                "angle_deg": float(np.median(angle[use])) if use.any() else float("nan"),
                "length": float(np.median(length[use])) if use.any() else float("nan"),
                "self": float(self_read[sel].mean()) if sel.any() else float("nan"),
            }
        out.append(row)
    return out

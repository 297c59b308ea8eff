"""The pooling pyramid of a surface CNN: geodesic texel groups and their 3×3 neighbourhoods.

Level 0 holds the valid texels. The nodes of level ``l + 1`` are groups of level-``l`` nodes: nodes
whose centroids fall into the same world-space voxel of side ``2^{l+1} h`` (``h`` the texel size,
voxels anchored at the mesh's bounding-box minimum), split into the connected components of the
level-``l`` adjacency graph restricted to the voxel, so a group never joins two surface sheets that
only pass through the same voxel (Kovács et al. 2024, Sec. 4.3). A node's *representative* is the
member texel nearest to its centroid; its surface point and tangent frame anchor the node's walks.

Two level-``l + 1`` nodes are adjacent when any of their members are. Level-0 adjacency joins a
texel to the texels its nearest taps read (which links charts across UV seams) and to its valid
8-neighbours in the image whose surface points lie within twice the local texel size (where the
texel density is below the median, taps one median texel long may not leave their own texel). The 3×3 neighbourhood of a level-``l + 1`` node walks ``2^{l+1} h``
(√2 times that on diagonals) from its representative, as at level 0, and reads the node containing
the texel nearest the end point. **Overshoot correction**: if that node is neither the centre nor
adjacent to it (the walk jumped over a neighbour, e.g. across a small group), the walk is retraced
at ``backoff`` fractions of its length, longest first, and the first adjacent node reached is used;
if none is, the tap reads the centre node itself. Walks stopped by a mesh boundary read what the
opposite tap reads, else the centre (``boundary="opposite"``), zero (``"zero"``) or the node where
they stopped (``"clamp"``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from jaxtyping import Float, Int
from scipy.sparse.csgraph import connected_components

from .._config import is_int
from .._errors import InputError
from ..geometry import TracerGeometry, tracer_geometry
from ..ops import PoolGroups, TexelNeighborhood
from ._atlas import TextureAtlas
from ._config import BOUNDARY_MODES
from ._neighborhood import TexelTaps, opposite_source, texel_taps, trace_taps, uv_to_texels

#: overshoot back-off: the reference tool samples each coarse walk at 8 points, k/8 of its length, and
#: takes the last one that reaches an adjacent group; the full length is tried first
BACKOFF = (0.875, 0.75, 0.625, 0.5, 0.375, 0.25, 0.125)


class TexelPyramid(NamedTuple):
    """Everything a mesh CNN needs besides the weights (host NumPy arrays).

    Attributes:
      bilinear: level-0 :class:`~jmeshtex.TexelNeighborhood`, ``J = 4`` (first convolution).
      nearest: per level ``0..L`` a ``J = 1`` :class:`~jmeshtex.TexelNeighborhood` over that
        level's nodes.
      pools: per level ``0..L-1`` the :class:`~jmeshtex.PoolGroups` that pool level ``l`` into
        level ``l + 1``.
      node_of_texel: per level ``0..L`` an ``[N]`` int64 array: the level's node of every texel.
      representative: per level an ``[N_l]`` int64 array: the representative texel of every node.
      parent: per level ``0..L-1`` an ``[N_l]`` int32 array: the level-``l + 1`` group of every node
        (the same grouping as ``pools``, for segment pooling of very uneven groups).
      tie: the level-0 taps' colour tie (:class:`~jmeshtex.surfacecnn.core.TexelTaps`), or None.
    """

    bilinear: TexelNeighborhood
    nearest: tuple[TexelNeighborhood, ...]
    pools: tuple[PoolGroups, ...]
    node_of_texel: tuple[Int[np.ndarray, " N"], ...]
    representative: tuple[Int[np.ndarray, " M"], ...]
    parent: tuple[Int[np.ndarray, " M"], ...]
    tie: tuple[Int[np.ndarray, "N K"], Float[np.ndarray, "N K"]] | None = None

    @property
    def levels(self) -> int:
        return len(self.pools)

    def network_arrays(self) -> tuple:
        """The pytree the network consumes: ``(bilinear, nearest, pools, parent)``."""
        return (self.bilinear, self.nearest, self.pools, self.parent)


def _undirected(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Unique undirected edges ``[E, 2]`` (a < b) from endpoint arrays, self-loops dropped."""
    keep = a != b
    lo, hi = np.minimum(a[keep], b[keep]), np.maximum(a[keep], b[keep])
    span = int(max(a.max(initial=0), b.max(initial=0))) + 1
    key = np.sort(lo.astype(np.int64) * span + hi)  # 1-D keys sort far faster than rows
    key = key[np.concatenate([[True], key[1:] != key[:-1]])] if key.size else key
    return np.stack(np.divmod(key, span), axis=1)


def _image_neighbors(atlas: TextureAtlas) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of valid texels that are 8-neighbours in the image and neighbours on the surface
    (world distance at most twice their local texel size, so charts packed side by side stay apart)."""
    size = atlas.size
    row, col = atlas.rows_cols()
    out_a, out_b = [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        r, c = row + dr, col + dc
        inside = (r < size) & (c >= 0) & (c < size)
        j = np.full(len(row), -1)
        j[inside] = atlas.index_of[r[inside] * size + c[inside]]
        i = np.nonzero(j >= 0)[0]
        j = j[i]
        dist = np.linalg.norm(atlas.point[i] - atlas.point[j], axis=1)
        near = dist <= 2.0 * np.maximum(atlas.local_size[i], atlas.local_size[j])
        out_a.append(i[near])
        out_b.append(j[near])
    return np.concatenate(out_a), np.concatenate(out_b)


def _group(labels: np.ndarray, num_groups: int) -> PoolGroups:
    """Pool groups ``[G, S]`` from a group label per node (members in increasing node order)."""
    order = np.argsort(labels, kind="stable")
    counts = np.bincount(labels, minlength=num_groups)
    start = np.cumsum(counts) - counts
    slot = np.arange(len(labels)) - start[labels[order]]
    index = np.zeros((num_groups, int(counts.max())), np.int32)
    mask = np.zeros(index.shape, bool)
    index[labels[order], slot] = order
    mask[labels[order], slot] = True
    return PoolGroups(index=index, mask=mask)


def _first_per_group(
    labels: np.ndarray, key: np.ndarray, values: np.ndarray, num_groups: int
) -> np.ndarray:
    order = np.lexsort((values, key, labels))
    first = np.ones(len(order), bool)
    first[1:] = labels[order][1:] != labels[order][:-1]
    out = np.empty(num_groups, values.dtype)
    out[labels[order][first]] = values[order][first]
    return out


def texel_pyramid(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    atlas: TextureAtlas,
    *,
    levels: int,
    boundary: str = "zero",
    rotation: float | Float[np.ndarray, " N"] = 0.0,
    backoff: tuple[float, ...] = BACKOFF,
    taps: TexelTaps | None = None,
    geometry: TracerGeometry | None = None,
) -> TexelPyramid:
    """Level-0 taps plus ``levels`` coarser levels of geodesic pooling groups and their taps.

    See the module docstring for the grouping, the adjacency and the overshoot correction.

    Args:
      vertices, faces: the mesh.
      atlas: from :func:`~jmeshtex.surfacecnn.core.texture_atlas`.
      levels: number of pooling levels (VGG: 4 or 5).
      boundary: ``"zero"``, ``"opposite"`` or ``"clamp"`` (see :func:`~jmeshtex.surfacecnn.core.texel_taps`).
      rotation: tap-frame rotation per texel (radians, scalar or ``[N]``); coarse nodes use their
        representative's.
      backoff: walk-length fractions tried, in order, when a coarse walk overshoots (default
        ``BACKOFF``: 7/8 … 1/8, the reference tool's 8 sample positions).
      taps: level-0 taps if already computed (:func:`~jmeshtex.surfacecnn.core.texel_taps`).
      geometry: tracer tables.

    Returns:
      :class:`TexelPyramid`.

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn.core import texture_atlas
      >>> v, f = grid(2)
      >>> atlas = texture_atlas(v, f, v[f][..., :2], size=4)
      >>> pyr = texel_pyramid(v, f, atlas, levels=1)
      >>> pyr.pools[0].index.tolist()                 # 2×2 blocks, like 2D pooling
      [[0, 1, 4, 5], [2, 3, 6, 7], [8, 9, 12, 13], [10, 11, 14, 15]]
      >>> pyr.nearest[1].index[0, :, 0].tolist()      # block (0, 0): right, below, diagonal
      [0, 0, 0, 0, 0, 1, 0, 2, 3]
    """
    _check_pyramid_args(levels, boundary, backoff)
    vertices = np.asarray(vertices, dtype=np.float64)
    if geometry is None:
        geometry = tracer_geometry(vertices, faces)
    if taps is None:
        taps = texel_taps(
            vertices, faces, atlas, boundary=boundary, rotation=rotation, geometry=geometry
        )
    N = atlas.num_texels
    rotation = np.broadcast_to(np.asarray(rotation, dtype=np.float64), (N,))
    origin = vertices.min(axis=0)
    h = atlas.texel_size

    edges = _level0_edges(atlas, taps)
    node_of_texel = [np.arange(N)]
    representative = [np.arange(N)]
    nearest = [taps.nearest]
    pools, parent = [], []
    centroid = atlas.point.copy()
    count = np.ones(N)
    for level in range(1, int(levels) + 1):
        num_groups, labels = _voxel_components(centroid, edges, origin, 2.0**level * h)
        pools.append(_group(labels, num_groups))
        parent.append(labels.astype(np.int32))
        centroid, count = _group_centroids(labels, num_groups, centroid, count)
        rep_prev = representative[-1]
        dist = np.linalg.norm(atlas.point[rep_prev] - centroid[labels], axis=1)
        rep = _first_per_group(labels, dist, rep_prev, num_groups)
        of_texel = labels[node_of_texel[-1]]
        edges = _undirected(labels[edges[:, 0]], labels[edges[:, 1]])
        node_of_texel.append(of_texel)
        representative.append(rep)
        nearest.append(
            _coarse_taps(
                vertices,
                faces,
                atlas,
                rep,
                of_texel,
                edges,
                2.0**level * h,
                rotation[rep],
                backoff,
                boundary,
                geometry,
            )
        )
    return TexelPyramid(
        bilinear=taps.bilinear,
        nearest=tuple(nearest),
        pools=tuple(pools),
        node_of_texel=tuple(node_of_texel),
        representative=tuple(representative),
        parent=tuple(parent),
        tie=taps.tie,
    )


def _check_pyramid_args(levels: int, boundary: str, backoff: tuple[float, ...]) -> None:
    """Refuse a bad level count, boundary mode or back-off fraction with a typed error."""
    if not is_int(levels, 0):
        raise InputError(f"texel_pyramid: levels must be an integer >= 0, got {levels!r}")
    if boundary not in BOUNDARY_MODES:
        raise InputError(
            f"texel_pyramid: boundary must be one of {BOUNDARY_MODES}, got {boundary!r}"
        )
    if not all(0.0 < b < 1.0 for b in backoff):
        raise InputError(f"texel_pyramid: backoff fractions must lie in (0, 1), got {backoff!r}")


def _level0_edges(atlas: TextureAtlas, taps: TexelTaps) -> Int[np.ndarray, "E 2"]:
    """Level-0 adjacency (module docstring): each texel to the texels its live nearest taps read,
    plus its image 8-neighbours that are also surface neighbours."""
    reached0 = taps.nearest.index[..., 0].astype(np.int64)
    live = ~taps.stopped
    centre = np.broadcast_to(np.arange(atlas.num_texels)[:, None], reached0.shape)
    a, b = _image_neighbors(atlas)
    return _undirected(np.concatenate([centre[live], a]), np.concatenate([reached0[live], b]))


def _voxel_components(
    centroid: Float[np.ndarray, "N 3"],
    edges: Int[np.ndarray, "E 2"],
    origin: Float[np.ndarray, " 3"],
    side: float,
) -> tuple[int, Int[np.ndarray, " N"]]:
    """The next level's groups: connected components of the adjacency restricted to each voxel of
    side ``side`` (anchored at ``origin``) that the nodes' centroids fall into."""
    n_prev = len(centroid)
    voxel = np.floor((centroid - origin) / side).astype(np.int64)
    voxel -= voxel.min(axis=0)
    dims = voxel.max(axis=0) + 1
    vid = (voxel[:, 0] * dims[1] + voxel[:, 1]) * dims[2] + voxel[:, 2]
    intra = edges[vid[edges[:, 0]] == vid[edges[:, 1]]]
    graph = sp.coo_matrix((np.ones(len(intra)), (intra[:, 0], intra[:, 1])), shape=(n_prev, n_prev))
    num_groups, labels = connected_components(graph, directed=False)
    return num_groups, labels.astype(np.int64)


def _group_centroids(
    labels: Int[np.ndarray, " N"],
    num_groups: int,
    centroid: Float[np.ndarray, "N 3"],
    count: Float[np.ndarray, " N"],
) -> tuple[Float[np.ndarray, "G 3"], Float[np.ndarray, " G"]]:
    """Texel-count-weighted centroids of the groups, and each group's texel count."""
    weight_sum = np.bincount(labels, count, minlength=num_groups)
    sums = [np.bincount(labels, count * centroid[:, k], minlength=num_groups) for k in range(3)]
    return np.stack(sums, axis=1) / weight_sum[:, None], weight_sum


def _coarse_taps(
    vertices, faces, atlas, rep, of_texel, edges, step, rotation, backoff, boundary, geometry
):
    """Nearest taps of one coarse level, with the overshoot correction (module docstring)."""
    G = len(rep)
    keys = np.concatenate([edges[:, 0] * G + edges[:, 1], edges[:, 1] * G + edges[:, 0]])
    keys.sort()

    def adjacent(c, r):
        k = c * G + r
        pos = np.clip(np.searchsorted(keys, k), 0, max(len(keys) - 1, 0))
        return (keys[pos] == k) if len(keys) else np.zeros(k.shape, bool)

    def reach(nodes, fraction):
        end, stopped = trace_taps(
            vertices,
            faces,
            atlas,
            rep[nodes],
            step,
            rotation=rotation[nodes],
            fraction=fraction,
            geometry=geometry,
        )
        _, _, texel = uv_to_texels(atlas, end.reshape(-1, 2), np.repeat(rep[nodes], 8))
        return of_texel[texel].reshape(len(nodes), 8), stopped

    centre = np.arange(G)
    node, stopped = reach(centre, 1.0)
    ok = (node == centre[:, None]) | adjacent(centre[:, None], node) | stopped
    for fraction in backoff:
        bad_rows = np.nonzero(~ok.all(axis=1))[0]
        if not bad_rows.size:
            break
        retry, retry_stopped = reach(bad_rows, fraction)
        fixed = ~ok[bad_rows] & (adjacent(bad_rows[:, None], retry) | retry_stopped)
        sub_node, sub_stopped = node[bad_rows], stopped[bad_rows]
        sub_node[fixed], sub_stopped[fixed] = retry[fixed], retry_stopped[fixed]
        node[bad_rows], stopped[bad_rows] = sub_node, sub_stopped
        ok[bad_rows] |= fixed
    node = np.where(
        ok, node, centre[:, None]
    )  # no adjacent group within reach: replicate the centre
    node = np.concatenate([node[:, :4], centre[:, None], node[:, 4:]], axis=1)
    stopped = np.concatenate([stopped[:, :4], np.zeros((G, 1), bool), stopped[:, 4:]], axis=1)
    if boundary == "opposite":
        node = np.take_along_axis(node, opposite_source(stopped), axis=1)
    off = stopped if boundary == "zero" else np.zeros_like(stopped)
    return TexelNeighborhood(
        index=np.where(off, 0, node).astype(np.int32)[..., None],
        weight=(~off).astype(np.float64)[..., None],
        texel_mask=np.ones(G, bool),
    )

"""Multiresolution mesh hierarchy with intrinsic, gauge-equivariant pooling maps.

Decimation (our own, not ``igl.decimate`` / ``igl.qslim``, whose quadric costs and midpoint
placements are extrinsic and move vertices): rounds of parallel *half-edge collapses* ``u → v`` in
which u disappears and v keeps its position, so every coarse vertex is one of the fine vertices
(``vertex_index``) and fine→coarse transport is well defined. Each round collapses, for a set of
vertices whose collapses do not interact (none changes a vertex of another's star), the shortest
admissible edge of each; rounds repeat until the level has ``ceil(ratio · V)`` vertices.
Admissible means: the link condition (the only common neighbours of u and v are the vertices
opposite the edge), boundary vertices only slide along boundary edges, no vertex drops below degree
3 (2 on the boundary) or rises above 12, and the new triangles are well shaped (every intrinsic
angle and the angle at v in u's flattened star above ~1°). Half-edge collapses under these rules
keep the surface a manifold with the same genus, boundary loops and components, for open meshes
and any genus.

Everything is intrinsic: every edge of every level carries ``log^0_a(b)`` and ``ρ^0_{b→a}`` in the
*input* mesh's vertex frames, composed along input-mesh edge paths (a collapse ``u → v`` gives the
new edge (v, w) the composition ``log_v(w) = log_v(u) + ρ_{u→v} log_u(w)``). Coarse edge lengths
are ``|log^0|``; costs, admissibility, Voronoi regions and frames use only these, and ties are
broken on lengths rounded to a dyadic grid, so a folded sheet gives the same hierarchy to rounding.

Pooling maps (level ℓ → ℓ+1): each level-ℓ vertex's parent is the nearest coarse vertex by edge
path within level ℓ (multi-source Dijkstra); the child→parent transport is

.. math::
    \\tau_c = \\overline{a^{\\ell+1}_P}\\; \\rho^0_{c\\to P}\\; a^{\\ell}_c

with ``ρ^0_{c→P}`` composed along that shortest path (input frames) and ``a^ℓ_v = e^{iα^ℓ_v}`` the
fixed alignment of v's level-ℓ frame with its input frame: the rotation that best matches the
directions of v's level-ℓ one-ring neighbours in the level-ℓ intrinsic log map to the same
directions measured in the input frame (least squares on the circle, ``α = arg Σ_j û^0_j
\\overline{û^ℓ_j}``). Each factor maps one frame to another, so pooling is exactly gauge-equivariant:
rotating any frame by β at either level changes ``τ`` by the matching ``e^{∓iβ}`` (tested by
relabelling vertices, which moves every gauge).

The frames the pooling maps land in are those of ``neighborhoods[ℓ]`` (one-ring log maps built from
the intrinsic coarse lengths). A coarse level's ``one_ring_neighborhood(vertices[ℓ], faces[ℓ])``
measures chords in 3D instead: same gauge reference edge, angles that differ by O(h²).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from .._config import is_finite_number, is_int
from .._errors import ConfigError, DecimationError, InputError
from .._mesh import accepts_mesh
from .._neighborhoods import PoolingMap, VertexNeighborhood
from .._types import Float, Int
from ._adjacency import one_rings
from ._intrinsic import check_mesh, edge_lengths
from ._knn import _quantization_step, _quantized_lengths
from ._log_map import _neighborhood_from_lengths

_MIN_ANGLE = 0.02  # radians: smallest angle allowed in a triangle created by a collapse
_MAX_DEGREE = 12  # largest vertex degree a collapse may create (unless the level already has more)
_CANDIDATES = 4  # shortest edges tried per vertex and round


class MeshHierarchy(NamedTuple):
    """Levels of a mesh from fine (level 0, the input) to coarse, with pooling maps between them.

    Attributes:
      vertices: per level ``[V_ℓ, 3]`` positions; rows of the input (coarse vertices are a subset).
      faces: per level ``[F_ℓ, 3]`` int64 triangles into that level's vertices.
      vertex_index: per level ``[V_ℓ]`` index of each vertex in the input mesh (level 0: arange).
      lengths: per level ``[F_ℓ, 3]`` intrinsic edge lengths (edge k of face f runs from corner k
        to corner k+1): input lengths at level 0, composed geodesic-path lengths above.
      neighborhoods: per level the intrinsic one-ring :class:`~jmeshtex.VertexNeighborhood` whose frames the
        pooling maps use.
      to_input_frame: per level ``[V_ℓ]`` unit complex ``a^ℓ``: a tangent vector x in a vertex's
        level-ℓ frame is ``a^ℓ x`` in the same vertex's input (level-0) frame (1 at level 0).
      pooling: ``levels - 1`` :class:`~jmeshtex.PoolingMap` from level ℓ (fine) to ℓ+1 (coarse). Children
        are sorted by path distance (the parent's own fine copy first); ``children_weight`` are
        intrinsic vertex areas normalised to sum to 1 per parent, so a weighted sum averages.
    """

    vertices: tuple[np.ndarray, ...]
    faces: tuple[np.ndarray, ...]
    vertex_index: tuple[np.ndarray, ...]
    lengths: tuple[np.ndarray, ...]
    neighborhoods: tuple[VertexNeighborhood, ...]
    to_input_frame: tuple[np.ndarray, ...]
    pooling: tuple[PoolingMap, ...]

    @property
    def num_levels(self) -> int:
        return len(self.faces)


class _Level(NamedTuple):
    """Working state of one level: compact ids, directed edge table in input frames."""

    faces: np.ndarray  # [F, 3] int64, compact ids
    index: np.ndarray  # [n] input ids
    keys: np.ndarray  # [E] sorted a * n + b of directed edges
    log: np.ndarray  # [E] log^0_a(b) in a's input frame
    tr: np.ndarray  # [E] rho^0_{b->a}


def _finest_level(v: np.ndarray, f: np.ndarray):
    """The input mesh as the first level: ``(level, edge lengths, one-ring neighbourhoods,
    quantisation step of the lengths)``."""
    n0 = len(v)
    lengths = edge_lengths(v, f)
    nb = _neighborhood_from_lengths(f, lengths, n0)
    src, slot = np.nonzero(nb.mask)
    keys = src * n0 + nb.index[src, slot].astype(np.int64)
    order = np.argsort(keys)
    level = _Level(
        f, np.arange(n0), keys[order], nb.log[src, slot][order], nb.transport[src, slot][order]
    )
    return level, lengths, nb, _quantization_step(lengths)


@accepts_mesh
def mesh_hierarchy(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    *,
    levels: int | None = None,
    min_vertices: int = 128,
    ratio: float = 0.5,
) -> MeshHierarchy:
    """Multiresolution hierarchy by intrinsic half-edge collapses, with tangent pooling maps.

    .. math::
        \\tau_c = \\overline{a^{\\ell+1}_P}\\,\\rho^0_{c\\to P}\\,a^{\\ell}_c,\\qquad
        \\text{pool}(x)_P = \\sum_{c \\in \\text{children}(P)} w_c\\, \\tau_c\\, x_c

    (tangent pooling of field-convolution U-Nets, Mitchel et al. 2021 §5; MeshMatch's
    coarse-to-fine pyramid, Chen et al. 2012 §4). See the module docstring for the decimation rules
    and the frame alignment ``a``.

    Args:
      vertices: ``[V, 3]`` positions (only edge lengths are used; coarse positions are copied).
      faces: ``[F, 3]`` consistently oriented manifold triangles, open or closed, any genus; every
        vertex must belong to a face.
      levels: total number of levels including the input (≥ 1). ``None``: keep halving while the
        next level would still have at least ``min_vertices`` vertices.
      min_vertices: smallest coarse level when ``levels`` is None (≥ 4).
      ratio: target ``V_{ℓ+1} / V_ℓ`` in (0, 1); a level that cannot get below halfway between
        ``V_ℓ`` and the target is an error (explicit ``levels``) or ends the hierarchy.

    Returns:
      :class:`MeshHierarchy`.

    Raises:
      DecimationError: the mesh is too small for one coarse level (``levels`` None) or for the
        requested number of levels.
      InputError: bad arguments, unreferenced vertices (ConfigError for bad settings); MeshError subclasses for
        malformed meshes.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import icosphere
      >>> h = mesh_hierarchy(*icosphere(2), levels=3)
      >>> [len(v) for v in h.vertices]
      [162, 81, 41]
      >>> pm = h.pooling[0]
      >>> bool(np.allclose(np.abs(pm.to_parent), 1)), bool(np.allclose(pm.children_weight.sum(1), 1))
      (True, True)
    """
    if not (is_finite_number(ratio) and 0.0 < ratio < 1.0):
        raise ConfigError(f"ratio must be in (0, 1), got {ratio!r}")
    if not is_int(min_vertices, 4):
        raise ConfigError(f"min_vertices must be an integer >= 4, got {min_vertices!r}")
    if levels is not None and (not is_int(levels, 1)):
        raise ConfigError(
            f"levels must be None or an integer >= 1 (the input counts as one), got {levels!r}"
        )
    v, f = check_mesh(vertices, faces)
    n0 = len(v)
    used = np.zeros(n0, bool)
    used[f.ravel()] = True
    if not used.all():
        raise InputError(
            f"{int((~used).sum())} vertices belong to no face (first: {np.nonzero(~used)[0][:5].tolist()}); "
            "remove unreferenced vertices first (jmeshtex.io loaders do)"
        )

    level, lengths0, nb0, step = _finest_level(v, f)

    out_levels = [level]
    out_lengths = [lengths0]
    out_nb = [nb0]
    out_align = [np.ones(n0, np.complex128)]
    pooling = []
    stalled = ""
    while levels is None or len(out_levels) < levels:
        n = len(level.index)
        target = math.ceil(ratio * n)
        if levels is None and target < min_vertices:
            break
        coarse, kept = _decimate(level, target, step)
        reached = len(coarse.index)
        if reached > n - (n - target) / 2 or reached < 4:
            stalled = (
                f"level {len(out_levels)} got only from {n} to {reached} vertices, not near the "
                f"target {target} (ratio {ratio}): no admissible collapse is left"
            )
            if levels is None:
                break
            raise DecimationError(f"{stalled}; the mesh cannot be decimated to {levels} levels")
        lengths = _face_lengths(coarse)
        nb = _neighborhood_from_lengths(coarse.faces, lengths, reached)
        align = _frame_alignment(coarse, nb)
        pooling.append(_pooling_map(level, out_nb[-1], out_align[-1], kept, align, step))
        level = coarse
        out_levels.append(coarse)
        out_lengths.append(lengths)
        out_nb.append(nb)
        out_align.append(align)

    if len(out_levels) == 1 and levels is None:
        raise DecimationError(
            f"the mesh is too small to decimate: {stalled}"
            if stalled
            else f"the mesh is too small to decimate: {n0} vertices, and one level at ratio {ratio} "
            f"would have {math.ceil(ratio * n0)} < min_vertices={min_vertices}"
        )
    return MeshHierarchy(
        vertices=tuple(v[lv.index] for lv in out_levels),
        faces=tuple(lv.faces for lv in out_levels),
        vertex_index=tuple(lv.index for lv in out_levels),
        lengths=tuple(out_lengths),
        neighborhoods=tuple(out_nb),
        to_input_frame=tuple(out_align),
        pooling=tuple(pooling),
    )


# ---------------------------------------------------------------------------------------------
# edge table helpers


def _find(keys: np.ndarray, query: np.ndarray) -> np.ndarray:
    """Position of each query key in the sorted ``keys``, or -1."""
    pos = np.minimum(np.searchsorted(keys, query), max(len(keys) - 1, 0))
    return np.where(keys[pos] == query, pos, -1)


def _face_lengths(level: _Level) -> np.ndarray:
    f = level.faces
    n = len(level.index)
    pos = _find(level.keys, (f * n + np.roll(f, -1, axis=1)).ravel())
    return np.abs(level.log[pos]).reshape(f.shape)


# ---------------------------------------------------------------------------------------------
# decimation


def _decimate(
    level: _Level, target: int, step: float, shortest_first: bool = False
) -> tuple[_Level, np.ndarray]:
    """Collapse rounds until ``target`` vertices remain (or no admissible collapse is left).

    A round collapses an independent set of admissible edges, ranked shortest first; with
    ``shortest_first`` only those within one half-octave band of the round's shortest, so that the
    decimation evens edge lengths out (an isotropic remesh of a graded mesh) instead of thinning
    every region alike (a hierarchy that keeps the input's grading)."""
    n = len(level.index)
    faces, keys, log, tr = level.faces, level.keys, level.log, level.tr
    alive = np.ones(n, bool)
    max_degree = None
    while alive.sum() > target:
        rings = one_rings(faces, n)
        if max_degree is None:
            max_degree = max(_MAX_DEGREE, int(rings.degree.max()))
        u, w = _select_collapses(
            rings, n, keys, log, step, int(alive.sum()) - target, max_degree, shortest_first
        )
        if len(u) == 0:
            break
        faces, keys, log, tr = _collapse(rings, n, faces, keys, log, tr, u, w)
        alive[u] = False

    kept = np.nonzero(alive)[0]
    new_id = np.full(n, -1, np.int64)
    new_id[kept] = np.arange(len(kept))
    a, b = keys // n, keys % n
    m = len(kept)
    new_keys = new_id[a] * m + new_id[b]
    order = np.argsort(new_keys)
    coarse = _Level(new_id[faces], level.index[kept], new_keys[order], log[order], tr[order])
    return coarse, kept


def _hash(x: np.ndarray) -> np.ndarray:
    """A fixed pseudo-random permutation of int64 values (splitmix64 finaliser), as int64."""
    z = x.astype(np.uint64) + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(1)).astype(np.int64)


def _select_collapses(rings, n, keys, log, step, need, max_degree, shortest_first=False):
    """Admissible collapses ``u → w`` that can be applied together (see :func:`_compatible_set`)."""
    deg, bnd = rings.degree.astype(np.int64), rings.boundary
    u = np.nonzero(deg > 0)[0]  # vertices still in the mesh; rows below are local to u
    ring, mask, wedge_mask = rings.ring[u].astype(np.int64), rings.mask[u], rings.wedge_mask[u]
    deg_u, bnd_u = deg[u][:, None], bnd[u][:, None]
    m, K = ring.shape
    rows = np.arange(m)[:, None]
    slot_log = np.where(mask, log[_find(keys, np.where(mask, u[:, None] * n + ring, -1))], 0.0)
    slot_q = np.where(mask, _quantized_lengths(np.abs(slot_log), step), np.iinfo(np.int64).max)
    j = np.lexsort((np.where(mask, ring, n), slot_q), axis=1)[:, : min(_CANDIDATES, K)]
    ok = mask[rows, j]
    w = ring[rows, j]
    # boundary vertices slide along boundary edges only (the first and last slot of their fan)
    ok &= ~bnd_u | (bnd[w] & ((j == 0) | (j == deg_u - 1)))
    # the vertices opposite the edge: previous and next slot (cyclic inside, clipped on the boundary)
    prev_j = np.where(bnd_u, j - 1, (j - 1) % deg_u)
    next_j = np.where(bnd_u, j + 1, (j + 1) % deg_u)
    has_prev, has_next = prev_j >= 0, next_j < deg_u
    opp_prev = ring[rows, np.clip(prev_j, 0, K - 1)]
    opp_next = ring[rows, np.clip(next_j, 0, K - 1)]
    n_opp = has_prev.astype(np.int64) + has_next
    # link condition: u and w share exactly the opposite vertices
    adj = sp.csr_matrix(
        (np.ones(int(mask.sum())), (u[np.nonzero(mask)[0]], ring[mask])), shape=(n, n)
    )
    common = (adj @ adj)[np.broadcast_to(u[:, None], w.shape).ravel(), w.ravel()]
    ok &= np.asarray(common).reshape(w.shape) == n_opp
    # degrees stay >= 3 (>= 2 on the boundary) and <= max_degree
    min_deg = np.where(bnd, 3, 4)
    ok &= ~has_prev | (deg[opp_prev] >= min_deg[opp_prev])
    ok &= ~has_next | (deg[opp_next] >= min_deg[opp_next])
    new_deg = deg_u + deg[w] - 2 - n_opp
    ok &= (new_deg >= np.where(bnd[w], 2, 3)) & (new_deg <= max_degree)

    # shape of the triangles (w, r_i, r_i+1) replacing u's wedges not incident to w; checked for
    # the first combinatorially admissible candidate of each vertex, then the next, ...
    i = np.arange(K)[None, :]
    nxt = np.clip(np.where(bnd_u, i + 1, (i + 1) % deg_u), 0, K - 1)
    len_ab = np.abs(log[_find(keys, np.where(wedge_mask, ring * n + ring[rows, nxt], -1))])
    slot_next = np.take_along_axis(slot_log, nxt, axis=1)
    decided = np.zeros(m, bool)
    for c in range(j.shape[1]):
        todo = np.nonzero(ok[:, c] & ~decided)[0]
        jc = j[todo, c][:, None]
        pw = slot_log[todo, jc[:, 0]][:, None]
        live = wedge_mask[todo] & (i != jc) & (nxt[todo] != jc)
        good = _well_shaped(slot_log[todo] - pw, slot_next[todo] - pw, len_ab[todo])
        fine = np.all(~live | good, axis=1)
        ok[todo[~fine], c] = False
        decided[todo[fine]] = True
    ok &= decided[:, None]

    # the shortest admissible edge of each vertex. Priority: half-octave band of its length, then
    # pseudo-random within the band (few Luby sweeps); the two ends of one edge tie on length and
    # are told apart by their star's total edge length, so the order (and the hierarchy) does not
    # depend on vertex labels; labels only break ties left on perfectly regular meshes.
    has = np.nonzero(ok.any(axis=1))[0]
    if has.size == 0:
        return has, has
    pick = np.argmax(ok[has], axis=1)
    cost = slot_q[has, j[has, pick]]
    band = np.floor(2.0 * np.log2(cost.astype(np.float64))).astype(np.int64)
    if shortest_first:  # only the shortest edges of this round: lengths even out
        short = band <= band.min() + 1
        has, pick, cost, band = has[short], pick[short], cost[short], band[short]
    star = np.where(mask[has], slot_q[has], 0).sum(axis=1)
    rank = np.empty(len(has), np.int64)
    rank[np.lexsort((_hash(u[has]), star, _hash(cost), band))] = np.arange(len(has))

    # a collapse changes u, w and the opposite vertices ("touched") and reads u's star ("read")
    touched = np.stack([u[has], w[has, pick], opp_prev[has, pick], opp_next[has, pick]], axis=1)
    touched_mask = np.stack([has >= 0, has >= 0, has_prev[has, pick], has_next[has, pick]], axis=1)
    read = np.concatenate([u[has][:, None], ring[has]], axis=1)
    read_mask = np.concatenate([np.ones((len(has), 1), bool), mask[has]], axis=1)
    chosen = _compatible_set(rank, touched, touched_mask, read, read_mask, n)
    chosen = chosen[np.argsort(rank[chosen])][:need]
    return u[has[chosen]], w[has[chosen], pick[chosen]]


def _well_shaped(pa: np.ndarray, pb: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Triangle (0, pa, pb) turns left at 0 and, with side lengths |pa|, |pb|, c, has all angles > min."""
    a, b = np.abs(pa), np.abs(pb)
    cos_min = np.cos(_MIN_ANGLE)
    with np.errstate(divide="ignore", invalid="ignore"):
        turn = np.angle(pb * np.conj(pa))
        cos_w = (a * a + b * b - c * c) / (2 * a * b)
        cos_a = (a * a + c * c - b * b) / (2 * a * c)
        cos_b = (b * b + c * c - a * a) / (2 * b * c)
    return (
        (a > 0)
        & (b > 0)
        & (c > 0)
        & (turn > _MIN_ANGLE)
        & (cos_w < cos_min)
        & (cos_a < cos_min)
        & (cos_b < cos_min)
    )


def _compatible_set(rank, touched, touched_mask, read, read_mask, n) -> np.ndarray:
    """Candidates that can collapse together, greedily by rank in Luby-style sweeps.

    Candidate c changes the vertices ``touched[c]`` (u, w, the opposite vertices) and reads the
    star ``read[c]`` (u and its ring). Two collapses conflict when one touches a vertex the other
    reads; otherwise their link conditions, degree counts, composed edges and new triangles do not
    interact. A sweep keeps every candidate whose rank is the smallest among those it conflicts
    with, then drops their conflicts. Returns candidate indices.
    """
    big = np.iinfo(np.int64).max
    alive = np.ones(len(rank), bool)
    chosen = np.zeros(len(rank), bool)
    while alive.any():
        tm = touched_mask & alive[:, None]
        rm = read_mask & alive[:, None]
        min_touch = np.full(n, big)
        min_read = np.full(n, big)
        np.minimum.at(min_touch, touched[tm], np.broadcast_to(rank[:, None], touched.shape)[tm])
        np.minimum.at(min_read, read[rm], np.broadcast_to(rank[:, None], read.shape)[rm])
        first = np.where(rm, min_touch[read], big).min(axis=1)
        second = np.where(tm, min_read[touched], big).min(axis=1)
        sel = alive & (rank == first) & (rank == second)
        chosen |= sel
        hit_touch = np.zeros(n, bool)
        hit_read = np.zeros(n, bool)
        hit_touch[touched[touched_mask & sel[:, None]]] = True
        hit_read[read[read_mask & sel[:, None]]] = True
        blocked = np.any(rm & hit_touch[read], axis=1) | np.any(tm & hit_read[touched], axis=1)
        alive &= ~blocked & ~sel
    return np.nonzero(chosen)[0]


def _collapse(rings, n, faces, keys, log, tr, u, w):
    """Apply the independent collapses ``u → w``: faces, and the edge table with composed maps."""
    to = np.arange(n)
    to[u] = w
    f = to[faces]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]

    # new edges (w, r) for ring vertices r of u not yet adjacent to w
    ring, mask = rings.ring[u].astype(np.int64), rings.mask[u]
    uu = np.broadcast_to(u[:, None], ring.shape)[mask]
    ww = np.broadcast_to(w[:, None], ring.shape)[mask]
    rr = ring[mask]
    fresh = (rr != ww) & (_find(keys, ww * n + rr) < 0)
    uu, ww, rr = uu[fresh], ww[fresh], rr[fresh]
    e_wu = _find(keys, ww * n + uu)
    e_uw = _find(keys, uu * n + ww)
    e_ur = _find(keys, uu * n + rr)
    e_ru = _find(keys, rr * n + uu)
    # log_w(r) = log_w(u) + rho_{u->w} log_u(r);  rho_{r->w} = rho_{u->w} rho_{r->u}
    log_wr = log[e_wu] + tr[e_wu] * log[e_ur]
    tr_wr = tr[e_wu] * tr[e_ur]
    log_rw = log[e_ru] + tr[e_ru] * log[e_uw]
    tr_rw = tr[e_ru] * tr[e_uw]

    gone = np.zeros(n, bool)
    gone[u] = True
    stay = ~gone[keys // n] & ~gone[keys % n]
    keys = np.concatenate([keys[stay], ww * n + rr, rr * n + ww])
    log = np.concatenate([log[stay], log_wr, log_rw])
    tr = np.concatenate([tr[stay], tr_wr, tr_rw])
    order = np.argsort(keys)
    return f, keys[order], log[order], tr[order]


# ---------------------------------------------------------------------------------------------
# frames and pooling


def _frame_alignment(level: _Level, nb: VertexNeighborhood) -> np.ndarray:
    """``[n]`` unit complex rotating each vertex's level frame onto its input frame (least squares)."""
    n = len(level.index)
    rows = np.arange(n)[:, None]
    pos = _find(level.keys, np.where(nb.mask, rows * n + nb.index, -1))
    fine = np.where(nb.mask, level.log[pos], 0.0)
    coarse = nb.log
    s = np.sum(_unit(fine) * np.conj(_unit(coarse)), axis=1)
    return np.where(np.abs(s) > 0, _unit(s), 1.0)


def _unit(z: np.ndarray) -> np.ndarray:
    r = np.abs(z)
    return np.where(r > 0, z / np.where(r > 0, r, 1.0), 0.0)


def _pooling_map(fine: _Level, fine_nb, fine_align, kept, coarse_align, step) -> PoolingMap:
    """Voronoi parents by edge path in the fine level, transport composed along the path."""
    n = len(fine.index)
    a, b = fine.keys // n, fine.keys % n
    weight = _quantized_lengths(np.abs(fine.log), step).astype(np.float64)  # exact path sums, > 0
    graph = sp.csr_matrix((weight, (a, b)), shape=(n, n))
    dist, pred, source = dijkstra(
        graph, directed=True, indices=kept, min_only=True, return_predecessors=True
    )
    is_root = pred < 0
    anc = np.where(is_root, np.arange(n), pred)
    # transport from each vertex's input frame to its predecessor's: stored at edge (pred, c)
    t = np.where(is_root, 1.0 + 0j, fine.tr[_find(fine.keys, anc * n + np.arange(n))])
    while np.any(anc != anc[anc]):
        t = t[anc] * t
        anc = anc[anc]
    coarse_id = np.full(n, -1, np.int64)
    coarse_id[kept] = np.arange(len(kept))
    parent = coarse_id[source]
    to_parent = np.conj(coarse_align[parent]) * t * fine_align

    m = len(kept)
    order = np.lexsort((np.arange(n), dist, parent))
    counts = np.bincount(parent, minlength=m)
    M = int(counts.max())
    rank = np.arange(n) - np.repeat(np.cumsum(counts) - counts, counts)
    p_sorted = parent[order]
    children = np.zeros((m, M), np.int32)
    children_mask = np.zeros((m, M), bool)
    children_weight = np.zeros((m, M))
    children_transport = np.ones((m, M), np.complex128)
    children[p_sorted, rank] = order
    children_mask[p_sorted, rank] = True
    area = fine_nb.area[order]
    total = np.bincount(p_sorted, weights=area, minlength=m)
    children_weight[p_sorted, rank] = area / total[p_sorted]
    children_transport[p_sorted, rank] = to_parent[order]
    return PoolingMap(
        parent=parent.astype(np.int32),
        to_parent=to_parent,
        children=children,
        children_mask=children_mask,
        children_weight=children_weight,
        children_transport=children_transport,
    )

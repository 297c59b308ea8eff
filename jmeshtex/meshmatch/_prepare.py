"""Host-side preparation of MeshMatch: each mesh's hierarchy and per-level tables, the per-level
arrays the jitted PatchMatch step reads, and their padding into shared shapes.

Everything here runs once per transfer on the host (NumPy): :func:`prepare_side` builds a mesh's
hierarchy, one-rings, smoothers, tracer tables and shape features; :func:`level_arrays` traces one
level's fans and packs the :class:`LevelArrays`; :func:`level_groups` and :func:`pad_level_arrays`
pad levels into groups that share one compiled step (the padded-neighbourhood contract: padding
changes no real vertex).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, connected_components

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from ..geometry import (
    MeshHierarchy,
    edge_lengths,
    face_areas,
    mean_edge_length,
    mesh_hierarchy,
    one_ring_neighborhood,
    tracer_geometry,
)
from ._config import Config
from ._fans import geodesic_fans, smoother
from ._features import ancestors, correspondence_affinities, hks_features, hks_level, shape_features


@dataclasses.dataclass
class Side:
    """One mesh prepared for MeshMatch: its hierarchy and per-level host geometry.

    Attributes:
      hierarchy: :class:`~jmeshtex.geometry.MeshHierarchy`.
      edge: per level mean edge length.
      neighborhoods: per level one-ring :class:`~jmeshtex.VertexNeighborhood` of the level mesh
        (the tracer's frames).
      smoothers: per level :class:`~jmeshtex.meshmatch.core.Smoother`.
      tracers: per level :class:`~jmeshtex.geometry.TracerGeometry`.
      log_hks: ``[V_0, T]`` log heat kernel signature.
      features: ``[V_0, D]`` standardised shape features (plus affinities when given).
      inverse: per level ``[V_0]`` position of each input vertex in that level (-1 if absent).
      hks_times: ``[T]`` the HKS times used (pass them to the other mesh's :func:`prepare_side`).
    """

    hierarchy: MeshHierarchy
    edge: list
    neighborhoods: list
    smoothers: list
    tracers: list
    log_hks: np.ndarray
    features: np.ndarray
    inverse: list
    hks_times: np.ndarray

    @property
    def num_levels(self) -> int:
        return self.hierarchy.num_levels


def _level_tables(vertices, faces, level: int):
    """One level's one-rings and tracer tables, from its positions' edge lengths, mollified where
    a coarse level's positions make a face flat.

    A coarse level's positions are copies of its kept vertices, so a collapse can leave a face with
    (near) zero area in space, and the hierarchy's composed intrinsic lengths can be flat there too
    (``docs/design_notes.md``, MeshMatch). Then every edge of the level is lengthened by the same ``ε``, the
    smallest that gives every face a triangle-inequality slack of ``δ = 10⁻⁴`` mean edge lengths
    (intrinsic mollification, Sharp & Crane 2020, "A Laplacian for nonmanifold triangle meshes"
    §4.5): shared edges keep one length, and the layouts change by about ``δ``. Level 0 is the
    input, whose degenerate faces :func:`~jmeshtex.geometry.mesh_hierarchy` already refuses."""
    lengths = edge_lengths(vertices, faces)
    mean = float(np.mean(lengths))
    if level == 0 or (face_areas(lengths) > 1e-12 * mean**2).all():
        return one_ring_neighborhood(vertices, faces, scale=None), tracer_geometry(vertices, faces)
    lengths = mollified_lengths(lengths, 1e-4 * mean)
    return (
        one_ring_neighborhood(vertices, faces, lengths=lengths, scale=None),
        tracer_geometry(vertices, faces, lengths=lengths),
    )


def mollified_lengths(lengths, delta: float):
    """``lengths + ε`` with the smallest ``ε ≥ 0`` that gives every face a triangle-inequality
    slack ``l_j + l_k - l_i ≥ delta`` (intrinsic mollification; adding ε to every edge raises each
    slack by ε).

    Example:
      >>> import numpy as np
      >>> mollified_lengths(np.array([[1.0, 1.0, 2.0]]), 0.01).round(6).tolist()
      [[1.01, 1.01, 2.01]]
    """
    lengths = np.asarray(lengths, np.float64)
    slack = lengths.sum(axis=1, keepdims=True) - 2.0 * lengths
    return lengths + max(0.0, float(delta) - float(slack.min()))


def prepare_side(
    mesh: Mesh | tuple,
    config: Config,
    *,
    hks_times=None,
    hierarchy: MeshHierarchy | None = None,
) -> Side:
    """Hierarchy, per-level one-rings / tracer tables / smoothers and the log HKS of one mesh.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])``.
      config: :class:`~jmeshtex.meshmatch.Config`.
      hks_times: shared HKS times (default: from this mesh's spectrum).
      hierarchy: reuse a hierarchy.

    Returns:
      :class:`Side` (shape features still without affinities).

    Example:
      >>> from jmeshtex.data import icosphere
      >>> side = prepare_side(icosphere(3), Config(min_vertices=100))
      >>> side.num_levels, side.features.shape      # 8 HKS times, the normal, the positions
      (3, (642, 14))
    """
    mesh = as_mesh(mesh)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if hierarchy is None:
        if config.levels == 1:
            hierarchy = mesh_hierarchy(vertices, faces, levels=1)
        else:
            hierarchy = mesh_hierarchy(
                vertices, faces, levels=config.levels, min_vertices=config.min_vertices
            )
    edge, nbs, sms, trs, inverse = [], [], [], [], []
    n0 = len(vertices)
    for level in range(hierarchy.num_levels):
        v, f = hierarchy.vertices[level], hierarchy.faces[level]
        edge.append(mean_edge_length(v, f))
        nb, tr = _level_tables(v, f, level)
        nbs.append(nb)
        sms.append(smoother(f, len(v)))
        trs.append(tr)
        inv = np.full(n0, -1, np.int64)
        inv[hierarchy.vertex_index[level]] = np.arange(len(v))
        inverse.append(inv)
    level = hks_level(hierarchy, config.experimental.hks_max_vertices)
    log_hks, times = hks_features(
        hierarchy, level=level, times=hks_times, num_times=config.hks_times, k=config.hks_eigenpairs
    )
    features = shape_features((vertices, faces), log_hks, **config.normal_axes())
    return Side(hierarchy, edge, nbs, sms, trs, log_hks, features, inverse, times)


def side_affinities(source: Side, target: Side, pairs):
    """:func:`~jmeshtex.meshmatch.core.correspondence_affinities` of the finest levels of prepared sides."""
    hs, ht = source.hierarchy, target.hierarchy
    return correspondence_affinities(
        (hs.vertices[0], hs.faces[0]), (ht.vertices[0], ht.faces[0]), pairs
    )


class LevelArrays(NamedTuple):
    """Arrays of one side at one level, as the jitted PatchMatch step reads them.

    Attributes:
      nb_index: ``[V, K]`` int32 one-ring neighbours (padded slots: 0).
      nb_mask: ``[V, K]`` bool, real slots.
      nb_log: ``[V, K]`` complex log map of each neighbour in the vertex's frame.
      nb_transport: ``[V, K]`` complex transport from the neighbour's frame to the vertex's.
      fan_corners: ``[V, R, A, 3]`` int32 corners of the face of each fan sample.
      fan_bary: ``[V, R, A, 3]`` barycentric coordinates of each fan sample.
      sm_index: ``[V, Ks]`` int32 smoother neighbours.
      sm_weight: ``[V, Ks]`` smoother weights (rows sum to 1).
      features: ``[V, D]`` shape features.
      colors: ``[V, C]`` the level's colours (source; zeros on the target).
      valid: ``[V]`` bool: the source vertices a match may use; False on padding.
    """

    nb_index: jax.Array
    nb_mask: jax.Array
    nb_log: jax.Array
    nb_transport: jax.Array
    fan_corners: jax.Array
    fan_bary: jax.Array
    sm_index: jax.Array
    sm_weight: jax.Array
    features: jax.Array
    colors: jax.Array
    valid: jax.Array


def level_arrays(side: Side, level: int, radii, config: Config, colors, valid, features, dtype):
    """Host (NumPy) :class:`LevelArrays` of one side at one level, and the fans' pre-filter steps."""
    h = side.hierarchy
    v, f = h.vertices[level], h.faces[level]
    # angle 0 half a step off the frame's x-axis (the edge to ring slot 0): no sample geodesic of a
    # regular mesh then runs along an edge through vertices (an ambiguous straightest geodesic)
    reference = np.full(len(v), np.exp(1j * np.pi / config.num_angles))
    fans = geodesic_fans(
        (v, f),
        radii=radii,
        num_angles=config.num_angles,
        edge=side.edge[level],
        reference=reference,
        geometry=side.tracers[level],
    )
    nb, sm = side.neighborhoods[level], side.smoothers[level]
    real = np.dtype(dtype)
    cdt = np.complex64 if real == np.float32 else np.complex128
    arr = LevelArrays(
        nb_index=np.asarray(nb.index, np.int32),
        nb_mask=np.asarray(nb.mask, bool),
        nb_log=np.asarray(nb.log, cdt),
        nb_transport=np.asarray(nb.transport, cdt),
        fan_corners=np.asarray(fans.corners, np.int32),
        fan_bary=np.asarray(fans.bary, real),
        sm_index=np.asarray(sm.index, np.int32),
        sm_weight=np.asarray(sm.weight, real),
        features=np.asarray(features[h.vertex_index[level]], real),
        colors=np.asarray(colors, real),
        valid=np.asarray(valid, bool),
    )
    return arr, tuple(int(s) for s in fans.steps)


def pad_axis(x: np.ndarray, axis: int, size: int, fill=0) -> np.ndarray:
    """``x`` padded with ``fill`` along ``axis`` to ``size`` (unchanged when already that long)."""
    extra = size - x.shape[axis]
    if extra < 0:
        raise InputError(
            f"pad_axis: cannot pad axis {axis} of shape {x.shape} down to {size}; pass a size of "
            f"at least {x.shape[axis]}"
        )
    if extra == 0:
        return x
    shape = list(x.shape)
    shape[axis] = extra
    return np.concatenate([x, np.full(shape, fill, x.dtype)], axis=axis)


def pad_level_arrays(
    arr: LevelArrays, *, num_vertices: int, ring: int, smooth_ring: int
) -> LevelArrays:
    """Pad one side's :class:`LevelArrays` to ``num_vertices`` rows and ``ring`` / ``smooth_ring``
    neighbour slots (padded-neighbourhood contract: index 0, mask False, weight 0, transport 1;
    padded vertices are not ``valid`` and no real vertex refers to them).

    Levels padded to one shape share one compiled PatchMatch step; padding changes no real
    vertex's result (tested).

    Args:
      arr: host :class:`LevelArrays` with ``V`` rows, ``K`` ring and ``Ks`` smoother slots.
      num_vertices: rows after padding (``>= V``).
      ring: one-ring slots after padding (``>= K``).
      smooth_ring: smoother slots after padding (``>= Ks``).

    Returns:
      The padded :class:`LevelArrays` (NumPy).

    Example:
      >>> a = LevelArrays(*(np.zeros((3, 2), t) for t in (np.int32, bool, np.complex64, np.complex64)),
      ...                 np.zeros((3, 1, 4, 3), np.int32), np.zeros((3, 1, 4, 3), np.float32),
      ...                 np.zeros((3, 2), np.int32), np.full((3, 2), 0.5, np.float32),
      ...                 np.zeros((3, 9), np.float32), np.zeros((3, 3), np.float32), np.ones(3, bool))
      >>> p = pad_level_arrays(a, num_vertices=5, ring=4, smooth_ring=3)
      >>> p.nb_index.shape, p.valid.tolist(), p.nb_transport[0].tolist()
      ((5, 4), [True, True, True, False, False], [0j, 0j, (1+0j), (1+0j)])
    """
    V = num_vertices
    fields = {}
    for name, x in arr._asdict().items():
        fill = 1 if name == "nb_transport" else 0
        x = pad_axis(np.asarray(x), 0, V, fill)
        if name in ("nb_index", "nb_mask", "nb_log", "nb_transport"):
            x = pad_axis(x, 1, ring, fill)
        elif name in ("sm_index", "sm_weight"):
            x = pad_axis(x, 1, smooth_ring, fill)
        fields[name] = x
    return LevelArrays(**fields)


def search_tables(h: MeshHierarchy, m: int, hops: int):
    """Random-search maps of source level ``m`` with a fixed structure of ``hops`` hops.

    ``up[j]``: each level-m vertex's ancestor at level ``min(m + j + 1, top)``; ``down[i]``:
    ``(children, count)`` from level ``m + i + 1`` to ``m + i``, or the identity of the top level
    where ``m + i + 1`` lies above it (so hops beyond the top repeat the top-level search). The
    fixed structure lets every level share one compiled step.
    """
    top = h.num_levels - 1
    up, down = [], []
    for j in range(hops):
        up.append(ancestors(h, m, min(m + j + 1, top)).astype(np.int32))
    for i in range(hops):
        if m + i + 1 <= top:
            p = h.pooling[m + i]
            down.append(
                (
                    np.asarray(p.children, np.int32),
                    np.asarray(p.children_mask).sum(1).astype(np.int32),
                )
            )
        else:
            n = len(h.vertices[top])
            down.append((np.arange(n, dtype=np.int32)[:, None], np.ones(n, np.int32)))
    return up, down


def level_pairing(source: Side, target: Side) -> list[int]:
    """Per target level, the source level whose mean edge length is closest (in log scale)."""
    hs, ht = np.log(np.asarray(source.edge)), np.log(np.asarray(target.edge))
    return [int(np.argmin(np.abs(hs - h))) for h in ht]


def pool_colors(h: MeshHierarchy, colors: np.ndarray) -> list[np.ndarray]:
    """Per level colours of a hierarchy: level 0 ``colors``, each coarser level its children's mean."""
    out = [np.asarray(colors, np.float64)]
    for p in h.pooling:
        c = out[-1]
        out.append(np.einsum("vm,vmc->vc", p.children_weight, c[p.children]))
    return out


def level_groups(sizes, bucket_vertices: int, *, ratio: float = 2.5) -> list[list[int]]:
    """Levels that are padded to one shape and share one compiled PatchMatch step.

    All levels with at most ``bucket_vertices`` vertices form one group (they are cheap: padding
    costs little, each compile saved costs seconds); from the finest level down, a larger level
    joins the group of the level above it when that group's largest size is at most ``ratio``
    times its own (with halving hierarchies: pairs of levels, the smaller padded to the larger: its
    extra work, a few iterations at twice its size, costs less than a compile of the step).

    Args:
      sizes: vertex count per level, finest first.
      bucket_vertices: the small-level bucket bound (0: no small-level bucket).
      ratio: largest padding factor of a larger level.

    Returns:
      Groups of level indices (each list finest first); every level is in exactly one.

    Example:
      >>> level_groups([65536, 32768, 16384, 8192, 4096, 2048, 1024], 4096)
      [[0, 1], [2, 3], [4, 5, 6]]
      >>> level_groups([1000, 500, 250], 0)
      [[0, 1], [2]]
    """
    small = [lv for lv, n in enumerate(sizes) if n <= bucket_vertices]
    groups: list[list[int]] = []
    for lv, n in enumerate(sizes):
        if lv in small:
            continue
        if groups and sizes[groups[-1][0]] <= ratio * n and len(groups[-1]) < 2:
            groups[-1].append(lv)
        else:
            groups.append([lv])
    if small:
        groups.append(small)
    return groups


def bucket_dims(source: Side, target: Side, pairing, levels, hops: int) -> dict:
    """Common padded sizes of the levels in ``levels`` (target and source rows, ring slots, children)."""
    dims = {"Vt": 0, "Kt": 0, "Kst": 0, "Vs": 0, "Ks": 0, "Kss": 0, "down": [(0, 0)] * hops}
    for level in levels:
        m = pairing[level]
        dims["Vt"] = max(dims["Vt"], len(target.hierarchy.vertices[level]))
        dims["Kt"] = max(dims["Kt"], target.neighborhoods[level].index.shape[1])
        dims["Kst"] = max(dims["Kst"], target.smoothers[level].index.shape[1])
        dims["Vs"] = max(dims["Vs"], len(source.hierarchy.vertices[m]))
        dims["Ks"] = max(dims["Ks"], source.neighborhoods[m].index.shape[1])
        dims["Kss"] = max(dims["Kss"], source.smoothers[m].index.shape[1])
        _, down = search_tables(source.hierarchy, m, hops)
        dims["down"] = [
            (max(a, c.shape[0]), max(b, c.shape[1]))
            for (a, b), (c, _) in zip(dims["down"], down, strict=True)
        ]
    return dims


def scan_order(
    nb_index: np.ndarray,
    nb_mask: np.ndarray,
    *,
    start: int = 0,
    pad_to: tuple[int, int] | None = None,
    fill: int | None = None,
) -> np.ndarray:
    """Breadth-first wavefronts of a mesh level: the order of sequential (Gauss–Seidel) propagation.

    Row ``l`` holds the vertices ``l`` one-ring hops from ``start`` (further components follow, each
    from its lowest vertex), padded with ``fill``; every vertex's neighbours lie in its own, the
    previous or the next row, so a sweep through the rows hands good matches on one ring per row.

    Args:
      nb_index: ``[V, K]`` one-ring neighbours; ``nb_mask``: ``[V, K]`` their real slots.
      start: the first wavefront's vertex.
      pad_to: ``(rows, width)`` to pad to (at least the wavefronts' own), or None.
      fill: the padding index (default ``V``: out of range, written nowhere).

    Returns:
      ``[L, B]`` int32: ``L`` wavefronts (rows) of at most ``B`` vertices.

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.geometry import one_ring_neighborhood
      >>> nb = one_ring_neighborhood(*grid(2, 1))          # a 3 × 2 vertex sheet
      >>> scan_order(np.asarray(nb.index), np.asarray(nb.mask)).tolist()
      [[0, 6, 6], [1, 3, 4], [2, 5, 6]]
    """
    V = len(nb_index)
    fill = V if fill is None else int(fill)
    rows, cols = np.nonzero(np.asarray(nb_mask, bool))
    graph = sp.coo_matrix(
        (np.ones(len(rows)), (rows, np.asarray(nb_index)[rows, cols])), shape=(V, V)
    ).tocsr()
    graph = ((graph + graph.T) > 0).astype(np.int8)
    _, labels = connected_components(graph, directed=False)
    depth = np.full(V, -1, np.int64)
    offset = 0
    seeds = [int(start)] + [
        int(np.argmax(labels == c)) for c in np.unique(labels) if c != labels[start]
    ]
    for seed in seeds:
        order, pred = breadth_first_order(graph, seed, directed=False, return_predecessors=True)
        d = np.zeros(V, np.int64)
        for v in order[1:]:  # predecessors come before their children in a breadth-first order
            d[v] = d[pred[v]] + 1
        depth[order] = d[order] + offset
        offset = int(depth[order].max()) + 1
    order = np.argsort(depth, kind="stable")
    counts = np.bincount(depth, minlength=offset)
    L, B = offset, int(counts.max())
    if pad_to is not None:
        L, B = max(L, pad_to[0]), max(B, pad_to[1])
    out = np.full((L, B), fill, np.int32)
    slot = np.arange(V) - np.repeat(np.cumsum(counts) - counts, counts)
    out[depth[order], slot] = order
    return out

"""Shape features: the per-vertex descriptors of the surface itself that MeshMatch compares
alongside the fans (Chen et al. 2012 §3.2).

The heat kernel signature (8 log-spaced times; Sun et al. 2009), computed on one coarse hierarchy
level and copied down the parent chain (:func:`ancestors`), and either (the aligned default of
``Config``) the whole normal and the per-axis standardised positions, or (``Config.intrinsic()``)
the normal's dot product with a chosen up direction (:func:`shape_features`); optional *geodesic affinities* describe where a vertex
is relative to user correspondences (:func:`correspondence_affinities`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._types import Float, Int
from ..geometry import MeshHierarchy, hks_times, laplacian_eigenpairs, tangent_frames, unique_edges
from ._fans import _smooth_host, smoother


def hks_level(hierarchy: MeshHierarchy, max_vertices: int) -> int:
    """The finest hierarchy level with at most ``max_vertices`` vertices (the coarsest if none).

    Example:
      >>> from jmeshtex.geometry import mesh_hierarchy
      >>> from jmeshtex.data import icosphere
      >>> hks_level(mesh_hierarchy(*icosphere(3), levels=3), 400)
      1
    """
    for level, v in enumerate(hierarchy.vertices):
        if len(v) <= max_vertices:
            return level
    return hierarchy.num_levels - 1


def ancestors(hierarchy: MeshHierarchy, start: int, stop: int) -> np.ndarray:
    """``[V_start]`` index, at level ``stop``, of each level-``start`` vertex's ancestor (parent chain).

    Example:
      >>> from jmeshtex.geometry import mesh_hierarchy
      >>> from jmeshtex.data import icosphere
      >>> h = mesh_hierarchy(*icosphere(2), levels=3)
      >>> a = ancestors(h, 0, 2)
      >>> a.shape, int(a.max()) < len(h.vertices[2])
      ((162,), True)
    """
    out = np.arange(len(hierarchy.vertices[start]))
    for level in range(start, stop):
        out = np.asarray(hierarchy.pooling[level].parent)[out]
    return out


def hks_features(
    hierarchy: MeshHierarchy, *, level: int, times=None, num_times: int = 8, k: int = 32
) -> tuple[Float[np.ndarray, "V T"], Float[np.ndarray, " T"]]:
    """Log heat kernel signature of every input vertex, computed on one coarse level.

    The HKS (Sun et al. 2009) of level ``level`` is copied to the finer vertices through the parent
    maps and smoothed over a few one-rings (it varies slowly), then log-transformed.

    Args:
      hierarchy: :func:`~jmeshtex.geometry.mesh_hierarchy` of the mesh.
      level: the level to compute the spectrum on (see ``hks_level``).
      times: ``[T]`` diffusion times (share them between meshes you compare); default ``num_times``
        log-spaced times from this spectrum.
      num_times: number of default times.
      k: eigenpairs.

    Returns:
      ``(log_hks [V_0, T], times [T])``.

    Example:
      >>> from jmeshtex.geometry import mesh_hierarchy
      >>> from jmeshtex.data import icosphere
      >>> h = mesh_hierarchy(*icosphere(3), levels=2)
      >>> f, t = hks_features(h, level=1, k=12)
      >>> f.shape, t.shape
      ((642, 8), (8,))
    """
    v, f = hierarchy.vertices[level], hierarchy.faces[level]
    k = int(min(k, len(v) - 1))
    ev = laplacian_eigenpairs(v, f, k=k)
    if times is None:
        times = hks_times(ev.values, num=num_times)
    times = np.asarray(times, dtype=np.float64)
    hks = (ev.vectors**2) @ np.exp(-np.outer(ev.values, times))
    values = np.log(np.maximum(hks, 1e-300))
    values = values[ancestors(hierarchy, 0, level)]
    if level > 0:
        sm = smoother(hierarchy.faces[0], len(hierarchy.vertices[0]))
        values = _smooth_host(values, sm, 2 ** (2 * level))
    return values, times


def shape_features(
    mesh: Mesh | tuple,
    log_hks: Float[np.ndarray, "V T"],
    *,
    up=None,
    side=None,
    axes=(),
    normal_weight: float = 1.0,
    position_weight: float = 0.0,
    min_spread: float = 0.01,
) -> Float[np.ndarray, "V D"]:
    """Standardised shape features: z-scored log HKS (block weight 1), ``n · a`` per axis ``a``
    (``up``, ``side``, ``axes``; weight ``normal_weight``) and optionally standardised positions.

    .. math:: \\phi_p = \\Bigl(\\tfrac{1}{\\sqrt{2T}}\\,\\tfrac{h_p - \\bar h}{s_h},\\;
              \\tfrac{1}{\\sqrt 2}\\, n_p\\cdot \\hat u\\Bigr)

    (shown for ``up`` alone at ``normal_weight`` 1: with ``B`` blocks each is divided by ``√B``, the
    HKS block also by ``√T`` and the position block by ``√3``), so ``|φ_p − φ_q|²`` is a dimension-normalised shape distance (each block contributes at most
    about 1). The HKS is standardised per mesh (per time), which removes the mesh's scale; the
    spread ``s_h`` is floored at ``min_spread`` (log units), so a time at which the HKS is constant
    up to tessellation noise (every time on a sphere: spreads of 10⁻³ and below; the largest times
    on any shape) stays near 0 instead of being blown up to unit-variance noise that then steers
    the match (bumpy sphere → sphere displacement, 642 vertices: 178 distinct source vertices
    used and the bumps' 95th height percentile down 38 % without the floor; 224 and 0 % with it).

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])`` (for the normals).
      log_hks: ``[V, T]`` from :func:`hks_features`.
      up: a 3-vector, or None to leave the ``n · up`` feature out.
      side: a second 3-vector (``n · side``, one more block of weight 1), or None.
      axes: further 3-vectors, one ``n · a`` block each (``Config.aligned``: the three coordinate
        axes, i.e. the whole normal, for meshes that share a pose).
      normal_weight: the factor of every ``n · a`` block relative to the HKS block.
      position_weight: the factor of a block of the vertex positions standardised per axis
        (``(x − mean) / std``, the second moments matched: a pose-aligned prior that also undoes
        a non-uniform stretch); 0 leaves it out.
      min_spread: the floor of the per-time standard deviation ``s_h`` of the log HKS.

    Returns:
      ``[V, T + number of axes (+ 3 with positions)]`` float64 features.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> sphere = icosphere(2)
      >>> shape_features(sphere, np.log(1 + sphere.vertices[:, :2] ** 2), up=(0, 0, 1)).shape
      (162, 3)
    """
    mesh = as_mesh(mesh)
    h = np.asarray(log_hks, dtype=np.float64)
    z = (h - h.mean(axis=0)) / np.maximum(h.std(axis=0), max(float(min_spread), 1e-12))
    axes = [np.asarray(a, dtype=np.float64) for a in (up, side, *axes) if a is not None]
    blocks = 1 + len(axes)
    parts = [z / np.sqrt(blocks * h.shape[1])]
    if axes:
        normal = tangent_frames(mesh.vertices, mesh.faces).normal
        for u in axes:
            parts.append(
                float(normal_weight) * (normal @ (u / np.linalg.norm(u)))[:, None] / np.sqrt(blocks)
            )
    if position_weight > 0:
        x = np.asarray(mesh.vertices, dtype=np.float64)
        x = (x - x.mean(axis=0)) / np.maximum(x.std(axis=0), 1e-12)
        parts.append(float(position_weight) * x / np.sqrt(3 * blocks))
    return np.concatenate(parts, axis=1)


def _edge_graph(mesh: Mesh) -> sp.csr_matrix:
    """Symmetric sparse matrix of edge lengths (the graph the affinities' geodesics run on)."""
    v = np.asarray(mesh.vertices, np.float64)
    e = unique_edges(mesh.faces, len(v))
    w = np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1)
    g = sp.coo_matrix((w, (e[:, 0], e[:, 1])), shape=(len(v), len(v))).tocsr()
    return (g + g.T).tocsr()


def correspondence_affinities(
    source: Mesh | tuple,
    target: Mesh | tuple,
    pairs: Int[np.ndarray, "m 2"],
    *,
    ridge: float = 1e-2,
) -> tuple[Float[np.ndarray, "Vs m"], Float[np.ndarray, "Vt m"]]:
    """Geodesic affinities to user correspondences, made comparable between the two meshes.

    Each vertex gets its vector of (edge-graph) geodesic distances to the ``m`` corresponding points
    of its mesh; the target's vectors are mapped by the affine transform ``W`` that best makes the
    corresponding points agree (ridge-regularised least squares towards the identity, since
    ``m`` points cannot determine an ``(m+1) × m`` map alone),

    .. math:: \\min_W \\lVert [D_t(c_t), 1]\\, W - D_s(c_s) \\rVert^2 + \\lambda \\lVert W - W_0\\rVert^2,

    then turned into affinities ``exp(−d² / 2σ²)`` with ``σ`` a third of the largest source
    distance, scaled by ``1/√m`` so the block's squared distance is at most about 1.

    Args:
      source: the source :class:`~jmeshtex.Mesh` (or ``(vertices [Vs, 3], faces [Fs, 3])``).
      target: the target mesh (``Vt`` vertices).
      pairs: ``[m, 2]`` (source vertex, target vertex) correspondences, ``m >= 1``.
      ridge: λ relative to the mean squared distance.

    Returns:
      ``(source_affinities [Vs, m], target_affinities [Vt, m])``.

    Raises:
      InputError: bad pair shapes or indices.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> sphere = icosphere(2)
      >>> a, b = correspondence_affinities(sphere, sphere, np.array([[0, 0], [5, 5], [40, 40]]))
      >>> a.shape, bool(np.abs(a - b).max() < 1e-6)
      ((162, 3), True)
    """
    source, target = as_mesh(source, what="source"), as_mesh(target, what="target")
    pairs = np.asarray(pairs)
    Vs, Vt = source.num_vertices, target.num_vertices
    if (
        pairs.ndim != 2
        or pairs.shape[1] != 2
        or len(pairs) == 0
        or not np.issubdtype(pairs.dtype, np.integer)
    ):
        raise InputError(
            f"correspondences must be an integer array [m >= 1, 2] of (source, target) vertices, got {pairs.dtype} {pairs.shape}"
        )
    if (
        pairs[:, 0].min() < 0
        or pairs[:, 0].max() >= Vs
        or pairs[:, 1].min() < 0
        or pairs[:, 1].max() >= Vt
    ):
        raise InputError(
            f"correspondence vertex indices out of range (source V={Vs}, target V={Vt})"
        )
    ds = dijkstra(_edge_graph(source), indices=pairs[:, 0]).T  # [Vs, m]
    dt = dijkstra(_edge_graph(target), indices=pairs[:, 1]).T
    finite_s = np.isfinite(ds)
    dmax = float(ds[finite_s].max()) if finite_s.any() else 1.0
    ds = np.where(finite_s, ds, 10 * dmax)
    dt = np.where(np.isfinite(dt), dt, 10 * dmax)
    m = len(pairs)
    x = np.concatenate([dt[pairs[:, 1]], np.ones((m, 1))], axis=1)  # [m, m+1]
    y = ds[pairs[:, 0]]  # [m, m]
    w0 = np.concatenate([np.eye(m), np.zeros((1, m))], axis=0)
    lam = ridge * max(float(np.mean(x * x)), 1e-12) * (m + 1)
    w = w0 + np.linalg.solve(x.T @ x + lam * np.eye(m + 1), x.T @ (y - x @ w0))
    dt_mapped = np.concatenate([dt, np.ones((len(dt), 1))], axis=1) @ w
    sigma = max(dmax / 3.0, 1e-12)
    scale = 1.0 / np.sqrt(m)
    return (
        np.exp(-(ds**2) / (2 * sigma**2)) * scale,
        np.exp(-(dt_mapped**2) / (2 * sigma**2)) * scale,
    )

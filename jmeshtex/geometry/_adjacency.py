"""Mesh topology on the host: half-edge lookups, face adjacency, ordered one-rings, boundaries.

Everything here depends on connectivity only (no positions) and is vectorised NumPy: no Python
loop over vertices or faces. Orientation convention: face ``(a, b, c)`` is counter-clockwise seen
from outside; around vertex ``a`` it spans the wedge from edge ``a→b`` to edge ``a→c``, so the
counter-clockwise one-ring of ``a`` visits ``b`` then ``c``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._errors import InconsistentOrientationError, NonManifoldEdgeError, NonManifoldVertexError
from .._mesh import accepts_mesh_faces
from .._neighborhoods import FaceNeighborhood


class OneRings(NamedTuple):
    """Counter-clockwise ordered one-rings (topology only).

    Attributes:
      ring: ``[V, K]`` neighbours in counter-clockwise order, padded with 0. For an interior vertex
        slot 0 is the neighbour of its lowest-numbered corner (deterministic gauge); for a boundary
        vertex the ring runs from one boundary neighbour to the other.
      mask: ``[V, K]`` True for real slots.
      wedge_faces: ``[V, K]`` face spanned by slots j and j+1 (cyclically for interior vertices);
        padded with 0.
      wedge_mask: ``[V, K]`` True for real wedges (``degree`` wedges inside, ``degree - 1`` on the
        boundary).
      degree: ``[V]`` number of neighbours.
      boundary: ``[V]`` True on boundary vertices.
    """

    ring: np.ndarray
    mask: np.ndarray
    wedge_faces: np.ndarray
    wedge_mask: np.ndarray
    degree: np.ndarray
    boundary: np.ndarray


def _corners(faces: np.ndarray):
    f = np.asarray(faces, dtype=np.int64)
    p = f.ravel()
    a = np.roll(f, -1, axis=1).ravel()
    b = np.roll(f, -2, axis=1).ravel()
    return p, a, b


def _lookup(sorted_keys: np.ndarray, order: np.ndarray, query: np.ndarray) -> np.ndarray:
    """Position (in the unsorted array) of each query key, or -1."""
    pos = np.searchsorted(sorted_keys, query)
    pos = np.minimum(pos, len(sorted_keys) - 1)
    found = sorted_keys[pos] == query if len(sorted_keys) else np.zeros(len(query), bool)
    return np.where(found, order[pos], -1)


def _halfedge_table(faces: np.ndarray, num_vertices: int):
    """Sorted keys of directed half-edges ``v_k -> v_{k+1}``; raises on repeated half-edges."""
    p, a, _ = _corners(faces)
    keys = p * num_vertices + a
    order = np.argsort(keys, kind="stable")
    sk = keys[order]
    dup = np.nonzero(sk[1:] == sk[:-1])[0]
    if dup.size:
        bad = np.unique(np.stack([p[order[dup]], a[order[dup]]], axis=1), axis=0)
        und = np.sort(bad, axis=1)
        # an undirected edge used by >2 faces is non-manifold; otherwise the orientation flips
        ukeys = np.sort(np.stack([p, a], 1), axis=1)
        _, inv, counts = np.unique(ukeys, axis=0, return_inverse=True, return_counts=True)
        over = np.unique(ukeys[counts[inv.ravel()] > 2], axis=0)
        if over.size:
            raise NonManifoldEdgeError(indices=over)
        raise InconsistentOrientationError(indices=np.unique(und, axis=0))
    return sk, order


@accepts_mesh_faces
def face_neighborhood(faces: np.ndarray, num_vertices: int | None = None) -> FaceNeighborhood:
    """Face adjacency across each edge, plus vertex→face incidence, as a padded pytree.

    Edge ``k`` of face ``f`` is ``(faces[f, k], faces[f, (k+1) % 3])``; its neighbour is the face that
    holds the reversed half-edge. On boundary edges ``mask`` is False, ``neighbors`` 0 and
    ``opposite`` the face's own opposite vertex (DGTS's reference code crashes there).

    Args:
      faces: ``[F, 3]`` consistently oriented, edge-manifold triangles.
      num_vertices: V (defaults to ``faces.max() + 1``).

    Returns:
      :class:`~jmeshtex.FaceNeighborhood` with int32 indices.

    Raises:
      MeshError: a non-manifold edge (``NonManifoldEdgeError``) or inconsistent orientation
        (``InconsistentOrientationError``).

    Example:
      >>> import numpy as np
      >>> nb = face_neighborhood(np.array([[0, 1, 2], [2, 1, 3]]))
      >>> nb.neighbors.tolist(), nb.mask.tolist()
      ([[0, 1, 0], [0, 0, 0]], [[False, True, False], [True, False, False]])
      >>> nb.opposite.tolist()
      [[2, 3, 1], [0, 2, 1]]
    """
    faces = np.asarray(faces, dtype=np.int64)
    n_faces = faces.shape[0]
    V = int(faces.max()) + 1 if num_vertices is None else int(num_vertices)
    sk, order = _halfedge_table(faces, V)
    p, a, _ = _corners(faces)
    twin = _lookup(sk, order, a * V + p)  # corner id (3g + m) holding the reversed half-edge
    mask = (twin >= 0).reshape(n_faces, 3)
    g = np.where(twin >= 0, twin // 3, 0).reshape(n_faces, 3)
    m = np.where(twin >= 0, twin % 3, 0).reshape(n_faces, 3)
    own_opposite = np.roll(faces, -2, axis=1)
    opposite = np.where(mask, faces[g, (m + 2) % 3], own_opposite)
    neighbors = np.where(mask, g, 0)

    vf, vc, vmask = _vertex_faces(faces, V)
    return FaceNeighborhood(
        faces=faces.astype(np.int32),
        neighbors=neighbors.astype(np.int32),
        opposite=opposite.astype(np.int32),
        mask=mask,
        face_mask=np.ones(n_faces, bool),
        vertex_faces=vf,
        vertex_corners=vc,
        vertex_faces_mask=vmask,
        vertex_mask=np.ones(V, bool),
    )


def _vertex_faces(faces: np.ndarray, V: int):
    p = faces.ravel()
    order = np.argsort(p, kind="stable")
    counts = np.bincount(p, minlength=V)
    M = max(int(counts.max()), 1) if counts.size else 1
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    slot = np.arange(len(p)) - np.repeat(starts, counts)
    vf = np.zeros((V, M), np.int32)
    vc = np.zeros((V, M), np.int32)
    vm = np.zeros((V, M), bool)
    vf[p[order], slot] = order // 3
    vc[p[order], slot] = order % 3
    vm[p[order], slot] = True
    return vf, vc, vm


@accepts_mesh_faces
def one_rings(faces: np.ndarray, num_vertices: int | None = None) -> OneRings:
    """Counter-clockwise ordered one-rings of every vertex, boundary-aware, fully vectorised.

    The wedges of each vertex are chained (wedge ``p: a→b`` is followed by the wedge ``p: b→c``) and
    ranked by pointer jumping, so the cost is O(F log K) with no per-vertex Python loop.

    Args:
      faces: ``[F, 3]`` consistently oriented, manifold triangles.
      num_vertices: V (defaults to ``faces.max() + 1``); unreferenced vertices get empty rings.

    Returns:
      :class:`OneRings`.

    Raises:
      NonManifoldVertexError: a vertex whose faces form more than one fan (bow-tie).
      NonManifoldEdgeError, InconsistentOrientationError: from the half-edge table.

    Example:
      >>> import numpy as np
      >>> r = one_rings(np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1]]))  # a closed fan around vertex 0
      >>> r.ring[0, :3].tolist(), bool(r.boundary[0])
      ([1, 2, 3], False)
    """
    faces = np.asarray(faces, dtype=np.int64)
    V = int(faces.max()) + 1 if num_vertices is None else int(num_vertices)
    sk, order = _halfedge_table(faces, V)
    p, a, b = _corners(faces)
    n_corners = len(p)
    # successor wedge around p: the corner at p whose first edge is p->b
    succ = _lookup(sk, order, p * V + b)
    pred = np.full(n_corners, -1)
    has_succ = succ >= 0
    pred[succ[has_succ]] = np.nonzero(has_succ)[0]

    # start wedges: boundary fans start where there is no predecessor; closed fans at the
    # lowest corner id of the vertex
    is_start = pred < 0
    starts_per_vertex = np.bincount(p[is_start], minlength=V)
    if np.any(starts_per_vertex > 1):
        raise NonManifoldVertexError(indices=np.nonzero(starts_per_vertex > 1)[0])
    counts = np.bincount(p, minlength=V)
    closed = (starts_per_vertex == 0) & (counts > 0)
    first_corner = np.full(V, n_corners)
    np.minimum.at(first_corner, p, np.arange(n_corners))
    closed_start = first_corner[closed]
    succ = succ.copy()
    succ[pred[closed_start]] = -1  # break each closed fan's cycle before its start
    is_start[closed_start] = True

    # list ranking: distance of each corner to the end of its chain
    dist = (succ >= 0).astype(np.int64)
    nxt = succ.copy()
    max_iter = int(np.ceil(np.log2(max(int(counts.max()), 2)))) + 2
    for _ in range(max_iter):
        active = nxt >= 0
        if not active.any():
            break
        idx = np.nonzero(active)[0]
        dist[idx] += dist[nxt[idx]]
        nxt[idx] = nxt[nxt[idx]]
    if (nxt >= 0).any():  # a second closed fan at the same vertex never terminates
        raise NonManifoldVertexError(indices=np.unique(p[nxt >= 0]))
    chain_len = np.zeros(V, np.int64)
    np.maximum.at(chain_len, p, dist + 1)
    if np.any(chain_len != counts):  # several fans at one vertex
        raise NonManifoldVertexError(indices=np.nonzero(chain_len != counts)[0])
    rank = chain_len[p] - 1 - dist

    boundary = starts_per_vertex == 1
    degree = counts + boundary.astype(np.int64)
    K = max(int(degree.max()), 1) if V else 1
    ring = np.zeros((V, K), np.int32)
    mask = np.zeros((V, K), bool)
    wedge_faces = np.zeros((V, K), np.int32)
    wedge_mask = np.zeros((V, K), bool)
    ring[p, rank] = a
    mask[p, rank] = True
    wedge_faces[p, rank] = np.arange(n_corners) // 3
    wedge_mask[p, rank] = True
    # the last neighbour of a boundary fan closes it: the b of the chain's last wedge
    last = (succ < 0) & boundary[p]
    ring[p[last], rank[last] + 1] = b[last]
    mask[p[last], rank[last] + 1] = True
    return OneRings(ring, mask, wedge_faces, wedge_mask, degree.astype(np.int32), boundary)


@accepts_mesh_faces
def boundary_edges(faces: np.ndarray, num_vertices: int | None = None) -> np.ndarray:
    """``[B, 2]`` directed boundary half-edges (their face lies to the left).

    Example:
      >>> import numpy as np
      >>> boundary_edges(np.array([[0, 1, 2]])).tolist()
      [[0, 1], [1, 2], [2, 0]]
    """
    faces = np.asarray(faces, dtype=np.int64)
    V = int(faces.max()) + 1 if num_vertices is None else int(num_vertices)
    sk, order = _halfedge_table(faces, V)
    p, a, _ = _corners(faces)
    twin = _lookup(sk, order, a * V + p)
    return np.stack([p[twin < 0], a[twin < 0]], axis=1)


@accepts_mesh_faces
def boundary_loops(faces: np.ndarray, num_vertices: int | None = None) -> list[np.ndarray]:
    """Boundary loops as arrays of vertex indices, each in the direction of its half-edges.

    Example:
      >>> import numpy as np
      >>> [loop.tolist() for loop in boundary_loops(np.array([[0, 1, 2], [0, 2, 3]]))]
      [[0, 1, 2, 3]]
    """
    edges = boundary_edges(faces, num_vertices)
    if len(edges) == 0:
        return []
    nxt = dict(zip(edges[:, 0].tolist(), edges[:, 1].tolist(), strict=True))
    loops, seen = [], set()
    for start in sorted(nxt):
        if start in seen:
            continue
        loop, v = [], start
        while v not in seen and v in nxt:
            seen.add(v)
            loop.append(v)
            v = nxt[v]
        loops.append(np.asarray(loop, dtype=np.int64))
    return loops


@accepts_mesh_faces
def connected_components(faces: np.ndarray, num_vertices: int | None = None) -> np.ndarray:
    """Component label of every face (faces connected through shared vertices), ``[F]``.

    Example:
      >>> import numpy as np
      >>> connected_components(np.array([[0, 1, 2], [3, 4, 5], [2, 1, 6]])).tolist()
      [0, 1, 0]
    """
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components as cc

    faces = np.asarray(faces, dtype=np.int64)
    V = int(faces.max()) + 1 if num_vertices is None else int(num_vertices)
    F = len(faces)
    rows = np.repeat(np.arange(F), 3)
    graph = sp.coo_matrix((np.ones(3 * F), (rows, faces.ravel() + F)), shape=(F + V, F + V))
    _, labels = cc(graph, directed=False)
    _, face_labels = np.unique(labels[:F], return_inverse=True)
    return face_labels.reshape(-1)

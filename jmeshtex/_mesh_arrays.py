"""Array-level mesh checks and vertex maps shared by :mod:`jmeshtex.io` and :mod:`jmeshtex.geometry`.

Both layers read user arrays the same way, so the coercions, the index check and the exact
coincident-vertex merge live here, below both (io must not import geometry):

- :func:`coerce_vertices` / :func:`coerce_faces`: copies as float64 ``[V, 3]`` / int64 ``[F, 3]``,
  or the typed error that says what is wrong (:class:`~jmeshtex.NonTriangleFaceError` names the
  polygons);
- :func:`check_indices`: every face index in ``[0, V)``;
- :func:`edge_keys` and :func:`corner_fans`: half-edge keys and the fans of faces around each
  vertex, the building blocks of the manifold checks;
- :func:`coincident_vertex_map`: merge vertices with exactly equal coordinates unless that pinches
  the surface (the seam merge of :func:`jmeshtex.io.load_mesh` and of
  :func:`jmeshtex.geometry.prepare_mesh`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components as _graph_components

from ._errors import FaceIndexError, InputError, NonTriangleFaceError

__all__ = [
    "check_indices",
    "coerce_faces",
    "coerce_vertices",
    "coincident_vertex_map",
    "corner_fans",
    "edge_keys",
]


def coerce_vertices(vertices: Any) -> np.ndarray:
    """``vertices`` as a float64 ``[V, 3]`` copy; :class:`~jmeshtex.InputError` if not real ``[V, 3]``."""
    try:
        v = np.asarray(vertices)
    except (ValueError, TypeError) as err:
        raise InputError(f"vertices must be a [V, 3] array of real numbers ({err})") from None
    if (
        v.dtype == object
        or v.dtype == bool
        or not (np.issubdtype(v.dtype, np.floating) or np.issubdtype(v.dtype, np.integer))
    ):
        raise InputError(f"vertices must be real numbers, got dtype {v.dtype}")
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError(
            f"vertices must have shape [V, 3], got {v.shape}. "
            "Fix: pass one row (x, y, z) per vertex"
        )
    return np.array(v, dtype=np.float64)  # always a copy: the caller's array is never touched


def coerce_faces(faces: Any) -> np.ndarray:
    """``faces`` as an int64 ``[F, 3]`` copy (``[0, 3]`` when empty).

    Raises :class:`~jmeshtex.NonTriangleFaceError` naming the polygons (ragged input or ``[F, n]``
    with ``n != 3``), :class:`~jmeshtex.InputError` for non-integer indices, and
    :class:`~jmeshtex.FaceIndexError` for unsigned indices beyond int64.
    """
    try:
        f = np.asarray(faces)
    except (ValueError, TypeError):  # a ragged nested sequence (numpy >= 1.24 refuses it)
        f = None
    if f is None or f.dtype == object:
        try:  # ragged input is a Python object already; measuring it is not a per-face hot path
            lengths = np.array([np.size(face) for face in faces])
        except TypeError:
            raise InputError("faces must be an [F, 3] array of vertex indices") from None
        bad = np.nonzero(lengths != 3)[0]
        raise NonTriangleFaceError(
            f"{NonTriangleFaceError.what}; faces with {sorted(set(lengths[bad].tolist()))} corners",
            indices=bad,
        )
    if f.size == 0:  # no faces (np.asarray([]) is float64: any dtype will do)
        return np.zeros((0, 3), np.int64)
    if f.ndim != 2 or f.shape[1] != 3:
        if f.ndim == 2:
            raise NonTriangleFaceError(
                f"{NonTriangleFaceError.what}, got {f.shape[1]} corners per face (shape {f.shape})",
                indices=np.arange(len(f)),
            )
        hint = (
            " (a flat index list? use faces.reshape(-1, 3))"
            if f.ndim == 1 and f.size % 3 == 0
            else ""
        )
        raise NonTriangleFaceError(f"{NonTriangleFaceError.what}, got shape {f.shape}{hint}")
    if f.dtype == bool or not np.issubdtype(f.dtype, np.integer):
        raise InputError(
            f"faces must hold integer vertex indices, got dtype {f.dtype}. "
            "Fix: faces.astype(np.int64)"
        )
    if np.issubdtype(f.dtype, np.unsignedinteger) and f.size and f.max() > np.iinfo(np.int64).max:
        rows = np.nonzero((f > np.iinfo(np.int64).max).any(axis=1))[0]
        raise FaceIndexError(indices=rows)
    return np.array(f, dtype=np.int64)


def check_indices(faces: np.ndarray, num_vertices: int) -> None:
    """Raise :class:`~jmeshtex.FaceIndexError`, naming the faces, unless every index is in ``[0, V)``."""
    bad = np.nonzero(((faces < 0) | (faces >= num_vertices)).any(axis=1))[0]
    if bad.size:
        raise FaceIndexError(
            f"face indices out of range [0, {num_vertices}) (negative, or not below the number of "
            "vertices) at faces",
            indices=bad,
        )


def edge_keys(faces: np.ndarray, num_vertices: int):
    """Half-edges ``a → b`` (corner order) with undirected edge keys and their face counts."""
    a = faces.ravel()
    b = faces[:, [1, 2, 0]].ravel()
    key = np.minimum(a, b) * num_vertices + np.maximum(a, b)
    _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    return a, b, key, inverse.reshape(-1), counts


def corner_fans(faces: np.ndarray, num_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Fan label of every corner and number of fans per vertex.

    Two corners at the same vertex p are in one fan when their faces share an edge incident to p;
    a manifold vertex has exactly one fan, a bow-tie several. Orientation is not used.

    Returns:
      labels ``[3F]`` (corner ``3f + k``), fans ``[V]``.
    """
    F = len(faces)
    if F == 0:
        return np.zeros(0, np.int64), np.zeros(num_vertices, np.int64)
    a = faces.ravel()
    b = faces[:, [1, 2, 0]].ravel()
    corner_a = np.arange(3 * F)
    corner_b = 3 * (corner_a // 3) + (corner_a % 3 + 1) % 3
    key = np.minimum(a, b) * num_vertices + np.maximum(a, b)
    keys = np.concatenate([key, key])
    ends = np.concatenate([a, b])
    corners = np.concatenate([corner_a, corner_b])
    order = np.lexsort((ends, keys))
    ks, es, cs = keys[order], ends[order], corners[order]
    link = (ks[1:] == ks[:-1]) & (es[1:] == es[:-1])
    graph = sp.coo_matrix(
        (np.ones(int(link.sum())), (cs[:-1][link], cs[1:][link])), shape=(3 * F, 3 * F)
    )
    n_labels, labels = _graph_components(graph, directed=False)
    fan_vertex = np.zeros(n_labels, np.int64)
    fan_vertex[labels] = a  # links only join corners at the same vertex: one vertex per fan
    fans = np.bincount(fan_vertex, minlength=num_vertices)
    return labels.astype(np.int64), fans


def coincident_vertex_map(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge referenced vertices with exactly equal coordinates, unless that pinches the surface.

    Each group of coincident referenced vertices is represented by its lowest index. A group is
    kept apart (not merged) when merging it would create a non-manifold edge or more fans at the
    merged vertex than any member had: two parts that merely touch at a point or along an edge
    stay separate, while seams split for UVs (or triangle soups) close up. The rule is applied
    until no group changes.

    Args:
      vertices: ``[V, 3]`` finite float64.
      faces: ``[F, 3]`` valid indices.

    Returns:
      ``rep [V]`` (the vertex each vertex merges into, itself if not merged) and ``kept_apart``,
      the sorted vertices that coincide with another referenced vertex but were kept separate.
    """
    V = len(vertices)
    rep = np.arange(V)
    referenced = np.zeros(V, bool)
    referenced[faces.ravel()] = True
    idx = np.nonzero(referenced)[0]
    p = vertices[idx] + 0.0  # -0.0 -> 0.0
    order = np.lexsort((p[:, 2], p[:, 1], p[:, 0]))  # stable: a group lists its indices ascending
    ps = p[order]
    new = np.ones(len(order), bool)
    new[1:] = np.any(ps[1:] != ps[:-1], axis=1)
    group_first = idx[order][new]
    rep[idx[order]] = group_first[np.cumsum(new) - 1]
    coincident = rep != np.arange(V)
    coincident[rep[coincident]] = True
    if not coincident.any():
        return rep, np.zeros(0, np.int64)

    while True:
        merged = rep[faces]
        ok = (
            (merged[:, 0] != merged[:, 1])
            & (merged[:, 1] != merged[:, 2])
            & (merged[:, 2] != merged[:, 0])
        )
        fo, fm = faces[ok], merged[ok]
        revert = np.zeros(V, bool)  # indexed by representative
        if len(fm):
            # (a) non-manifold edges that no original edge had
            _, _, _, inv_o, cnt_o = edge_keys(fo, V)
            am, bm, _, inv_m, cnt_m = edge_keys(fm, V)
            worst_before = np.zeros(len(cnt_m), np.int64)
            np.maximum.at(worst_before, inv_m, cnt_o[inv_o])
            new_nm = (cnt_m[inv_m] > 2) & (worst_before[inv_m] <= 2)
            revert[am[new_nm]] = True
            revert[bm[new_nm]] = True
            # (b) more fans at a merged vertex than at any of its members
            _, fans_o = corner_fans(fo, V)
            _, fans_m = corner_fans(fm, V)
            most_before = np.zeros(V, np.int64)
            np.maximum.at(most_before, rep, fans_o)
            revert |= fans_m > most_before
        size = np.bincount(rep, minlength=V)
        revert &= size > 1
        if not revert.any():
            break
        rep = np.where(revert[rep], np.arange(V), rep)
    kept = coincident & (rep == np.arange(V)) & (np.bincount(rep, minlength=V) == 1)
    return rep, np.nonzero(kept)[0]

"""Edges of a triangle mesh: the one enumeration of undirected edges, and the mean edge length."""

from __future__ import annotations

import numpy as np

from .._errors import InputError
from .._mesh import accepts_mesh, accepts_mesh_faces
from .._types import Float, Int


@accepts_mesh_faces
def unique_edges(
    faces: Int[np.ndarray, "F 3"], num_vertices: int | None = None, *, face_edges: bool = False
) -> Int[np.ndarray, "E 2"] | tuple[Int[np.ndarray, "E 2"], Int[np.ndarray, "F 3"]]:
    """Undirected edges ``[E, 2]`` of a triangle mesh: sorted pairs ``(i < j)``, rows sorted.

    Args:
      faces: ``[F, 3]`` vertex indices.
      num_vertices: V (default: ``faces.max() + 1``).
      face_edges: also return, per face, the edge ids of its sides ``(ab, bc, ca)``, ``[F, 3]``.

    Raises:
      InputError: an index outside ``[0, num_vertices)``.

    Example:
      >>> unique_edges(np.array([[0, 1, 2], [2, 1, 3]])).tolist()
      [[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]]
      >>> unique_edges(np.array([[0, 1, 2], [2, 1, 3]]), face_edges=True)[1].tolist()
      [[0, 2, 1], [2, 3, 4]]
    """
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    n = int(num_vertices) if num_vertices is not None else (int(f.max()) + 1 if f.size else 0)
    if f.size and (f.min() < 0 or f.max() >= n):
        raise InputError(
            f"unique_edges: face indices must lie in [0, num_vertices={n}), got "
            f"[{int(f.min())}, {int(f.max())}]; pass the mesh's vertex count (or None)"
        )
    a, b = f, np.roll(f, -1, axis=1)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    keys, inverse = np.unique(lo * max(n, 1) + hi, return_inverse=True)
    edges = np.stack([keys // max(n, 1), keys % max(n, 1)], axis=1)
    return (edges, inverse.reshape(f.shape)) if face_edges else edges


@accepts_mesh
def mean_edge_length(vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"]) -> float:
    """Mean length of the mesh's undirected edges (each edge counted once, boundary edges included).

    Example:
      >>> from jmeshtex.data import single_triangle
      >>> round(mean_edge_length(*single_triangle()), 6)  # (1 + 1 + sqrt 2) / 3
      1.138071
    """
    from ._validate import check_mesh_arrays

    v, f = check_mesh_arrays(vertices, faces)
    edges = unique_edges(f, len(v))
    if not len(edges):
        return 0.0
    d = v[edges[:, 0]] - v[edges[:, 1]]
    with np.errstate(over="ignore", invalid="ignore"):
        lengths = np.hypot(np.hypot(d[:, 0], d[:, 1]), d[:, 2])  # no overflow at 1e200
    top = float(lengths.max())
    if not np.isfinite(top) or top == 0.0:
        return top
    return float((lengths / top).mean() * top)

"""Mesh validation on the host (vectorised NumPy + scipy).

:func:`validate_mesh` raises the typed errors of :mod:`jmeshtex._errors`, naming the offending
indices, in a fixed order so that the most basic problem is reported first:

  shape → indices → finiteness → empty → degenerate faces → duplicate faces → non-manifold edges
  → orientation → non-manifold (bow-tie) vertices.

Open meshes, several components and any genus are valid. :func:`check_mesh_arrays` is the
structural half (shapes, indices, finiteness, emptiness) for builders that accept any triangle soup.

Tolerance: a face is degenerate when its doubled area, computed from its edge lengths scaled by
the longest (so: its height over its longest edge), is at most ``area_tol``. This is the one
definition of :func:`~jmeshtex.geometry.flat_faces`, shared with repair and the geodesic tracer, so a
mesh that passes validation (or that ``repair=True`` produced) is one the tracer can lay out. The
default ``1e-7`` sits above the rounding noise of Heron's formula on float64 lengths (up to about
1.3e-8 for exactly collinear corners), so corners collinear up to rounding are caught.
"""

from collections.abc import Sequence

import numpy as np

from .._errors import (
    DegenerateFaceError,
    DuplicateFaceError,
    EmptyMeshError,
    InconsistentOrientationError,
    MeshScaleError,
    NonFiniteVertexError,
    NonManifoldEdgeError,
    NonManifoldVertexError,
)
from .._mesh import accepts_mesh
from .._mesh_arrays import check_indices, coerce_faces, coerce_vertices, corner_fans, edge_keys
from .._types import ArrayLike, Float, Int

AREA_TOL = 1e-7

#: mean edge lengths between which float64 squared lengths, areas and cotangent weights stay finite
#: and normal (outside it, validation would call every face degenerate and solvers fail)
EDGE_RANGE = (1e-100, 1e100)

__all__ = ["AREA_TOL", "EDGE_RANGE", "check_float_range", "check_mesh_arrays", "validate_mesh"]


def robust_edge_mean(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Mean length of the face edges (each side of each face), without overflow or underflow."""
    if len(faces) == 0:
        return 0.0
    d = vertices[np.roll(faces, -1, axis=1)] - vertices[faces]
    with np.errstate(over="ignore", invalid="ignore"):
        lengths = np.hypot(np.hypot(d[..., 0], d[..., 1]), d[..., 2])
    top = float(lengths.max())
    if not np.isfinite(top) or top == 0.0:
        return top
    return float((lengths / top).mean() * top)


def check_float_range(vertices: np.ndarray, faces: np.ndarray, *, what: str = "mesh") -> float:
    """Raise :class:`~jmeshtex.MeshScaleError` when the mean edge length is outside
    ``EDGE_RANGE`` (or coordinate differences overflow); return the mean edge length."""
    edge = robust_edge_mean(vertices, faces)
    low, high = EDGE_RANGE
    if edge != 0.0 and not low <= edge <= high:  # 0: every face collapsed, a degenerate-face error
        raise MeshScaleError(
            f"{what}: mean edge length {edge:.3g} is outside [{low:.0e}, {high:.0e}], where float64 "
            "areas and angles can be computed"
        )
    return edge


# ----------------------------------------------------------------------------------------------
# the individual checks (each returns the offending indices; the caller raises)
# ----------------------------------------------------------------------------------------------


def _check_basic(vertices: np.ndarray, faces: np.ndarray) -> None:
    """Indices, finiteness and emptiness (shapes are checked by the coercions)."""
    check_indices(faces, len(vertices))
    bad = np.nonzero(~np.isfinite(vertices).all(axis=1))[0]
    if bad.size:
        raise NonFiniteVertexError(indices=bad)
    if len(vertices) == 0 or len(faces) == 0:
        raise EmptyMeshError(
            f"the mesh has no vertices or no faces (V={len(vertices)}, F={len(faces)})"
        )


def _degenerate_faces(vertices: np.ndarray, faces: np.ndarray, area_tol: float) -> np.ndarray:
    """Boolean ``[F]``: repeated vertex index, or flat by :func:`~jmeshtex.geometry.flat_faces`
    (the tracer's definition, so whatever validation passes the tracer can lay out)."""
    from ._intrinsic import edge_lengths, flat_faces  # _intrinsic imports this module

    with np.errstate(over="ignore", invalid="ignore"):
        flat = flat_faces(edge_lengths(vertices, faces), area_tol)
    repeated = (
        (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    )
    return repeated | flat


def _duplicate_faces(faces: np.ndarray) -> np.ndarray:
    """``[k, 2]`` pairs (first face, later face with the same vertex set), by later face."""
    if len(faces) == 0:
        return np.zeros((0, 2), np.int64)
    key = np.sort(faces, axis=1)
    order = np.lexsort((key[:, 2], key[:, 1], key[:, 0]))  # stable: equal rows keep face order
    ks = key[order]
    new = np.ones(len(order), bool)
    new[1:] = np.any(ks[1:] != ks[:-1], axis=1)
    first = order[new][np.cumsum(new) - 1]
    pairs = np.stack([first, order], axis=1)[~new]
    return pairs[np.argsort(pairs[:, 1], kind="stable")]


def _nonmanifold_edges(faces: np.ndarray, num_vertices: int) -> np.ndarray:
    """``[k, 2]`` sorted vertex pairs of edges shared by more than two faces."""
    a, b, _, inverse, counts = edge_keys(faces, num_vertices)
    over = counts[inverse] > 2
    return np.unique(np.sort(np.stack([a[over], b[over]], 1), axis=1), axis=0)


def _misoriented_edges(faces: np.ndarray, num_vertices: int) -> np.ndarray:
    """``[k, 2]`` sorted vertex pairs of two-face edges traversed in the same direction by both."""
    a, b, _, inverse, counts = edge_keys(faces, num_vertices)
    directed = a * num_vertices + b
    _, dinv, dcounts = np.unique(directed, return_inverse=True, return_counts=True)
    bad = (dcounts[dinv.reshape(-1)] > 1) & (counts[inverse] == 2)
    return np.unique(np.sort(np.stack([a[bad], b[bad]], 1), axis=1), axis=0)


def _check_topology(vertices: np.ndarray, faces: np.ndarray, area_tol: float) -> None:
    """Degenerate → duplicate → non-manifold edge → orientation → bow-tie, raising the first."""
    V = len(vertices)
    check_float_range(vertices, faces)  # a scale error, not every face "degenerate"
    bad = np.nonzero(_degenerate_faces(vertices, faces, area_tol))[0]
    if bad.size:
        raise DegenerateFaceError(indices=bad)
    pairs = _duplicate_faces(faces)
    if pairs.size:
        raise DuplicateFaceError(
            f"{DuplicateFaceError.what}, as (first, repeat) face pairs", indices=pairs
        )
    edges = _nonmanifold_edges(faces, V)
    if edges.size:
        raise NonManifoldEdgeError(indices=edges)
    edges = _misoriented_edges(faces, V)
    if edges.size:
        raise InconsistentOrientationError(
            f"{InconsistentOrientationError.what}, at edges", indices=edges
        )
    _, fans = corner_fans(faces, V)
    bad = np.nonzero(fans > 1)[0]
    if bad.size:
        raise NonManifoldVertexError(indices=bad)


@accepts_mesh
def check_mesh_arrays(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """The structural half of :func:`validate_mesh`: shapes, dtypes, index range, finiteness, emptiness.

    For host geometry that accepts any triangle soup (subdivision, HKS, rendering, tracing): it does
    not check manifoldness, orientation or degenerate faces. Returns copies as float64 ``[V, 3]``
    and int64 ``[F, 3]``; raises the same typed errors as :func:`validate_mesh`.

    Example:
      >>> v, f = check_mesh_arrays([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
      >>> v.dtype, f.dtype
      (dtype('float64'), dtype('int64'))
    """
    v = coerce_vertices(vertices)
    f = coerce_faces(faces)
    _check_basic(v, f)
    return v, f


@accepts_mesh
def validate_mesh(
    vertices: Float[ArrayLike, "V 3"] | Sequence,
    faces: Int[ArrayLike, "F 3"] | Sequence,
    *,
    area_tol: float = AREA_TOL,
) -> None:
    """Check that a triangle mesh is valid input for jmeshtex geometry; raise a typed error if not.

        Valid means: ``vertices`` is ``[V, 3]`` and finite, ``faces`` is ``[F, 3]`` integer indices in
        ``[0, V)``, both are non-empty, no face has zero area (``2·area ≤ area_tol · longest_edge²``),
        no two faces share the same three vertices, every edge has at most two faces, the two faces of
        an interior edge traverse it in opposite directions (consistent orientation), and the faces
        around every vertex form a single fan (no bow-ties). Boundaries, several components,
        unreferenced vertices and any genus are allowed. The checks run in that order, so the most
        basic problem is the one reported.

        Args:
          vertices: ``[V, 3]`` positions (any real dtype, or nested lists; never modified).
          faces: ``[F, 3]`` vertex indices (any integer dtype, or nested lists; never modified).
          area_tol: relative zero-area threshold (see the module docstring for the default).

        Raises:
          InputError: vertices not ``[V, 3]`` reals, or faces not integers.
          NonTriangleFaceError, FaceIndexError, NonFiniteVertexError, EmptyMeshError,
          DegenerateFaceError, DuplicateFaceError, NonManifoldEdgeError,
          InconsistentOrientationError, NonManifoldVertexError: each names the offending faces,
          vertices or edges (as vertex pairs) in ``err.indices``.

        Example:
          >>> from collections.abc import Sequence

    import numpy as np
          >>> from jmeshtex.data import icosahedron
          >>> v, f = icosahedron()
          >>> validate_mesh(v, f)  # valid: returns None
          >>> validate_mesh(v, np.concatenate([f, f[:1, ::-1]]))
          Traceback (most recent call last):
          ...
          jmeshtex._errors.DuplicateFaceError: duplicate faces (same three vertices), as (first, repeat) face pairs (count 1: (0, 20)). Fix: repair first with jmeshtex.geometry.prepare_mesh(mesh, repair=True), which drops the duplicates
    """
    v, f = check_mesh_arrays(vertices, faces)
    _check_topology(v, f, area_tol)

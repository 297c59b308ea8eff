"""Intrinsic triangle geometry from edge lengths: corner angles, face areas, vertex areas.

Everything downstream (one-ring log maps, transport, geodesic neighbourhoods, the hierarchy) is
computed from the quantities here and therefore from edge lengths only, so it does not change when a
surface is bent isometrically (docs/concepts.md, "Log maps, transport and their units").

Edge ``k`` of face ``f`` runs from ``faces[f, k]`` to ``faces[f, (k + 1) % 3]``; corner ``k`` is the
angle at ``faces[f, k]``, between edges ``k`` and ``k - 1``, opposite edge ``(k + 1) % 3``.
"""

from __future__ import annotations

import numpy as np

from .._mesh import accepts_mesh
from .._types import Bool, Float, Int
from ._validate import AREA_TOL, validate_mesh


@accepts_mesh
def edge_lengths(
    vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"]
) -> Float[np.ndarray, "F 3"]:
    """Euclidean length of every face edge.

    .. math:: \\ell_{f,k} = \\lVert x_{f_{k+1}} - x_{f_k} \\rVert

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` vertex indices.

    Returns:
      ``[F, 3]`` float64 lengths; column k is the edge ``faces[:, k] -> faces[:, (k+1) % 3]``.

    Example:
      >>> from jmeshtex.data import single_triangle
      >>> edge_lengths(*single_triangle()).round(4).tolist()
      [[1.0, 1.4142, 1.0]]
    """
    from .._mesh_arrays import check_indices, coerce_faces, coerce_vertices

    v = coerce_vertices(vertices)
    f = coerce_faces(faces)
    check_indices(f, len(v))  # a -1 would silently read the last vertex
    return np.linalg.norm(v[np.roll(f, -1, axis=1)] - v[f], axis=-1)


def corner_angles(lengths: Float[np.ndarray, "F 3"]) -> Float[np.ndarray, "F 3"]:
    """Interior angle at every face corner from the three edge lengths (half-angle law).

    The law of cosines ``arccos((b² + c² - a²) / 2bc)`` loses half the digits near 0 and π; the
    half-angle form used here is accurate everywhere and needs no clipping of an ``arccos`` argument:

    .. math:: \\alpha = 2\\,\\operatorname{atan2}\\big(\\sqrt{(s-b)(s-c)},\\ \\sqrt{s(s-a)}\\big),
              \\quad s = (a+b+c)/2

    with ``a`` the opposite edge. Lengths that violate the triangle inequality (a degenerate
    intrinsic triangle) are clipped to angles 0 / π instead of producing NaN.

    Args:
      lengths: ``[F, 3]`` edge lengths as returned by :func:`edge_lengths`.

    Returns:
      ``[F, 3]`` angles in radians; column k is the angle at ``faces[:, k]``. Rows sum to π.

    Example:
      >>> import numpy as np
      >>> corner_angles(np.array([[1.0, 2.0**0.5, 1.0]])) / np.pi  # the right isoceles triangle
      array([[0.5 , 0.25, 0.25]])
    """
    lengths = np.asarray(lengths, dtype=np.float64)
    # corner k sits between edges k and k-1 and faces edge k+1
    a = np.roll(lengths, -1, axis=1)  # opposite
    b = lengths
    c = np.roll(lengths, 1, axis=1)
    s_a = 0.5 * (b + c - a)
    s_b = 0.5 * (a + c - b)
    s_c = 0.5 * (a + b - c)
    s = 0.5 * (a + b + c)
    num = np.sqrt(np.maximum(s_b * s_c, 0.0))
    den = np.sqrt(np.maximum(s * s_a, 0.0))
    return 2.0 * np.arctan2(num, den)


def face_areas(lengths: Float[np.ndarray, "F 3"]) -> Float[np.ndarray, " F"]:
    """Triangle areas from edge lengths (Heron's formula in Kahan's stable ordering).

    .. math:: A = \\tfrac14\\sqrt{(a+(b+c))\\,(c-(a-b))\\,(c+(a-b))\\,(a+(b-c))}, \\quad a \\ge b \\ge c

    Args:
      lengths: ``[F, 3]`` edge lengths.

    Returns:
      ``[F]`` areas (0 for degenerate or triangle-inequality-violating lengths, never NaN).

    Example:
      >>> import numpy as np
      >>> float(face_areas(np.array([[3.0, 4.0, 5.0]]))[0])
      6.0
    """
    srt = -np.sort(-np.asarray(lengths, dtype=np.float64), axis=1)
    a, b, c = srt[:, 0], srt[:, 1], srt[:, 2]
    prod = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c))
    return 0.25 * np.sqrt(np.maximum(prod, 0.0))


def flat_faces(
    lengths: Float[np.ndarray, "F 3"], area_tol: float = AREA_TOL
) -> Bool[np.ndarray, " F"]:
    """Which faces are degenerate (zero-area): the one definition validation, repair and the
    geodesic tracer share.

    .. math:: \\text{flat}_f \\iff 2\\,A(\\ell_f / \\max \\ell_f) \\le \\text{area\\_tol}

    with ``A`` the area from edge lengths (:func:`face_areas`, Kahan's Heron) of the face's lengths
    divided by its longest, so the test is scale-free. Working from edge lengths, not a cross
    product, is what makes the definitions agree: a needle whose corners are not exactly collinear
    in space can still have lengths that close to zero area after rounding, and every length-based
    computation (the tracer's face layouts, corner angles) sees the lengths. Non-finite or all-zero
    lengths count as flat.

    Args:
      lengths: ``[F, 3]`` edge lengths (:func:`edge_lengths`, or intrinsic lengths).
      area_tol: threshold on the doubled area over the squared longest edge (the face's height
        over its longest edge); the default ``1e-7`` is above the rounding noise of Heron's formula
        on float64 lengths (about 1.3e-8 for exactly collinear corners).

    Returns:
      ``[F]`` bool, True for degenerate faces.

    Example:
      >>> import numpy as np
      >>> v = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 1e-9, 0], [0, 1, 0]])
      >>> flat_faces(edge_lengths(v, np.array([[0, 1, 2], [0, 1, 3]]))).tolist()  # a needle
      [True, False]
    """
    lengths = np.asarray(lengths, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        unit = lengths / lengths.max(axis=1, keepdims=True)
        relative = 2.0 * face_areas(np.nan_to_num(unit, nan=0.0, posinf=0.0))
    return ~(relative > area_tol) | ~np.isfinite(unit).all(axis=1)


def vertex_areas(
    faces: Int[np.ndarray, "F 3"], areas: Float[np.ndarray, " F"], num_vertices: int
) -> Float[np.ndarray, " V"]:
    """Barycentric vertex areas: a third of the area of every incident face.

    .. math:: A_p = \\tfrac13 \\sum_{f \\ni p} A_f

    Args:
      faces: ``[F, 3]`` vertex indices.
      areas: ``[F]`` face areas (e.g. :func:`face_areas`).
      num_vertices: V; unreferenced vertices get area 0.

    Returns:
      ``[V]`` areas summing to the total surface area.

    Example:
      >>> import numpy as np
      >>> vertex_areas(np.array([[0, 1, 2], [0, 2, 3]]), np.array([3.0, 6.0]), 4).tolist()
      [3.0, 1.0, 3.0, 2.0]
    """
    f = np.asarray(faces, dtype=np.int64)
    weights = np.repeat(np.asarray(areas, dtype=np.float64) / 3.0, 3)
    return np.bincount(f.ravel(), weights=weights, minlength=int(num_vertices))


def check_mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """Validate with :func:`~jmeshtex.geometry.validate_mesh`; return ``(float64 [V,3], int64 [F,3])``.

    Intrinsic geometry needs finite positions, in-range indices, no zero-area faces and manifold,
    consistently oriented triangles; a violation raises the typed error ``validate_mesh`` names
    instead of an ``IndexError`` or a NaN later.

    Example:
      >>> import numpy as np
      >>> v, f = check_mesh(np.eye(3), [[0, 1, 2]])
      >>> v.dtype, f.dtype
      (dtype('float64'), dtype('int64'))
    """
    validate_mesh(vertices, faces)
    return np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64)

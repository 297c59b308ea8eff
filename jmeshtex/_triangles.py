"""Per-face quantities from vertex positions by the cross product: the one definition of a
triangle's area and of its unit normal that geometry, metrics, render, data and the methods share.

(Areas from edge lengths alone, for the intrinsic operators, are
:func:`jmeshtex.geometry.face_areas`: Kahan's Heron formula, a different rounding.)
"""

from __future__ import annotations

import numpy as np

from ._types import Float, Int


def triangle_areas(tri: Float[np.ndarray, "F 3 3"]) -> Float[np.ndarray, " F"]:
    """Areas of triangles given by their corners, ``½ |(p₁ − p₀) × (p₂ − p₀)|``.

    Example:
      >>> triangle_areas(np.array([[[0.0, 0, 0], [3, 0, 0], [0, 4, 0]]])).tolist()
      [6.0]
    """
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def face_normals(
    vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"]
) -> Float[np.ndarray, "F 3"]:
    """Unit face normals (counter-clockwise corners: right-handed); 0 for a zero-area face.

    Example:
      >>> face_normals(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]])).tolist()
      [[0.0, 0.0, 1.0]]
    """
    v, f = vertices, faces
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)

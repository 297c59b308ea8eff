"""Typed values for the equivariance harness: what a value *is* decides how a transform acts on it.

================  ===========================  ===============================================
kind              shape                        how transforms act on it
================  ===========================  ===============================================
``invariant``     anything                     unchanged (global scalars, losses)
``vertex_scalar`` ``[V, ...]`` real            permuted with the vertices; otherwise unchanged
``face_scalar``   ``[F, ...]`` real            permuted with the faces; otherwise unchanged
``face_edge``     ``[F, 3, ...]``              permuted with the faces, edge axis rolled with a
                                               cyclic rotation of a face's vertex order
``vertex_tangent`` ``[V, ...]`` complex        permuted; rotated by ``e^{-iα_p}`` when p's frame
                                               turns by α_p (gauge change, or the relabelled
                                               mesh's intrinsic frame); unchanged by isometries
``vertex_vector`` ``[V, ..., 3]`` real         permuted; rotated by R under rigid motions
``face_vector``   ``[F, ..., 3]`` real         permuted with faces; rotated by R
``points``        ``[V, 3]``                   the mesh's own vertex positions: replaced by the
                                               transformed mesh's positions
================  ===========================  ===============================================
"""

from __future__ import annotations

from typing import Any, NamedTuple

INVARIANT = "invariant"
VERTEX_SCALAR = "vertex_scalar"
FACE_SCALAR = "face_scalar"
FACE_EDGE = "face_edge"
VERTEX_TANGENT = "vertex_tangent"
VERTEX_VECTOR = "vertex_vector"
FACE_VECTOR = "face_vector"
POINTS = "points"

KINDS = (
    INVARIANT,
    VERTEX_SCALAR,
    FACE_SCALAR,
    FACE_EDGE,
    VERTEX_TANGENT,
    VERTEX_VECTOR,
    FACE_VECTOR,
    POINTS,
)

# kinds whose transformation needs a rigid motion (they are extrinsic: an isometric bending has no
# well-defined action on them)
EXTRINSIC_KINDS = (VERTEX_VECTOR, FACE_VECTOR, POINTS)


class Field(NamedTuple):
    """A value tagged with its kind (one of ``KINDS``).

    Example:
      >>> import numpy as np
      >>> Field("vertex_scalar", np.zeros((4, 2))).kind
      'vertex_scalar'
    """

    kind: str
    value: Any

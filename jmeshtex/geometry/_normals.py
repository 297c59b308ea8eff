"""Vertex normals: the one definition, area- or angle-weighted."""

from __future__ import annotations

import numpy as np

from .._mesh import accepts_mesh
from .._types import Float, Int

_WEIGHTINGS = ("area", "angle")


@accepts_mesh
def vertex_normals(
    vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"], *, weighting: str = "area"
) -> Float[np.ndarray, "V 3"]:
    """Unit vertex normals: the sum of incident face normals, weighted by face area or corner angle.

    .. math:: n_i \\propto \\sum_{f \\ni i} w_{f,i}\\, \\hat n_f, \\qquad
       w_{f,i} = |f| \\ (\\text{area}) \\quad\\text{or}\\quad \\alpha_{f,i} \\ (\\text{angle; Thürmer \\& Wüthrich 1998})

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` counter-clockwise faces.
      weighting: ``"area"`` (default) or ``"angle"``.

    Returns:
      ``[V, 3]`` float64 unit normals; 0 for vertices in no (non-degenerate) face.

    Raises:
      InputError, NonTriangleFaceError, FaceIndexError, NonFiniteVertexError: arrays that are not
        a triangle mesh (wrong shapes, ragged or 4-column faces, indices out of range or negative).

    Example:
      >>> from jmeshtex.data import single_triangle
      >>> vertex_normals(*single_triangle()).tolist()[0]
      [0.0, 0.0, 1.0]
    """
    from .._errors import InputError

    if weighting not in _WEIGHTINGS:
        raise InputError(
            f"vertex_normals: weighting must be one of {_WEIGHTINGS}, got {weighting!r}"
        )
    from .._mesh_arrays import check_indices, coerce_faces, coerce_vertices

    v = coerce_vertices(vertices)
    f = coerce_faces(faces)
    check_indices(f, len(v))
    if not np.isfinite(v).all():
        from .._errors import NonFiniteVertexError

        raise NonFiniteVertexError(indices=np.nonzero(~np.isfinite(v).all(axis=1))[0])
    top = float(np.abs(v).max(initial=0.0))
    if top > 0:  # unit normals are scale-free: a power-of-two rescale is exact and cannot overflow
        v = v * 2.0 ** -np.floor(np.log2(top))
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])  # |cross| = 2 area
    if weighting == "area":
        w = np.repeat(cross[:, None, :], 3, axis=1)
    else:
        length = np.linalg.norm(cross, axis=1, keepdims=True)
        unit = np.divide(cross, length, out=np.zeros_like(cross), where=length > 0)
        e1 = v[np.roll(f, -1, axis=1)] - v[f]
        e2 = v[np.roll(f, 1, axis=1)] - v[f]
        cos = np.sum(e1 * e2, -1) / np.maximum(
            np.linalg.norm(e1, axis=-1) * np.linalg.norm(e2, axis=-1), 1e-300
        )
        alpha = np.arccos(np.clip(cos, -1.0, 1.0))
        w = alpha[..., None] * unit[:, None, :]
    n = np.zeros_like(v)
    np.add.at(n, f.ravel(), w.reshape(-1, 3))
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)

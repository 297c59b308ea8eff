"""The scale and placement check every method can call before float32 geometry or UV unwrapping.

Methods run their geometry in float32 (jitted ops) and some hand positions to libraries with
absolute tolerances (xatlas's unwrapper: below a mean edge of about 5e-4 it returns NaN UVs, at
1e11 it loops without end). :func:`check_mesh_scale` refuses, before any work, a mesh whose mean
edge length is outside ``[min_edge, max_edge]`` or whose bounding-box centre lies more than
``max_offset`` mean edges from the origin (float32 keeps about 7 digits: at 1e5 edges a position is
rounded to a few thousandths of an edge).
"""

from __future__ import annotations

import numpy as np

from .._errors import MeshScaleError
from .._mesh import accepts_mesh
from .._types import ArrayLike, Float, Int
from ._edges import mean_edge_length
from ._validate import check_mesh_arrays

MIN_EDGE = 1e-3
MAX_EDGE = 1e8
MAX_OFFSET = 1e5

__all__ = ["MAX_EDGE", "MAX_OFFSET", "MIN_EDGE", "check_mesh_scale"]


@accepts_mesh
def check_mesh_scale(
    vertices: Float[ArrayLike, "V 3"],
    faces: Int[ArrayLike, "F 3"],
    *,
    what: str = "mesh",
    min_edge: float = MIN_EDGE,
    max_edge: float = MAX_EDGE,
    max_offset: float = MAX_OFFSET,
) -> float:
    """Raise :class:`~jmeshtex.MeshScaleError` unless the mesh's scale and placement are in range.

    .. math:: \\text{min\\_edge} \\le \\bar\\ell \\le \\text{max\\_edge}, \\qquad
              \\lVert c \\rVert \\le \\text{max\\_offset}\\cdot\\bar\\ell

    with ``ℓ̄`` the mean edge length and ``c`` the centre of the bounding box.

    Args:
      vertices: ``[V, 3]`` positions (or a :class:`~jmeshtex.Mesh` in place of both arrays).
      faces: ``[F, 3]`` triangles (structure checked: shapes, indices, finiteness, non-empty).
      what: the argument's name, for the message.
      min_edge, max_edge: accepted range of the mean edge length (absolute units).
      max_offset: largest distance of the bounding-box centre from the origin, in mean edges.

    Returns:
      The mean edge length.

    Raises:
      MeshScaleError: out of range; the message gives the measured values and the fix.
      MeshError: (another subclass) the arrays are not a triangle mesh.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> v, f = icosphere(1)
      >>> round(check_mesh_scale(v, f), 3)
      0.582
      >>> check_mesh_scale(v * 1e12, f)
      Traceback (most recent call last):
      ...
      jmeshtex._errors.MeshScaleError: mesh: mean edge length 5.82e+11 is outside [0.001, 1e+08] ...
    """
    v, f = check_mesh_arrays(vertices, faces)
    with np.errstate(over="ignore", invalid="ignore"):
        edge = float(mean_edge_length(v, f))
        centre = float(np.linalg.norm((v.max(axis=0) + v.min(axis=0)) / 2))
    if not (min_edge <= edge <= max_edge):
        raise MeshScaleError(
            f"{what}: mean edge length {edge:.3g} is outside [{min_edge:.3g}, {max_edge:.3g}] "
            "(float32 geometry and the UV unwrapper fail outside it)"
        )
    if not centre <= max_offset * edge:
        raise MeshScaleError(
            f"{what}: its centre lies {centre:.3g} from the origin, {centre / edge:.3g} mean edges "
            f"(at most {max_offset:.3g}: float32 positions that far out lose the mesh's detail)"
        )
    return edge

"""Midpoint (1→4) subdivision with parent maps, per-corner UV subdivision, and edge-length rescaling.

DGTS (Hertz et al. 2020, §3.3) grows its mesh hierarchy by midpoint subdivision: every edge gets a
new vertex at its midpoint and every triangle ``(a, b, c)`` is replaced by four triangles. Positions
are not smoothed (unlike Loop subdivision), so a flat mesh stays flat and the surface does not move.
The parent maps returned here let any per-vertex or per-face quantity follow the subdivision.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._errors import (
    InputError,
)
from .._mesh import accepts_mesh
from .._types import ArrayLike, Float, Int
from ._edges import mean_edge_length, unique_edges
from ._validate import check_mesh_arrays


class Subdivision(NamedTuple):
    """A midpoint-subdivided mesh and the maps back to the coarse mesh.

    Numbering: the ``V`` coarse vertices keep their indices; new vertex ``V + e`` sits at the midpoint
    of coarse edge ``e = (edge_vertices[e, 0], edge_vertices[e, 1])`` (edges sorted
    lexicographically, ``edge_vertices[e, 0] < edge_vertices[e, 1]``). Fine face ``j·F + f`` is child
    ``j`` of coarse face ``f = (a, b, c)``: ``j = 0: (a, ab, ca)``, ``1: (ab, b, bc)``,
    ``2: (ca, bc, c)``, ``3: (ab, bc, ca)`` (the middle one), all oriented like the parent.

    Attributes:
      vertices: ``[V + E, 3]`` fine positions.
      faces: ``[4F, 3]`` fine faces (int64).
      edge_vertices: ``[E, 2]`` the two coarse parents of each new vertex (int64).
      face_parent: ``[4F]`` coarse face of each fine face (int64).
    """

    vertices: Float[ArrayLike, "Vf 3"]
    faces: Int[ArrayLike, "Ff 3"]
    edge_vertices: Int[ArrayLike, "E 2"]
    face_parent: Int[ArrayLike, " Ff"]

    def upsample(self, values: np.ndarray) -> np.ndarray:
        """Carry per-vertex values ``[V, ...]`` to the fine mesh: new vertices get the parents' mean.

        Example:
          >>> from jmeshtex.data import single_triangle
          >>> s = subdivide_midpoint(*single_triangle())
          >>> s.upsample(np.array([0.0, 1.0, 2.0])).tolist()
          [0.0, 1.0, 2.0, 0.5, 1.0, 1.5]
        """
        values = np.asarray(values)
        n_coarse = len(self.vertices) - len(self.edge_vertices)
        if values.shape[:1] != (n_coarse,):
            raise InputError(
                f"upsample expects one value per coarse vertex, shape [{n_coarse}, ...], got {values.shape}"
            )
        mids = 0.5 * (values[self.edge_vertices[:, 0]] + values[self.edge_vertices[:, 1]])
        return np.concatenate([values, mids.astype(values.dtype, copy=False)])


@accepts_mesh
def subdivide_midpoint(
    vertices: Float[ArrayLike, "V 3"], faces: Int[ArrayLike, "F 3"]
) -> Subdivision:
    """Split every triangle into four at its edge midpoints (DGTS, Hertz et al. 2020, §3.3).

    .. math:: v_{V+e} = \\tfrac12 (v_i + v_j) \\quad \\text{for edge } e = (i, j), \\qquad
              (a, b, c) \\mapsto (a, m_{ab}, m_{ca}),\\ (m_{ab}, b, m_{bc}),\\ (m_{ca}, m_{bc}, c),\\
              (m_{ab}, m_{bc}, m_{ca})

    Every child keeps its parent's orientation; ``V' = V + E``, ``F' = 4F``, the Euler characteristic
    and (since the children are coplanar with their parent) the surface and its area are unchanged.
    Edges shared by two faces get one midpoint, so the fine mesh is as connected as the coarse one.

    Args:
      vertices: ``[V, 3]`` positions (any frame).
      faces: ``[F, 3]`` triangles.

    Returns:
      :class:`Subdivision` with the fine mesh and the parent maps (numbering documented there).

    Raises:
      MeshError: (``NonTriangleFaceError``, ``EmptyMeshError``, ``FaceIndexError``,
        ``NonFiniteVertexError``) malformed input; InputError for other bad arguments.

    Example:
      >>> from jmeshtex.data import single_triangle
      >>> s = subdivide_midpoint(*single_triangle())
      >>> s.vertices.shape, s.faces.shape, s.edge_vertices.tolist()
      ((6, 3), (4, 3), [[0, 1], [0, 2], [1, 2]])
      >>> s.faces.tolist(), s.face_parent.tolist()
      ([[0, 3, 4], [3, 1, 5], [4, 5, 2], [3, 5, 4]], [0, 0, 0, 0])
    """
    v, f = check_mesh_arrays(vertices, faces)
    n_vertices, n_faces = len(v), len(f)
    edges, face_edges = unique_edges(f, n_vertices, face_edges=True)
    mids = 0.5 * (v[edges[:, 0]] + v[edges[:, 1]])
    a, b, c = f.T
    ab, bc, ca = (face_edges + n_vertices).T
    fine_faces = np.concatenate(
        [np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))]
    )
    return Subdivision(
        vertices=np.concatenate([v, mids]),
        faces=fine_faces,
        edge_vertices=edges,
        face_parent=np.tile(np.arange(n_faces, dtype=np.int64), 4),
    )


def subdivide_uv(uv: Float[ArrayLike, "F 3 2"]) -> Float[ArrayLike, "4*F 3 2"]:
    """Per-corner texture coordinates of the faces :func:`subdivide_midpoint` makes.

    Each child corner gets the mean of its parent face's two corner UVs (or the corner's own UV), so
    UV seams stay where they were: a midpoint on a seam edge gets a different UV in each of its faces.

    .. math:: uv(m_{ab}) = \\tfrac12 (uv_a + uv_b) \\text{ within face } (a, b, c)

    Args:
      uv: ``[F, 3, 2]`` per-corner UVs of the coarse faces.

    Returns:
      ``[4F, 3, 2]`` per-corner UVs, in the fine face order of :class:`Subdivision`.

    Example:
      >>> uv = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]])
      >>> subdivide_uv(uv)[3].tolist()  # the middle child
      [[0.5, 0.0], [0.5, 0.5], [0.0, 0.5]]
    """
    uv = np.asarray(uv)
    if uv.ndim != 3 or uv.shape[1:] != (3, 2) or not np.issubdtype(uv.dtype, np.number):
        raise InputError(
            f"uv must be per-corner texture coordinates of shape [F, 3, 2], got {uv.shape}"
        )
    uv = uv.astype(np.float64, copy=False)
    a, b, c = uv[:, 0], uv[:, 1], uv[:, 2]
    ab, bc, ca = 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)
    return np.concatenate(
        [np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))]
    )


@accepts_mesh
def rescale_to_mean_edge(
    vertices: Float[ArrayLike, "V 3"], faces: Int[ArrayLike, "F 3"], target: float = 1.0
) -> tuple[Float[ArrayLike, "V 3"], float]:
    """Scale a mesh about the origin so that its mean edge length is ``target``.

    .. math:: v' = s\\, v, \\qquad s = \\text{target} / \\overline{\\lVert v_i - v_j \\rVert}

    Neighbourhood radii and HKS times are in mesh units; rescaling first makes hyper-parameters
    mean the same thing on every mesh (DGTS normalises its meshes the same way).

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` triangles.
      target: the wanted mean edge length, > 0.

    Returns:
      ``(vertices [V, 3] float64, scale)``; multiply lengths by ``scale`` to compare with the input.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, s = rescale_to_mean_edge(*grid(4), target=2.0)
      >>> round(mean_edge_length(v, grid(4).faces), 12), s > 1
      (2.0, True)
    """
    if not (np.isfinite(target) and target > 0):
        raise InputError(f"target mean edge length must be a positive number, got {target}")
    v, f = check_mesh_arrays(vertices, faces)
    mean = mean_edge_length(v, f)
    if mean == 0.0:
        raise InputError("cannot rescale: every edge has zero length (all vertices coincide)")
    scale = float(target) / mean
    return v * scale, scale

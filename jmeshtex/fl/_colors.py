"""Colour sources on a mesh surface: a UV texture (bilinear lookup) or vertex colours (barycentric).

The FL-VAE encoder reads colours at points of each one-ring; :class:`SurfaceColors` answers "which
colour lies at this surface point" for points given either by (face, barycentric coordinates) on the
mesh it was built from, or by 3D positions anywhere near it (closest point, then the same lookup) —
the second form lets a re-triangulated copy of a textured mesh be encoded with the original colours.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._types import Float, Int
from ..geometry import sample_texture, uv_at


def _rgb(values: np.ndarray) -> np.ndarray:
    """``[..., C]`` colours → ``[..., 3]`` float64 RGB (grey is repeated, alpha dropped)."""
    values = np.asarray(values, dtype=np.float64)
    c = values.shape[-1]
    if c == 1 or c == 2:  # grey (+ alpha)
        return np.repeat(values[..., :1], 3, axis=-1)
    return values[..., :3]


@dataclasses.dataclass(frozen=True, eq=False)
class SurfaceColors:
    """A host-side colour field on a triangle mesh.

    Attributes:
      vertices: ``[V, 3]`` float64 positions of the (merged) mesh.
      faces: ``[F, 3]`` int64 faces.
      uv: ``[F, 3, 2]`` per-corner texture coordinates, or None (vertex colours).
      texture: ``[H, W, 3]`` float64 RGB texture in [0, 1], or None.
      vertex_colors: ``[V, 3]`` float64 RGB, or None (texture).
    """

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray | None = None
    texture: np.ndarray | None = None
    vertex_colors: np.ndarray | None = None

    @property
    def source(self) -> str:
        """``"texture"`` or ``"vertex_colors"``."""
        return "texture" if self.texture is not None else "vertex_colors"

    def at_barycentric(
        self, face: Int[np.ndarray, " N"], bary: Float[np.ndarray, "N 3"]
    ) -> Float[np.ndarray, "N 3"]:
        """Colours at points given by face and barycentric coordinates (corner order of ``faces``).

        Texture: bilinear lookup at ``uv(p) = Σ_k b_k uv_{f,k}``; vertex colours: ``Σ_k b_k c_{f_k}``.

        Args:
          face: ``[...N]`` face of each point.
          bary: ``[...N, 3]`` barycentric coordinates in that face.

        Returns:
          ``[...N, 3]`` float64 RGB.

        Example:
          >>> import numpy as np
          >>> from jmeshtex import Mesh
          >>> m = Mesh(np.eye(3), np.array([[0, 1, 2]]), vertex_colors=np.eye(3, dtype=np.float32))
          >>> surface_colors(m).at_barycentric(np.array([0]), np.array([[0.5, 0.5, 0.0]])).tolist()
          [[0.5, 0.5, 0.0]]
        """
        face = np.asarray(face)
        bary = np.asarray(bary, dtype=np.float64)
        if bary.shape != (*face.shape, 3):
            raise InputError(
                f"bary must have shape face.shape + (3,) = {(*face.shape, 3)}, got {bary.shape}"
            )
        if face.size and (face.min() < 0 or face.max() >= len(self.faces)):
            raise InputError(
                f"face indices must lie in [0, {len(self.faces)}), got {face.min()}..{face.max()}"
            )
        if self.texture is not None:
            return sample_texture(self.texture, uv_at(self.uv, face, bary), mode="bilinear")
        corners = self.vertex_colors[self.faces[face]]  # [..., 3, 3]
        return np.einsum("...k,...kc->...c", bary, corners)

    def at_points(self, points: Float[np.ndarray, "N 3"]) -> Float[np.ndarray, "N 3"]:
        """Colours at arbitrary 3D points: closest point on this mesh, then :meth:`at_barycentric`.

        Args:
          points: ``[N, 3]`` positions (e.g. vertices or samples of a re-triangulated copy).

        Returns:
          ``[N, 3]`` float64 RGB.

        Example:
          >>> import numpy as np
          >>> from jmeshtex import Mesh
          >>> m = Mesh(np.eye(3), np.array([[0, 1, 2]]), vertex_colors=np.eye(3, dtype=np.float32))
          >>> surface_colors(m).at_points(np.array([[1.0, 1.0, 1.0]])).round(6).tolist()  # centroid
          [[0.333333, 0.333333, 0.333333]]
        """
        face, bary = self.closest(points)
        return self.at_barycentric(face, bary)

    def closest(
        self, points: Float[np.ndarray, "N 3"]
    ) -> tuple[Int[np.ndarray, " N"], Float[np.ndarray, "N 3"]]:
        """Closest point on the mesh as ``(face [N], bary [N, 3])`` (libigl AABB tree)."""
        import igl

        points = np.asarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3 or not np.isfinite(points).all():
            raise InputError(f"points must be a finite [N, 3] array, got shape {points.shape}")
        if len(points) == 0:
            return np.zeros(0, np.int64), np.zeros((0, 3))
        _, face, closest = igl.point_mesh_squared_distance(points, self.vertices, self.faces)
        face = np.asarray(face, dtype=np.int64)
        return face, _barycentric(closest, self.vertices[self.faces[face]])


def _barycentric(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Barycentric coordinates ``[N, 3]`` of points ``p [N, 3]`` in triangles ``tri [N, 3, 3]``."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, p - a
    d00 = np.einsum("nd,nd->n", v0, v0)
    d01 = np.einsum("nd,nd->n", v0, v1)
    d11 = np.einsum("nd,nd->n", v1, v1)
    d20 = np.einsum("nd,nd->n", v2, v0)
    d21 = np.einsum("nd,nd->n", v2, v1)
    den = d00 * d11 - d01 * d01
    den = np.where(np.abs(den) > 0, den, 1.0)
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    bary = np.clip(np.stack([1.0 - v - w, v, w], axis=1), 0.0, 1.0)
    return bary / np.maximum(bary.sum(1, keepdims=True), 1e-300)


def surface_colors(mesh: Mesh) -> SurfaceColors:
    """The colour source of a mesh: its UV texture if it has one, else its vertex colours.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` with ``texture`` and ``uv``, or with ``vertex_colors``.

    Returns:
      :class:`SurfaceColors` over the mesh's merged geometry.

    Raises:
      InputError: the mesh has neither a texture with UVs nor vertex colours.

    Example:
      >>> import numpy as np
      >>> from jmeshtex import Mesh
      >>> surface_colors(Mesh(np.eye(3), np.array([[0, 1, 2]]), vertex_colors=np.ones((3, 3)))).source
      'vertex_colors'
    """
    mesh = as_mesh(mesh, what="mesh")
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if mesh.texture is not None and mesh.uv is not None:
        tex = np.asarray(mesh.texture)
        if tex.ndim == 2:
            tex = tex[..., None]
        uv = np.asarray(mesh.uv, dtype=np.float64)
        if uv.shape != (len(faces), 3, 2):
            raise InputError(
                f"mesh.uv must have shape [F, 3, 2] = ({len(faces)}, 3, 2), got {uv.shape}"
            )
        return SurfaceColors(vertices, faces, uv=uv, texture=_rgb(tex))
    if mesh.vertex_colors is not None:
        colors = np.asarray(mesh.vertex_colors)
        if colors.ndim != 2 or len(colors) != len(vertices):
            raise InputError(
                f"mesh.vertex_colors must have shape [V, C] with V = {len(vertices)}, got {colors.shape}"
            )
        return SurfaceColors(vertices, faces, vertex_colors=_rgb(colors))
    if mesh.texture is not None:
        raise InputError(
            "the mesh has a texture but no UV coordinates, so its colours cannot be read on the surface. "
            "Fix: load a mesh with UVs (mesh.uv [F, 3, 2]) or pass vertex_colors"
        )
    raise InputError(
        "the mesh has neither a UV texture nor vertex colours: nothing to encode. Fix: load a textured "
        "mesh (texture + uv), set Mesh.vertex_colors, or pass colors=SurfaceColors(...) explicitly"
    )

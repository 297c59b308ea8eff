"""The host-side mesh record shared by I/O, geometry and the methods."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np


@dataclasses.dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh with optional UV texture and vertex colours (host side, NumPy).

    Geometry always sees the *merged* surface: files that split vertices along UV seams are merged
    by position, and ``split_faces`` / ``split_to_merged`` keep the stored indexing so the mesh can be
    written back with its seams.

    Attributes:
      vertices: ``[V, 3]`` float64 positions of the merged surface.
      faces: ``[F, 3]`` int64 vertex indices, counter-clockwise seen from outside.
      uv: ``[F, 3, 2]`` float64 per-corner texture coordinates (u right, v up, in [0, 1]), or None.
      texture: ``[H, W, C]`` float32 image in [0, 1], row 0 at the top (v = 1), or None.
      vertex_colors: ``[V, C]`` float32 colours in [0, 1] (C = 3 or 4), or None.
      split_faces: ``[F, 3]`` int64 faces in the stored (seam-split) indexing, or None if not split.
      split_to_merged: ``[V_stored]`` int64 merged vertex of each stored vertex, or None.
      name: a short name used for file names of materials/textures on save.

    Example:
      >>> import numpy as np
      >>> m = Mesh(np.eye(3), np.array([[0, 1, 2]]))
      >>> m.num_vertices, m.num_faces
      (3, 1)
    """

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray | None = None
    texture: np.ndarray | None = None
    vertex_colors: np.ndarray | None = None
    split_faces: np.ndarray | None = None
    split_to_merged: np.ndarray | None = None
    name: str = "mesh"

    @property
    def num_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def num_faces(self) -> int:
        return int(self.faces.shape[0])

    @property
    def has_uv(self) -> bool:
        return self.uv is not None

    @property
    def has_texture(self) -> bool:
        return self.texture is not None

    def __iter__(self):
        """Unpack as the ``(vertices, faces)`` pair: ``v, f = mesh``.

        Host geometry functions take that pair; unpacking lets a ``Mesh`` stand wherever one is
        expected (``geometry.face_areas(*mesh)``), and ``Mesh(*mesh)`` keeps the geometry only.
        """
        return iter((self.vertices, self.faces))

    def replace(self, **changes) -> Mesh:
        """A copy with some fields replaced (the original is never modified)."""
        return dataclasses.replace(self, **changes)


def as_mesh(mesh: Mesh | tuple, *, what: str = "mesh") -> Mesh:
    """``mesh`` as a :class:`Mesh`: a ``Mesh`` is returned as it is, a ``(vertices, faces)`` pair wrapped.

    Every method function that takes a mesh goes through this, so a ``Mesh`` and a pair are both
    accepted everywhere; anything else raises :class:`~jmeshtex.InputError` naming the argument.

    Args:
      mesh: a :class:`Mesh`, or a pair ``(vertices [V, 3], faces [F, 3])``.
      what: the argument's name, for the error message.

    Example:
      >>> import numpy as np
      >>> as_mesh((np.eye(3), np.array([[0, 1, 2]]))).num_faces
      1
    """
    from ._errors import InputError
    from ._mesh_arrays import coerce_faces, coerce_vertices

    if isinstance(mesh, Mesh):
        if isinstance(mesh.vertices, np.ndarray) and isinstance(mesh.faces, np.ndarray):
            return mesh
        # lists (ragged ones included) become arrays here, or a typed error naming the problem
        return mesh.replace(vertices=coerce_vertices(mesh.vertices), faces=coerce_faces(mesh.faces))
    if isinstance(mesh, (tuple, list)) and len(mesh) == 2:
        try:
            v, f = (np.asarray(x) for x in mesh)
        except ValueError:  # a ragged nested list: the coercions name the bad rows
            coerce_vertices(mesh[0])
            coerce_faces(mesh[1])
            raise InputError(f"{what}: vertices and faces must be arrays") from None
        if v.ndim == 2 and v.shape[-1] == 3 and f.ndim == 2 and f.shape[-1] == 3:
            return Mesh(v.astype(np.float64), f.astype(np.int64))
        raise InputError(
            f"{what}: a (vertices, faces) pair needs shapes [V, 3] and [F, 3], got "
            f"{v.shape} and {f.shape}"
        )
    raise InputError(
        f"{what} must be a jmeshtex.Mesh or a (vertices, faces) pair, got {type(mesh).__name__}"
        " (load a file with jmeshtex.io.load_mesh, or build one with jmeshtex.data)"
    )


def accepts_mesh(fn):
    """Let a host function of ``(vertices, faces, ...)`` take a :class:`Mesh` in their place.

    ``f(mesh, ...)`` is ``f(mesh.vertices, mesh.faces, ...)``; a call with arrays is unchanged.
    (A bare ``(vertices, faces)`` tuple is not unpacked here: write ``f(*pair)``.)

    Example:
      >>> @accepts_mesh
      ... def count(vertices, faces, scale=1):
      ...     return scale * (len(vertices) + len(faces))
      >>> mesh = Mesh(np.eye(3), np.array([[0, 1, 2]]))
      >>> count(mesh, scale=2), count(mesh.vertices, mesh.faces)
      (8, 4)
    """

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        if args and isinstance(args[0], Mesh):
            args = (args[0].vertices, args[0].faces, *args[1:])
        return fn(*args, **kwargs)

    return wrapper


def accepts_mesh_faces(fn):
    """Let a host function of ``(faces, num_vertices, ...)`` take a :class:`Mesh` in their place.

    Example:
      >>> @accepts_mesh_faces
      ... def unused(faces, num_vertices):
      ...     return num_vertices - len(np.unique(faces))
      >>> unused(Mesh(np.zeros((4, 3)), np.array([[0, 1, 2]])))
      1
    """

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        if args and isinstance(args[0], Mesh):
            args = (args[0].faces, len(args[0].vertices), *args[1:])
        return fn(*args, **kwargs)

    return wrapper

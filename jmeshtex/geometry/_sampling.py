"""Uniform random points on a triangle mesh and barycentric interpolation of per-vertex values."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Float, Int, Shaped

from .._config import is_int
from .._errors import EmptyMeshError, FaceIndexError, InputError, NonTriangleFaceError
from .._mesh import accepts_mesh
from .._random import check_key, host_rng
from .._triangles import triangle_areas
from .._types import ArrayLike


class SurfaceSamples(NamedTuple):
    """Points on a mesh surface.

    Attributes:
      face: ``[N]`` int32 face of each point.
      bary: ``[N, 3]`` float64 barycentric coordinates in that face (corner order of ``faces``).
      point: ``[N, 3]`` float64 positions.
    """

    face: Int[np.ndarray, " N"]
    bary: Float[np.ndarray, "N 3"]
    point: Float[np.ndarray, "N 3"]


def _generator(key, rng) -> np.random.Generator:
    if (key is None) == (rng is None):
        raise InputError(
            "pass exactly one of key= (a jax.random.key) or rng= (a numpy.random.Generator); jmeshtex "
            "uses no global random state"
        )
    if rng is not None:
        if not isinstance(rng, np.random.Generator):
            raise InputError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        return rng
    return host_rng(check_key(key))


@accepts_mesh
def sample_surface(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    n: int,
    *,
    key=None,
    rng: np.random.Generator | None = None,
) -> SurfaceSamples:
    """Draw ``n`` points uniformly with respect to surface area.

    A face is chosen with probability ``A_f / Σ A`` (inverse CDF: cumulative sum of areas and
    ``searchsorted``), then a point uniformly inside it by the square-root trick (Osada et al.
    2002, "Shape distributions", §4.2): with ``u, v ~ U[0, 1)`` and ``s = √u``,

    .. math:: b = (1 - s,\\; s (1 - v),\\; s v).

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` triangles; zero-area faces are never drawn.
      n: number of points, ``>= 0``.
      key: a :func:`jax.random.key` to draw from (give this or ``rng``).
      rng: a ``numpy.random.Generator`` to draw from (advanced in place).

    Returns:
      :class:`SurfaceSamples` ``(face [N], bary [N, 3], point [N, 3])``.

    Raises:
      InputError: bad ``n``, neither or both of ``key`` / ``rng``, a mesh of zero total area.
      FaceIndexError, NonTriangleFaceError, EmptyMeshError: a malformed mesh.

    Example:
      >>> from jmeshtex.data import grid
      >>> import jax
      >>> s = sample_surface(*grid(2), 4, key=jax.random.key(0))
      >>> s.point.shape, bool(np.all((s.point[:, :2] >= 0) & (s.point[:, :2] <= 1)))
      ((4, 3), True)
      >>> bool(np.allclose(s.bary.sum(1), 1.0))
      True
    """
    generator = _generator(key, rng)
    vertices = np.asarray(vertices, dtype=np.float64)
    faces_in = np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise InputError(f"vertices must have shape [V, 3], got {vertices.shape}")
    if faces_in.ndim != 2 or faces_in.shape[1] != 3:
        raise NonTriangleFaceError(f"faces must be triangles, shape [F, 3], got {faces_in.shape}")
    if len(faces_in) == 0 or len(vertices) == 0:
        raise EmptyMeshError()
    if not np.issubdtype(faces_in.dtype, np.integer):
        raise InputError(f"faces must hold integer vertex indices, got dtype {faces_in.dtype}")
    faces = faces_in.astype(np.int64)
    bad = np.nonzero((faces < 0).any(1) | (faces >= len(vertices)).any(1))[0]
    if bad.size:
        raise FaceIndexError(indices=bad)
    if not is_int(n, 0):
        raise InputError(f"n must be a non-negative int, got {n!r}")

    tri = vertices[faces]
    area = triangle_areas(tri)
    cdf = np.cumsum(area)
    total = cdf[-1]
    if not (np.isfinite(total) and total > 0):
        raise InputError(f"the mesh's total area is {total}; cannot sample a surface without area")
    # side="right" never selects a zero-area face (its CDF step has zero width)
    face = np.searchsorted(cdf, generator.random(n) * total, side="right")
    face = np.minimum(face, len(faces) - 1)
    u, v = generator.random((2, n))
    s = np.sqrt(u)
    bary = np.stack([1.0 - s, s * (1.0 - v), s * v], axis=1)
    point = np.einsum("nk,nkd->nd", bary, tri[face])
    return SurfaceSamples(face=face.astype(np.int32), bary=bary, point=point)


def barycentric_interpolate(
    values: Shaped[ArrayLike, "V ..."],
    faces: Int[ArrayLike, "F 3"],
    face: Int[ArrayLike, " *N"],
    bary: Float[ArrayLike, "*N 3"],
) -> Shaped[ArrayLike, "..."]:
    """Interpolate per-vertex values at points given by face and barycentric coordinates.

    .. math:: x(p) = \\sum_{k=0}^{2} b_k\\, x_{F_{f,k}}

    NumPy in, NumPy out; JAX arrays in (any argument) give a JAX result, differentiable in
    ``values`` and ``bary`` and safe under ``jit``. The result has ``values``' dtype (the weights are
    cast to it), so float32 features stay float32.

    Args:
      values: ``[V, ...]`` per-vertex values (positions, colours, features, complex allowed).
      faces: ``[F, 3]`` triangles.
      face: ``[...N]`` face of each point.
      bary: ``[...N, 3]`` barycentric coordinates in that face.

    Returns:
      ``[...N, ...]`` interpolated values.

    Raises:
      InputError: mismatching shapes (host arrays also: face indices out of range).

    Example:
      >>> from jmeshtex.data import single_triangle
      >>> v, f = single_triangle()
      >>> barycentric_interpolate(v, f, np.array([0]), np.array([[0.5, 0.25, 0.25]])).tolist()
      [[0.25, 0.25, 0.0]]
    """
    use_jax = any(isinstance(a, jax.Array) for a in (values, faces, face, bary))
    xp = jnp if use_jax else np
    values = xp.asarray(values)
    faces = xp.asarray(faces)
    face = xp.asarray(face)
    bary = xp.asarray(bary)
    if values.ndim < 1:
        raise InputError(
            f"values must have a leading vertex axis [V, ...], got shape {values.shape}"
        )
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise InputError(f"faces must have shape [F, 3], got {faces.shape}")
    if bary.shape != (*face.shape, 3):
        raise InputError(
            f"bary must have shape face.shape + (3,) = {(*face.shape, 3)}, got {bary.shape}"
        )
    if not use_jax:
        if not np.issubdtype(face.dtype, np.integer):
            raise InputError(f"face must hold integer face indices, got dtype {face.dtype}")
        if face.size and (face.min() < 0 or face.max() >= len(faces)):
            raise InputError(
                f"face indices must lie in [0, {len(faces)}), got {face.min()}..{face.max()}"
            )
        if faces.size and (faces.min() < 0 or faces.max() >= len(values)):
            raise InputError(f"faces reference vertices outside [0, {len(values)})")
    if not xp.issubdtype(values.dtype, xp.inexact):  # integer / bool values interpolate as floats
        values = values.astype(bary.dtype)
    corners = values[faces[face]]  # [*N, 3, *C]
    weights = bary.astype(values.dtype).reshape(*bary.shape, *([1] * (values.ndim - 1)))
    return (weights * corners).sum(axis=face.ndim)

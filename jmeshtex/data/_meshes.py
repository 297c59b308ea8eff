"""Procedural meshes: the package's embedded default geometry (no files, no network).

All meshes are consistently oriented (counter-clockwise seen from outside / from +z), manifold, and
returned as a :class:`jmeshtex.Mesh` (vertices ``[V, 3]`` float64, faces ``[F, 3]`` int64) named after
the builder. A ``Mesh`` unpacks as its ``(vertices, faces)`` pair, so ``v, f = icosphere(2)`` works
too.
"""

from __future__ import annotations

import numpy as np

from .._config import is_int
from .._errors import InputError
from .._mesh import Mesh


def single_triangle() -> Mesh:
    """The right triangle (0,0,0), (1,0,0), (0,1,0) in the z = 0 plane.

    Example:
      >>> v, f = single_triangle()
      >>> v.shape, f.tolist()
      ((3, 3), [[0, 1, 2]])
    """
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    return Mesh(v, np.array([[0, 1, 2]], dtype=np.int64), name="single_triangle")


def icosahedron(radius: float = 1.0) -> Mesh:
    """The regular icosahedron inscribed in a sphere of ``radius`` (12 vertices, 20 faces).

    Every edge has length ``radius / sin(2π/5)``; every vertex has 5 neighbours at equal angles.

    Example:
      >>> v, f = icosahedron()
      >>> v.shape, f.shape, bool(np.allclose(np.linalg.norm(v, axis=1), 1.0))
      ((12, 3), (20, 3), True)
    """
    t = (1.0 + 5.0**0.5) / 2.0
    v = np.array(
        [
            [-1, t, 0],
            [1, t, 0],
            [-1, -t, 0],
            [1, -t, 0],
            [0, -1, t],
            [0, 1, t],
            [0, -1, -t],
            [0, 1, -t],
            [t, 0, -1],
            [t, 0, 1],
            [-t, 0, -1],
            [-t, 0, 1],
        ],
        dtype=np.float64,
    )
    v *= radius / np.linalg.norm(v[0])
    f = np.array(
        [
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ],
        dtype=np.int64,
    )
    return Mesh(v, f, name="icosahedron")


def icosphere(subdivisions: int = 2, radius: float = 1.0) -> Mesh:
    """A geodesic sphere: the icosahedron midpoint-subdivided ``subdivisions`` times, projected.

    ``V = 10·4^s + 2``, ``F = 20·4^s``.

    Example:
      >>> v, f = icosphere(1)
      >>> v.shape, f.shape
      ((42, 3), (80, 3))
    """
    from ..geometry import subdivide_midpoint  # lazy: geometry may import data

    v, f = icosahedron(1.0)
    for _ in range(subdivisions):
        v, f = subdivide_midpoint(v, f)[:2]
        v /= np.linalg.norm(v, axis=1, keepdims=True)
    return Mesh(v * radius, f, name="icosphere")


def grid(
    nx: int = 8,
    ny: int | None = None,
    *,
    size: tuple[float, float] = (1.0, 1.0),
    diagonals: str = "alternate",
) -> Mesh:
    """A flat triangulated rectangle in the z = 0 plane with ``nx × ny`` cells.

    Args:
      nx, ny: cells along x and y (``ny`` defaults to ``nx``).
      size: side lengths (x, y); the sheet spans ``[0, size_x] × [0, size_y]``.
      diagonals: ``"alternate"`` (checkerboard of diagonal directions, interior vertices of degree 4
        or 8), ``"uniform"`` (all diagonals parallel, degree 6 inside, a regular triangulation).

    Returns:
      vertices ``[(nx+1)(ny+1), 3]`` (vertex ``i + j (nx+1)`` at column i, row j) and faces
      ``[2 nx ny, 3]`` counter-clockwise seen from +z.

    Example:
      >>> v, f = grid(2, 3)
      >>> v.shape, f.shape
      ((12, 3), (12, 3))
    """
    ny = nx if ny is None else ny
    if not (is_int(nx, 1) and is_int(ny, 1)):
        raise InputError(
            f"grid: nx and ny (cells each way) must be integers >= 1, got nx={nx!r}, ny={ny!r}"
        )
    if diagonals not in ("alternate", "uniform"):
        raise InputError(f"grid: diagonals must be 'alternate' or 'uniform', got {diagonals!r}")
    xs = np.linspace(0.0, size[0], nx + 1)
    ys = np.linspace(0.0, size[1], ny + 1)
    X, Y = np.meshgrid(xs, ys)
    v = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    i, j = i.ravel(), j.ravel()
    v00 = i + j * (nx + 1)
    v10, v01, v11 = v00 + 1, v00 + nx + 1, v00 + nx + 2
    flip = ((i + j) % 2 == 1) if diagonals == "alternate" else np.zeros_like(i, bool)
    t1 = np.where(flip[:, None], np.stack([v00, v10, v01], 1), np.stack([v00, v10, v11], 1))
    t2 = np.where(flip[:, None], np.stack([v10, v11, v01], 1), np.stack([v00, v11, v01], 1))
    return Mesh(v, np.concatenate([t1, t2]).astype(np.int64), name="grid")


def torus(
    n_major: int = 24, n_minor: int = 12, *, major_radius: float = 1.0, minor_radius: float = 0.35
) -> Mesh:
    """A torus of revolution around z (genus 1), triangulated with alternating diagonals.

    Unlike ``trimesh.creation.torus`` no cotangent weight vanishes identically (no split quads with
    right angles on both sides).

    Example:
      >>> v, f = torus(8, 6)
      >>> v.shape, f.shape
      ((48, 3), (96, 3))
    """
    if not (is_int(n_major, 3) and is_int(n_minor, 3)):
        raise InputError(
            f"torus: n_major and n_minor (segments around each circle) must be integers >= 3, "
            f"got {n_major!r}, {n_minor!r}"
        )
    u = np.arange(n_major) * 2 * np.pi / n_major
    w = np.arange(n_minor) * 2 * np.pi / n_minor
    U, W = np.meshgrid(u, w, indexing="ij")
    # shift alternate minor rings by half a step so triangles are not right-angled
    W = W + (np.arange(n_major)[:, None] % 2) * (np.pi / n_minor)
    r = major_radius + minor_radius * np.cos(W)
    v = np.stack([r * np.cos(U), r * np.sin(U), minor_radius * np.sin(W)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_major), np.arange(n_minor), indexing="ij")
    i, j = i.ravel(), j.ravel()
    idx = lambda a, b: (a % n_major) * n_minor + (b % n_minor)  # noqa: E731
    a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
    odd = (i % 2 == 1)[:, None]
    t1 = np.where(odd, np.stack([a, b, d], 1), np.stack([a, b, c], 1))
    t2 = np.where(odd, np.stack([b, c, d], 1), np.stack([a, c, d], 1))
    return Mesh(v, np.concatenate([t1, t2]).astype(np.int64), name="torus")

"""Procedural meshes with a known texture: geometric (bumps) or colour (stripes).

They are the embedded references of the methods' demos, learning checks and notebooks; each texture
has a closed form, so a test can compare a method's output with the truth.
"""

from __future__ import annotations

import numpy as np

from .._mesh import Mesh
from .._types import Float
from ._meshes import icosphere


def fibonacci_sphere(n: int) -> Float[np.ndarray, "n 3"]:
    """``n`` nearly uniform unit vectors on the Fibonacci (golden-angle) lattice.

    Example:
      >>> p = fibonacci_sphere(10)
      >>> p.shape, bool(np.allclose(np.linalg.norm(p, axis=1), 1))
      ((10, 3), True)
    """
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5**0.5) * i
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def bumpy_sphere(
    *, subdivisions: int = 4, bumps: int = 40, height: float = 0.12, width: float = 0.12
) -> Mesh:
    """A unit icosphere with Gaussian bumps centred on a Fibonacci lattice (a procedural texture).

    .. math:: v \\mapsto v\\,\\Big(1 + h \\sum_j \\exp\\big(-\\tfrac{\\lVert v - c_j\\rVert^2}{2 w^2}\\big)\\Big)

    Example:
      >>> v, f = bumpy_sphere(subdivisions=2, bumps=12)
      >>> v.shape, f.shape, bool(np.linalg.norm(v, axis=1).max() > 1.1)
      ((162, 3), (320, 3), True)
    """
    v, f = icosphere(subdivisions)
    c = fibonacci_sphere(bumps)
    d2 = np.sum((v[:, None, :] - c[None]) ** 2, axis=-1)
    r = 1 + height * np.exp(-d2 / (2 * width**2)).sum(axis=1)
    return Mesh(v * r[:, None], f, name="bumpy_sphere")


def striped_sphere(*, subdivisions: int = 3, frequency: float = 9.0) -> Mesh:
    """An icosphere with latitudinal stripes as vertex colours (dark blue / light yellow).

    Example:
      >>> m = striped_sphere(subdivisions=1)
      >>> m.num_vertices, m.vertex_colors.shape
      (42, (42, 3))
    """
    v, f = icosphere(subdivisions)
    s = stripe_intensity(v, frequency=frequency)
    return Mesh(v, f, vertex_colors=intensity_to_rgb(s).astype(np.float32), name="striped_sphere")


def stripe_intensity(
    points: Float[np.ndarray, "N 3"], *, frequency: float = 9.0
) -> Float[np.ndarray, " N"]:
    """``s = ½ + ½ sin(ω z)`` in [0, 1]."""
    return 0.5 + 0.5 * np.sin(frequency * np.asarray(points)[:, 2])


def intensity_to_rgb(s: Float[np.ndarray, " N"]) -> Float[np.ndarray, "N 3"]:
    """Map an intensity in [0, 1] to a dark-blue → light-yellow colour ramp."""
    lo, hi = np.array([0.10, 0.15, 0.45]), np.array([0.98, 0.90, 0.55])
    s = np.clip(np.asarray(s, np.float64), 0, 1)[:, None]
    return (1 - s) * lo + s * hi


def rgb_to_intensity(rgb: Float[np.ndarray, "N 3"]) -> Float[np.ndarray, " N"]:
    """Inverse of :func:`intensity_to_rgb` (least squares along the ramp)."""
    lo, hi = np.array([0.10, 0.15, 0.45]), np.array([0.98, 0.90, 0.55])
    d = hi - lo
    return np.clip((np.asarray(rgb, np.float64) - lo) @ d / (d @ d), 0, 1)


def coloured_sphere_pair(subdivisions: int = 3) -> tuple[Mesh, Mesh, Float[np.ndarray, "Vt 3"]]:
    """A bumpy sphere with a procedural colour field (source) and its subdivided copy (target).

    The colour transfer test case with a known answer: the target is the source's icosphere
    subdivided once more and pushed onto the same bumpy surface, and ``truth`` is the source's
    colour field evaluated at the target's vertices.

    Args:
      subdivisions: of the source's icosphere (the target has one more).

    Returns:
      ``(source, target, truth)``: the source :class:`~jmeshtex.Mesh` with ``vertex_colors``, the
      target mesh (4× the faces, no colours) and ``[Vt, 3]`` the colour field at its vertices.

    Example:
      >>> source, target, truth = coloured_sphere_pair(3)
      >>> source.vertex_colors.shape, target.num_vertices, truth.shape
      ((642, 3), 2562, (2562, 3))
    """
    from ..geometry import subdivide_midpoint

    v, f = icosphere(subdivisions)
    fine = subdivide_midpoint(v, f)
    tv = fine.vertices / np.linalg.norm(fine.vertices, axis=1, keepdims=True)

    def bumpy(p):
        r = (
            1
            + 0.25 * np.sin(3 * p[:, 0] + 1) * np.cos(2 * p[:, 1])
            + 0.15 * np.sin(4 * p[:, 2] + 0.5)
        )
        return p * r[:, None]

    def colour(p):
        return np.stack(
            [
                0.5 + 0.4 * np.sin(6 * p[:, 0]) * np.cos(5 * p[:, 1]),
                0.5 + 0.4 * np.sin(7 * p[:, 2] + 1),
                0.5 + 0.3 * np.cos(4 * p[:, 0] + 3 * p[:, 1]),
            ],
            axis=1,
        )

    source = Mesh(bumpy(v), f, vertex_colors=colour(v), name="source")
    return source, Mesh(bumpy(tv), fine.faces, name="target"), colour(tv)

"""Procedural references with a real geometric texture and a known spatial period (DGTS-style).

The paper's references carry relief that repeats over the surface: spikes, knobs, scales, craters.
These functions build such surfaces on a unit sphere, a torus, or any given mesh
(:func:`textured_mesh`, the ground truth a DGTS transfer is scored against): texture centres are spread over the
surface by Poisson-disc sampling with minimum distance ``period`` (so the spacing of neighbouring
centres lies in ``[period, ~1.4 period]``; :func:`texture_centers` returns them), and every vertex
moves along the surface normal by a profile of its distance ``d`` to the nearest centre:

- ``"knobs"``: rounded bumps, ``a·exp(−(d / 0.3p)²)``;
- ``"spikes"``: sharp cones, ``a·max(0, 1 − d / 0.3p)^{2.5}``;
- ``"craters"``: a raised rim around a sunken bowl, ``a·(exp(−((d − 0.3p) / 0.08p)²) − 0.8·exp(−(d / 0.18p)²))``;
- ``"scales"``: overlapping plates, in each centre's Voronoi cell a ramp that rises against a
  fixed direction ``t`` (the tangent towards +z), ``a·clip(0.6 − (x − c)·t / p, 0, 1)``, so each cell
  ends in a step where the next scale starts.

Default amplitudes ``a`` are fractions of the period (0.25, 0.5, 0.2, 0.15). Everything is NumPy and
deterministic for a given ``seed``.
"""

from __future__ import annotations

import numpy as np

from .._config import is_finite_number
from .._errors import InputError
from .._mesh import Mesh
from .._triangles import triangle_areas
from .._types import Float
from ._meshes import icosphere, torus
from ._procedural import fibonacci_sphere

#: the texture kinds of :func:`textured_sphere` / :func:`textured_torus`
GEOMETRIC_TEXTURES = ("spikes", "knobs", "scales", "craters")

_AMPLITUDE = {"knobs": 0.25, "spikes": 0.5, "craters": 0.2, "scales": 0.15}


def _poisson_disc(points: np.ndarray, radius: float, rng: np.random.Generator) -> np.ndarray:
    """Greedy Poisson-disc subset of ``points`` (random order): no two chosen closer than ``radius``."""
    chosen: list[np.ndarray] = []
    for i in rng.permutation(len(points)):
        p = points[i]
        if not chosen or np.min(np.sum((np.asarray(chosen) - p) ** 2, axis=1)) >= radius * radius:
            chosen.append(p)
    return np.asarray(chosen)


def _torus_points(
    n: int, major_radius: float, minor_radius: float, rng: np.random.Generator
) -> np.ndarray:
    """``n`` area-uniform random points on a torus of revolution around z (rejection on the ring radius)."""
    out = []
    while sum(len(o) for o in out) < n:
        u, w = rng.uniform(0, 2 * np.pi, (2, 2 * n))
        keep = rng.uniform(0, 1, 2 * n) < (major_radius + minor_radius * np.cos(w)) / (
            major_radius + minor_radius
        )
        u, w = u[keep], w[keep]
        r = major_radius + minor_radius * np.cos(w)
        out.append(np.stack([r * np.cos(u), r * np.sin(u), minor_radius * np.sin(w)], -1))
    return np.concatenate(out)[:n]


def _nearest(points: np.ndarray, centers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance to, and index of, the nearest centre of every point (blocks of points, low memory)."""
    d = np.empty(len(points))
    nearest = np.empty(len(points), np.int64)
    for s in range(0, len(points), 4096):
        d2 = np.sum((points[s : s + 4096, None, :] - centers[None]) ** 2, axis=-1)
        nearest[s : s + 4096] = np.argmin(d2, axis=1)
        d[s : s + 4096] = np.sqrt(d2[np.arange(len(d2)), nearest[s : s + 4096]])
    return d, nearest


def texture_centers(
    surface: str = "sphere",
    *,
    period: float = 0.35,
    seed: int = 0,
    major_radius: float = 1.0,
    minor_radius: float = 0.35,
) -> Float[np.ndarray, "C 3"]:
    """Texture centres on the unit sphere or a torus: a Poisson-disc set with minimum distance ``period``.

    Args:
      surface: ``"sphere"`` (unit sphere) or ``"torus"`` (around z, radii as given).
      period: the minimum distance between centres (Euclidean, in the surface's units).
      seed: the NumPy seed of the candidate order.
      major_radius, minor_radius: the torus' radii.

    Returns:
      ``[C, 3]`` centres on the surface.

    Example:
      >>> c = texture_centers("sphere", period=0.5)
      >>> d = np.linalg.norm(c[:, None] - c[None], axis=-1) + 9 * np.eye(len(c))
      >>> bool(d.min() >= 0.5), bool(0.5 <= d.min(axis=1).mean() < 0.7)
      (True, True)
    """
    if not is_finite_number(period) or not period > 0:
        raise InputError(
            f"texture_centers: period must be a number > 0 (the spacing of the centres in mesh "
            f"units), got {period!r}"
        )
    rng = np.random.default_rng(seed)
    if surface == "sphere":
        candidates = fibonacci_sphere(max(2000, int(60 / period**2)))
    elif surface == "torus":
        area = 4 * np.pi**2 * major_radius * minor_radius
        candidates = _torus_points(
            max(2000, int(15 * area / period**2)), major_radius, minor_radius, rng
        )
    else:
        raise InputError(
            f"texture_centers: surface must be 'sphere' or 'torus', got {surface!r}; for another "
            "mesh use textured_mesh"
        )
    return _poisson_disc(candidates, float(period), rng)


def texture_height(
    points: Float[np.ndarray, "V 3"],
    normals: Float[np.ndarray, "V 3"],
    centers: Float[np.ndarray, "C 3"],
    *,
    kind: str,
    period: float,
    amplitude: float | None = None,
) -> Float[np.ndarray, " V"]:
    """Height of the texture ``kind`` at ``points`` (module docstring profiles), along ``normals``.

    Example:
      >>> p = np.array([[0.0, 0, 1], [0, 0.3, 0.95]])
      >>> h = texture_height(p, p, np.array([[0.0, 0, 1]]), kind="knobs", period=0.5)
      >>> h.round(3).tolist()  # the top of a knob, and its flank
      [0.125, 0.002]
    """
    if kind not in GEOMETRIC_TEXTURES:
        raise InputError(
            f"texture_height: kind must be one of {', '.join(GEOMETRIC_TEXTURES)}, got {kind!r}"
        )
    p = float(period)
    a = _AMPLITUDE[kind] * p if amplitude is None else float(amplitude)
    d, nearest = _nearest(points, centers)
    if kind == "knobs":
        return a * np.exp(-((d / (0.3 * p)) ** 2))
    if kind == "spikes":
        return a * np.maximum(0.0, 1 - d / (0.3 * p)) ** 2.5
    if kind == "craters":
        return a * (
            np.exp(-(((d - 0.3 * p) / (0.08 * p)) ** 2)) - 0.8 * np.exp(-((d / (0.18 * p)) ** 2))
        )
    # scales: a ramp per Voronoi cell, rising against the tangent towards +z at the cell's centre
    c = centers[nearest]
    up = np.array([0.0, 0.0, 1.0])
    t = up - np.sum(up * normals, axis=1, keepdims=True) * normals
    t_norm = np.linalg.norm(t, axis=1, keepdims=True)
    t = np.where(t_norm > 1e-6, t / np.maximum(t_norm, 1e-12), np.array([1.0, 0.0, 0.0]))
    s = np.sum((points - c) * t, axis=1) / p
    return a * np.clip(0.6 - s, 0.0, 1.0)


def textured_sphere(
    kind: str = "knobs",
    *,
    subdivisions: int = 4,
    period: float = 0.35,
    amplitude: float | None = None,
    seed: int = 0,
) -> Mesh:
    """A unit icosphere carrying the geometric texture ``kind`` with spatial period ``period``.

    .. math:: v \\mapsto v + h(v)\\, n(v),\\qquad n(v) = v

    with ``h`` the profile of the module docstring around centres from :func:`texture_centers`.

    Args:
      kind: one of ``GEOMETRIC_TEXTURES``.
      subdivisions: of the icosphere (4: 5120 faces, mean edge ≈ 0.077, about 4–5 edges per
        period 0.35).
      period: minimum distance between texture centres (unit-sphere units).
      amplitude: relief height; default a fraction of ``period`` (module docstring).
      seed: seed of the centres.

    Returns:
      The :class:`~jmeshtex.Mesh` (name ``"<kind>_sphere"``).

    Example:
      >>> m = textured_sphere("spikes", subdivisions=3, period=0.5)
      >>> m.num_faces, m.name, bool(np.linalg.norm(m.vertices, axis=1).max() > 1.15)
      (1280, 'spikes_sphere', True)
    """
    v, f = icosphere(subdivisions)
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    h = texture_height(
        n,
        n,
        texture_centers("sphere", period=period, seed=seed),
        kind=kind,
        period=period,
        amplitude=amplitude,
    )
    return Mesh(n * (1 + h)[:, None], f, name=f"{kind}_sphere")


def textured_torus(
    kind: str = "knobs",
    *,
    n_major: int = 96,
    n_minor: int = 32,
    period: float = 0.3,
    amplitude: float | None = None,
    seed: int = 0,
    major_radius: float = 1.0,
    minor_radius: float = 0.35,
) -> Mesh:
    """A torus (around z) carrying the geometric texture ``kind`` with spatial period ``period``.

    Args:
      kind: one of ``GEOMETRIC_TEXTURES``.
      n_major, n_minor: resolution of :func:`~jmeshtex.data.torus` (96 × 32: 6144 faces, edges ≈ 0.066).
      period: minimum distance between texture centres.
      amplitude: relief height; default a fraction of ``period``.
      seed: seed of the centres.
      major_radius, minor_radius: the torus' radii.

    Returns:
      The :class:`~jmeshtex.Mesh` (name ``"<kind>_torus"``).

    Example:
      >>> m = textured_torus("craters", n_major=48, n_minor=16, period=0.4)
      >>> m.num_faces, m.name
      (1536, 'craters_torus')
    """
    v, f = torus(n_major, n_minor, major_radius=major_radius, minor_radius=minor_radius)
    ring = v.copy()
    ring[:, 2] = 0
    ring = major_radius * ring / np.linalg.norm(ring, axis=1, keepdims=True)
    n = (v - ring) / np.linalg.norm(v - ring, axis=1, keepdims=True)
    centers = texture_centers(
        "torus", period=period, seed=seed, major_radius=major_radius, minor_radius=minor_radius
    )
    h = texture_height(v, n, centers, kind=kind, period=period, amplitude=amplitude)
    return Mesh(v + h[:, None] * n, f, name=f"{kind}_torus")


def _vertex_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (unit; zero where a vertex has no area)."""
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def textured_mesh(
    mesh: Mesh | tuple[Float[np.ndarray, "V 3"], np.ndarray],
    kind: str = "knobs",
    *,
    period: float,
    amplitude: float | None = None,
    seed: int = 0,
) -> Mesh:
    """Any mesh carrying the geometric texture ``kind`` at spatial period ``period`` (its own units).

    .. math:: v \\mapsto v + h(v)\\, n(v)

    with ``n`` the area-weighted vertex normals and ``h`` the profile of the module docstring
    around centres chosen by Poisson-disc sampling (minimum distance ``period``, Euclidean) from
    area-uniform random points of the surface. The tessellation does not enter the centres, so
    two tessellations of one surface carry statistically the same texture.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])``.
      kind: one of ``GEOMETRIC_TEXTURES``.
      period: minimum distance between texture centres, in the mesh's units (for a period in mean
        edges, multiply by the mesh's mean edge).
      amplitude: relief height; default a fraction of ``period`` (module docstring).
      seed: the NumPy seed of the surface samples and their order.

    Returns:
      The displaced :class:`~jmeshtex.Mesh` (same faces, name ``"<kind>_<name>"``).

    Example:
      >>> from jmeshtex.data import torus
      >>> m = textured_mesh(torus(48, 16), "spikes", period=0.4)
      >>> m.num_faces, bool(np.abs(m.vertices - torus(48, 16).vertices).max() > 0.1)
      (1536, True)
    """
    if isinstance(mesh, Mesh):
        v, f, name = mesh.vertices, mesh.faces, mesh.name or "mesh"
    else:
        (v, f), name = mesh, "mesh"
    v = np.asarray(v, np.float64)
    f = np.asarray(f, np.int64)
    if not is_finite_number(period) or not period > 0:
        raise InputError(
            f"textured_mesh: period must be a number > 0 (the spacing of the centres in mesh units), "
            f"got {period!r}"
        )
    rng = np.random.default_rng(seed)
    tri = v[f]
    area = triangle_areas(tri)
    n_samples = max(2000, int(15 * area.sum() / period**2))
    face = rng.choice(len(f), n_samples, p=area / area.sum())
    a, b = rng.uniform(size=(2, n_samples))
    flip = a + b > 1
    a, b = np.where(flip, 1 - a, a), np.where(flip, 1 - b, b)
    t = tri[face]
    samples = t[:, 0] + a[:, None] * (t[:, 1] - t[:, 0]) + b[:, None] * (t[:, 2] - t[:, 0])
    centers = _poisson_disc(samples, float(period), rng)
    n = _vertex_normals(v, f)
    h = texture_height(v, n, centers, kind=kind, period=period, amplitude=amplitude)
    return Mesh(v + h[:, None] * n, f, name=f"{kind}_{name}")

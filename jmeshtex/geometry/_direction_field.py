"""Tangent direction fields on a mesh: a global vector projected on the surface, or the smoothest field.

Both return one unit tangent vector per vertex, in world coordinates, that depends only on the
surface (never on a UV layout), so a texture read along it keeps its orientation across UV seams.

- :func:`global_direction_field` is the construction of Kovács et al. 2024 (Sec. 4.2) and of their
  reference tool: every face projects a fixed world vector ``p`` onto its plane (a second vector
  ``q`` where the face normal is parallel to ``p``), vertices sum the area-weighted face directions.
  Simple and continuous, but it has singularities where the normal is parallel to ``p`` (the poles
  of a sphere with ``p`` along its axis), placed by the world axes.
- :func:`smoothest_direction_field` is the lowest eigenvector of the connection Laplacian built
  from :mod:`jmeshtex.geometry`'s intrinsic one-ring transport (Knöppel, Crane, Pinkall & Schröder
  2013, "Globally optimal direction fields", §5-6, 1-direction fields): the field with the least
  Dirichlet energy, whose few singularities the geometry places.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .._config import is_int
from .._errors import InputError
from .._mesh import accepts_mesh
from .._types import Float, Int
from ._frames import tangent_frames, tangent_from_3d, tangent_to_3d
from ._intrinsic import check_mesh, corner_angles, edge_lengths, face_areas, vertex_areas
from ._log_map import _neighborhood_from_lengths

#: a face normal within this of ±p (|n·p| > 1 − tol) projects the secondary vector instead
PARALLEL_TOL = 1e-3


def _unit(a, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.shape != (3,) or not np.isfinite(a).all() or np.linalg.norm(a) == 0:
        raise InputError(f"{name} must be a finite non-zero 3-vector, got {a!r}")
    return a / np.linalg.norm(a)


def _normalize_rows(a: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(a, axis=1, keepdims=True)
    ok = norm > 1e-12 * max(float(norm.max(initial=0.0)), 1e-300)
    return np.where(ok, a / np.where(ok, norm, 1.0), fallback)


def project_direction(
    direction: Float[np.ndarray, "N 3"],
    normal: Float[np.ndarray, "N 3"],
    *,
    primary=(1.0, 0.0, 0.0),
    secondary=(0.0, 1.0, 0.0),
) -> Float[np.ndarray, "N 3"]:
    """Unit tangent vectors: ``direction`` minus its normal part, with the global vector as fallback.

    .. math:: t = \\frac{d - (d\\cdot n)\\, n}{\\lVert d - (d\\cdot n)\\, n\\rVert}

    Where the projection vanishes (a singularity of the field, or ``d = 0``), the Gram–Schmidt
    projection of ``primary`` (of ``secondary`` where ``|n·primary| > 1 − 10⁻³``) is used instead.

    Args:
      direction: ``[N, 3]`` vectors (e.g. vertex directions interpolated inside a face).
      normal: ``[N, 3]`` unit normals.
      primary, secondary: the global vectors of :func:`global_direction_field`.

    Returns:
      ``[N, 3]`` unit vectors orthogonal to ``normal``.

    Example:
      >>> project_direction(np.array([[1.0, 0, 1], [0, 0, 1]]), np.array([[0.0, 0, 1], [0, 0, 1]])).tolist()
      [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    """
    p, q = _unit(primary, "primary"), _unit(secondary, "secondary")
    n = np.asarray(normal, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    r = np.where((np.abs(n @ p) > 1.0 - PARALLEL_TOL)[:, None], q, p)
    fallback = r - np.sum(r * n, axis=1, keepdims=True) * n
    fallback /= np.linalg.norm(fallback, axis=1, keepdims=True)
    t = d - np.sum(d * n, axis=1, keepdims=True) * n
    return _normalize_rows(t, fallback)


def _face_normals(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    double_area = np.linalg.norm(cross, axis=1)
    return cross / np.where(double_area > 0, double_area, 1.0)[:, None], 0.5 * double_area


@accepts_mesh
def global_direction_field(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    *,
    primary=(1.0, 0.0, 0.0),
    secondary=(0.0, 1.0, 0.0),
) -> Float[np.ndarray, "V 3"]:
    """Per-vertex tangent directions from one global vector (Kovács et al. 2024, Sec. 4.2).

    Each face ``f`` projects ``r_f = p`` (``q`` where ``|n_f · p| > 1 − 10⁻³``) onto its plane
    (Gram–Schmidt); a vertex sums its faces' unit projections weighted by face area and the sum is
    projected onto the vertex's angle-weighted normal:

    .. math:: t_v \\propto \\Pi_{n_v} \\sum_{f \\ni v} A_f\\, \\frac{\\Pi_{n_f} r_f}{\\lVert \\Pi_{n_f} r_f\\rVert},
       \\qquad \\Pi_n x = x - (x\\cdot n)\\, n

    A vertex whose sum vanishes gets the projection of ``p`` (or ``q``). The reference tool builds
    ``n_f × r_f`` instead of ``Π r_f``: the same field turned by 90° everywhere (a global gauge);
    it also only tests ``n_f · p ≈ +1`` (not −1) for the fallback.

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` consistently oriented triangles.
      primary: ``p``, the world direction the field follows.
      secondary: ``q``, used where a face is orthogonal to ``p``.

    Returns:
      ``[V, 3]`` float64 unit vectors orthogonal to the vertex normals.

    Raises:
      InputError: a zero or non-finite ``primary`` / ``secondary``.

    Example:
      >>> from jmeshtex.data import grid
      >>> global_direction_field(*grid(2), primary=(1.0, 1.0, 1.0))[4].round(6).tolist()
      [0.707107, 0.707107, 0.0]
    """
    v, f = check_mesh(vertices, faces)
    face_n, area = _face_normals(v, f)
    face_t = project_direction(np.zeros_like(face_n), face_n, primary=primary, secondary=secondary)
    total = np.zeros_like(v)
    for axis in range(3):
        total[:, axis] = np.bincount(
            f.ravel(), np.repeat(area * face_t[:, axis], 3), minlength=len(v)
        )
    normal = tangent_frames(v, f).normal
    return project_direction(total, normal, primary=primary, secondary=secondary)


@accepts_mesh
def connection_laplacian(
    vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"]
) -> tuple[sp.csr_matrix, Float[np.ndarray, " V"]]:
    """Connection Laplacian of tangent vector fields (complex, one-ring gauges) and vertex areas.

    .. math:: (L u)_p = \\sum_{q \\sim p} w_{pq}\\, \\big(u_p - \\rho_{q\\to p}\\, u_q\\big), \\qquad
       u^* L u = \\sum_{\\{p,q\\}} w_{pq}\\, \\lvert u_p - \\rho_{q\\to p} u_q\\rvert^2

    with ``ρ`` the intrinsic transport of :func:`~jmeshtex.geometry.one_ring_neighborhood` and
    ``w_pq = max(0, ½(cot α + cot β))`` the cotangent weights clipped at 0 so ``L`` stays positive
    semi-definite on meshes with obtuse triangles (Knöppel et al. 2013, §6). Edge lengths only.

    Returns:
      ``(L [V, V] Hermitian complex128 CSR, area [V] barycentric vertex areas)``.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> L, area = connection_laplacian(*icosphere(1))
      >>> bool(abs(L - L.conj().T).max() < 1e-12), L.shape
      (True, (42, 42))
    """
    v, f = check_mesh(vertices, faces)
    V = len(v)
    lengths = edge_lengths(v, f)
    alpha = corner_angles(lengths)
    # corner k is opposite edge (k+1) % 3, which joins faces[:, k+1] and faces[:, k+2]
    a = np.roll(f, -1, axis=1).ravel()
    b = np.roll(f, -2, axis=1).ravel()
    cot = 0.5 / np.tan(np.clip(alpha.ravel(), 1e-12, np.pi - 1e-12))
    C = sp.coo_matrix(
        (np.concatenate([cot, cot]), (np.concatenate([a, b]), np.concatenate([b, a]))), shape=(V, V)
    ).tocsr()
    nb = _neighborhood_from_lengths(f, lengths, V)
    rows = np.broadcast_to(np.arange(V)[:, None], nb.index.shape)[nb.mask]
    cols = nb.index[nb.mask].astype(np.int64)
    w = np.maximum(np.asarray(C[rows, cols]).ravel(), 0.0)
    A = sp.coo_matrix((w * nb.transport[nb.mask], (rows, cols)), shape=(V, V)).tocsr()
    D = sp.diags(np.bincount(rows, w, minlength=V).astype(np.complex128))
    area = vertex_areas(f, face_areas(lengths), V)
    return (D - A).tocsr(), area


@accepts_mesh
def smoothest_direction_field(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    *,
    primary=(1.0, 0.0, 0.0),
    iterations: int = 30,
) -> Float[np.ndarray, "V 3"]:
    """Per-vertex unit directions of the smoothest tangent field (Knöppel et al. 2013).

    The lowest eigenvector of :func:`connection_laplacian` against the vertex areas,

    .. math:: L u = \\lambda M u, \\qquad \\lambda \\text{ smallest},

    by inverse iteration ``u ← (L + εM)^{-1} M u`` from the projection of ``primary`` (which picks
    one field in a degenerate eigenspace, such as the sphere's, and fixes the global phase
    deterministically), then normalised per vertex and sent to 3D with the extrinsic frames of the
    same gauge (:func:`~jmeshtex.geometry.tangent_frames`). Vertices where the field vanishes
    (singularities) get the projection of ``primary``.

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` consistently oriented manifold triangles.
      primary: start vector of the iteration (its phase becomes the field's).
      iterations: inverse-iteration steps.

    Returns:
      ``[V, 3]`` float64 unit vectors orthogonal to the vertex normals.

    Example:
      >>> from jmeshtex.data import grid
      >>> t = smoothest_direction_field(*grid(3), primary=(1.0, 2.0, 0.0))
      >>> bool(np.allclose(t, np.array([1.0, 2.0, 0.0]) / np.sqrt(5.0)))   # a flat sheet: parallel
      True
    """
    v, f = check_mesh(vertices, faces)
    if not is_int(iterations, 1):
        raise InputError(
            f"smoothest_direction_field: iterations must be a positive integer, got {iterations!r}"
        )
    p = _unit(primary, "primary")
    frames = tangent_frames(v, f)
    L, area = connection_laplacian(v, f)
    M = sp.diags(area.astype(np.complex128))
    eps = 1e-8 * abs(L.diagonal()).max() / max(area.max(), 1e-300)
    solve = splu((L + eps * M).tocsc()).solve
    u = tangent_from_3d(np.broadcast_to(p, v.shape), frames).astype(np.complex128)
    if not np.any(np.abs(u) > 0):
        u = np.ones(len(v), np.complex128)
    for _ in range(int(iterations)):
        u = solve(area * u)
        u /= np.sqrt(np.sum(area * np.abs(u) ** 2))
    # the global phase: make the field agree on average with the start vector
    start = tangent_from_3d(np.broadcast_to(p, v.shape), frames)
    c = np.sum(area * np.conj(u) * start)
    if abs(c) > 0:
        u *= c / abs(c)
    mag = np.abs(u)
    unit = np.where(mag > 1e-9 * mag.max(), u / np.where(mag > 0, mag, 1.0), 0.0)
    return project_direction(
        tangent_to_3d(unit, frames), frames.normal, primary=p, secondary=_perp(p)
    )


def _perp(p: np.ndarray) -> np.ndarray:
    axis = np.eye(3)[np.argmin(np.abs(p))]
    return np.cross(p, axis)

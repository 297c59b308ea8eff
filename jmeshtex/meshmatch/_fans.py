"""Geodesic fans: the per-vertex signal descriptors MeshMatch compares (Chen et al. 2012 §3.1).

A *geodesic fan* of vertex p samples a signal at ``R`` radii × ``A`` angles along straightest
geodesics (the discrete exponential map of :func:`jmeshtex.geometry.trace_from_vertices`):

.. math:: F_p[i, a] = x\\bigl(\\exp_p(r_i\\, u_p\\, e^{2\\pi i a / A})\\bigr)

where ``u_p`` is a unit reference direction in p's tangent frame (default 1, the frame's x-axis).
Everything is intrinsic (edge lengths only), so fans are unchanged by rigid motions and bending;
a gauge rotation that turns the frame by α changes ``u_p`` to ``u_p e^{-iα}`` and leaves the sample
points where they were, and turning ``u_p`` by ``2πk/A`` shifts the fan's angular axis by k. The
signal is pre-filtered before sampling (ring i is blurred to about half its angular sample spacing
``2π r_i / A``) so sparse samples do not alias.

The pre-filter is explicit one-ring smoothing (:func:`smoother`, :func:`smooth`).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp

from .._config import is_int
from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._types import ArrayLike, Bool, Complex, Float, Int
from ..geometry import (
    TracerGeometry,
    mean_edge_length,
    one_rings,
    trace_from_vertices,
    trace_geodesics,
    tracer_geometry,
)

# blend factor of one explicit smoothing step x <- (1 - λ) x + λ mean(one-ring)
_SMOOTH_LAMBDA = 0.5


class GeodesicFans(NamedTuple):
    """Where the samples of every vertex's fan lie on the mesh.

    Attributes:
      face: ``[V, R, A]`` int32 face of each sample.
      bary: ``[V, R, A, 3]`` float64 barycentric coordinates of the sample in that face.
      corners: ``[V, R, A, 3]`` int32 vertices of that face (``faces[face]``), for interpolation.
      stopped: ``[V, R, A]`` bool, True where a boundary stopped the geodesic early (the sample
        then sits on the boundary).
      radii: ``[R]`` ring radii.
      steps: ``[R]`` int32 smoothing steps of each ring's pre-filter (see :func:`prefilter_steps`).
    """

    face: Int[np.ndarray, "V R A"]
    bary: Float[np.ndarray, "V R A 3"]
    corners: Int[np.ndarray, "V R A 3"]
    stopped: Bool[np.ndarray, "V R A"]
    radii: Float[np.ndarray, " R"]
    steps: Int[np.ndarray, " R"]


class Smoother(NamedTuple):
    """Padded one-ring averaging: ``mean(x)_p = Σ_k weight[p, k] x[index[p, k]]`` (rows sum to 1).

    Attributes:
      index: ``[V, K]`` int32 one-ring neighbours (padded slots: 0).
      weight: ``[V, K]`` float weights, ``1 / degree`` on real slots and 0 on padding.
    """

    index: Int[np.ndarray, "V K"]
    weight: Float[np.ndarray, "V K"]


def prefilter_steps(radii, num_angles: int, edge: float) -> np.ndarray:
    """Smoothing steps that blur ring i to a Gaussian of σ_i = half its angular sample spacing.

    .. math:: \\sigma_i = \\frac{\\pi r_i}{A}, \\qquad n_i = \\operatorname{round}\\Bigl(
              \\frac{2\\sigma_i^2}{\\lambda h^2}\\Bigr)

    One step ``x ← (1 − λ) x + λ · mean(one-ring)`` on a mesh of mean edge ``h`` adds a variance of
    about ``λ h² / 2`` per axis.

    Args:
      radii: ``[R]`` ring radii ``r_i``.
      num_angles: ``A``, samples per ring.
      edge: ``h``, the mesh's mean edge length.

    Returns:
      ``[R]`` int32 smoothing steps ``n_i``.

    Example:
      >>> prefilter_steps([1.0, 2.0, 6.0], 18, 1.0).tolist()
      [0, 0, 4]
    """
    radii = np.asarray(radii, dtype=np.float64)
    sigma = np.pi * radii / num_angles
    return np.rint(2.0 * sigma**2 / (_SMOOTH_LAMBDA * edge**2)).astype(np.int32)


def smoother(faces: Int[np.ndarray, "F 3"], num_vertices: int) -> Smoother:
    """Uniform one-ring averaging weights in padded form (combinatorial: no geometry involved).

    Args:
      faces: ``[F, 3]`` triangles.
      num_vertices: ``V``.

    Returns:
      :class:`Smoother` with ``[V, K]`` tables, ``K`` the largest vertex degree.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> s = smoother(icosahedron().faces, 12)
      >>> s.index.shape, float(s.weight.sum(1).min())
      ((12, 5), 1.0)
    """
    rings = one_rings(np.asarray(faces), num_vertices)
    mask = rings.mask
    degree = np.maximum(mask.sum(axis=1, keepdims=True), 1)
    return Smoother(index=rings.ring.astype(np.int32), weight=mask / degree)


def smooth(values, sm: Smoother, steps: int):
    """``steps`` explicit smoothing steps ``x ← (1 − λ) x + λ · mean(one-ring)`` (λ = 1/2), JAX.

    Args:
      values: ``[V, C]`` per-vertex values.
      sm: :func:`smoother` of the mesh.
      steps: number of steps.

    Returns:
      ``[V, C]`` smoothed values (JAX, in ``values``' dtype).

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> v, f = icosahedron()
      >>> x = jnp.asarray(v[:, :1])
      >>> bool(jnp.abs(smooth(x, smoother(f, 12), 3)).max() < jnp.abs(x).max())
      True
    """
    values = jnp.asarray(values)
    index = jnp.asarray(sm.index)
    weight = jnp.asarray(sm.weight, dtype=values.dtype)
    lam = jnp.asarray(_SMOOTH_LAMBDA, values.dtype)
    for _ in range(int(steps)):
        values = (1 - lam) * values + lam * jnp.einsum("vk,vkc->vc", weight, values[index])
    return values


def geodesic_fans(
    mesh: Mesh | tuple,
    *,
    radii,
    num_angles: int = 18,
    reference: Complex[np.ndarray, " V"] | None = None,
    edge: float | None = None,
    geometry: TracerGeometry | None = None,
) -> GeodesicFans:
    """Trace the sample points of every vertex's geodesic fan with the exponential map.

    .. math:: s_p[i, a] = \\exp_p\\bigl(r_i\\, \\hat u_p\\, e^{2\\pi i a/A}\\bigr)

    (MeshMatch's geodesic fans, Chen et al. 2012 §3.1), traced intrinsically from each vertex in its
    tangent frame (:func:`~jmeshtex.geometry.trace_from_vertices`). With increasing radii one
    geodesic per angle is traced and continued ring by ring from where the previous ring ended
    (:func:`~jmeshtex.geometry.trace_geodesics`): the same straight line, half the face crossings.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` (or ``(vertices [V, 3], faces [F, 3])``) of consistently
        oriented manifold triangles.
      radii: ``[R]`` increasing positive ring radii (world units).
      num_angles: ``A`` samples per ring.
      reference: ``[V]`` complex direction of angle 0 in each vertex's intrinsic frame (only its
        angle is used); default 1 (the frame's x-axis).
      edge: the mean edge length used for the pre-filter (default: measured on the mesh).
      geometry: precomputed :func:`~jmeshtex.geometry.tracer_geometry` of this mesh.

    Returns:
      :class:`GeodesicFans`.

    Raises:
      InputError: bad radii, angle count or reference directions.

    Example:
      >>> from jmeshtex.data import grid
      >>> fans = geodesic_fans(grid(8), radii=[0.1], num_angles=4)
      >>> fans.face.shape, bool(fans.stopped[40].any())    # vertex 40 is the centre: nothing stops
      ((81, 1, 4), False)
    """
    mesh = as_mesh(mesh)
    vertices, faces = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)
    radii = np.asarray(radii, dtype=np.float64).reshape(-1)
    if radii.size == 0 or not np.all(np.isfinite(radii)) or np.any(radii <= 0):
        raise InputError(f"radii must be a non-empty list of positive finite numbers, got {radii}")
    if not is_int(num_angles, 1):
        raise InputError(f"num_angles must be a positive integer, got {num_angles!r}")
    if geometry is None:
        geometry = tracer_geometry(vertices, faces)
    V = len(vertices)
    if reference is None:
        reference = np.ones(V, np.complex128)
    reference = np.asarray(reference, dtype=np.complex128)
    if reference.shape != (V,) or not np.all(np.isfinite(reference)) or np.any(reference == 0):
        raise InputError(
            f"reference must be [V={V}] finite non-zero complex directions, got shape {reference.shape}"
        )
    reference = reference / np.abs(reference)
    if edge is None:
        edge = mean_edge_length(vertices, geometry.faces)
    R, A = len(radii), int(num_angles)
    turn = np.exp(2j * np.pi * np.arange(A) / A)
    direction = (reference[:, None] * turn[None]).ravel()
    vertex = np.repeat(np.arange(V), A)
    if np.all(np.diff(radii) > 0):
        # one straightest geodesic per angle, continued ring by ring from where the previous ring
        # ended (same line, half the face crossings of tracing every ring from the vertex)
        tr = trace_from_vertices(vertices, faces, vertex, direction, radii[0], geometry=geometry)
        rings, stopped = [tr], tr.stopped
        for i in range(1, R):
            tr = trace_geodesics(
                vertices,
                faces,
                tr.face,
                tr.bary,
                tr.direction,
                np.where(stopped, 0.0, radii[i] - radii[i - 1]),
                geometry=geometry,
            )
            stopped = stopped | tr.stopped
            rings.append(tr._replace(stopped=stopped))
        face = np.stack([t.face for t in rings], axis=1).reshape(V, A, R).transpose(0, 2, 1)
        bary = np.stack([t.bary for t in rings], axis=1).reshape(V, A, R, 3).transpose(0, 2, 1, 3)
        stop = np.stack([t.stopped for t in rings], axis=1).reshape(V, A, R).transpose(0, 2, 1)
    else:
        tr = trace_from_vertices(
            vertices,
            faces,
            np.repeat(vertex, R),
            np.repeat(direction, R),
            np.tile(radii, V * A),
            geometry=geometry,
        )
        face = tr.face.reshape(V, A, R).transpose(0, 2, 1)
        bary = tr.bary.reshape(V, A, R, 3).transpose(0, 2, 1, 3)
        stop = tr.stopped.reshape(V, A, R).transpose(0, 2, 1)
    face = np.ascontiguousarray(face)
    return GeodesicFans(
        face=face.astype(np.int32),
        bary=np.ascontiguousarray(bary),
        corners=geometry.faces[face].astype(np.int32),
        stopped=np.ascontiguousarray(stop),
        radii=radii,
        steps=prefilter_steps(radii, A, edge),
    )


def sample_fans(fans: GeodesicFans, values):
    """Barycentric interpolation of per-vertex values at the fan samples (NumPy or JAX).

    .. math:: F_p[i, a] = \\sum_k b_k\\, x_{c_k}

    Args:
      fans: :class:`GeodesicFans`.
      values: ``[V, C]`` per-vertex values.

    Returns:
      ``[V, R, A, C]`` samples (JAX when ``values`` is a JAX array).

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(8)
      >>> fans = geodesic_fans((v, f), radii=[0.1], num_angles=4)
      >>> xy = sample_fans(fans, v[:, :2])[40, 0]          # centre (0.5, 0.5), radius 0.1
      >>> np.round(np.linalg.norm(xy - 0.5, axis=1), 6).tolist()
      [0.1, 0.1, 0.1, 0.1]
    """
    xp = jnp if isinstance(values, jax.Array) else np
    bary = xp.asarray(fans.bary).astype(values.dtype) if xp is jnp else fans.bary
    return (bary[..., None] * values[xp.asarray(fans.corners)]).sum(axis=-2)


def filtered_fans(fans: GeodesicFans, values, sm: Smoother):
    """Pre-filter then sample: ring i samples ``values`` after ``fans.steps[i]`` smoothing steps (JAX).

    Args:
      fans: :class:`GeodesicFans`.
      values: ``[V, C]`` per-vertex values.
      sm: :func:`smoother` of the same mesh.

    Returns:
      ``[V, R, A, C]`` fan samples in ``values``' dtype.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(8)
      >>> fans = geodesic_fans((v, f), radii=[0.05, 0.1], num_angles=6)
      >>> filtered_fans(fans, jnp.asarray(v), smoother(f, len(v))).shape
      (81, 2, 6, 3)
    """
    values = jnp.asarray(values)
    rings = []
    done, current = 0, values
    for i, steps in enumerate(np.asarray(fans.steps).tolist()):
        if steps > done:
            current = smooth(current, sm, steps - done)
            done = steps
        ring = fans._replace(bary=fans.bary[:, i : i + 1], corners=fans.corners[:, i : i + 1])
        rings.append(sample_fans(ring, current))
    return jnp.concatenate(rings, axis=1)


def fan_descriptor(
    mesh: Mesh | tuple,
    values: Float[ArrayLike, "V C"],
    *,
    radii,
    num_angles: int = 18,
    reference: Complex[np.ndarray, " V"] | None = None,
    geometry: TracerGeometry | None = None,
):
    """The pre-filtered geodesic fan of a per-vertex signal at every vertex (trace, filter, sample).

    .. math:: F_p[i, a] = (S^{n_i} x)\\bigl(\\exp_p(r_i\\, \\hat u_p\\, e^{2\\pi i a/A})\\bigr)

    with ``S`` one explicit one-ring smoothing step and ``n_i`` from :func:`prefilter_steps`.
    Invariant to rigid motions, relabelling and isometric bending; turning ``reference`` by
    ``2πk/A`` rolls the angle axis: ``F'[p, :, a] = F[p, :, (a + k) mod A]`` (the same points).

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])``.
      values: ``[V, C]`` per-vertex signal (colours).
      radii: ``[R]`` ring radii.
      num_angles: ``A``.
      reference: ``[V]`` complex angle-0 direction in each intrinsic vertex frame (default 1).
      geometry: precomputed tracer tables.

    Returns:
      ``[V, R, A, C]`` JAX array in ``values``' dtype.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> sphere = icosphere(2)
      >>> d = fan_descriptor(sphere, jnp.asarray(sphere.vertices[:, 2:]), radii=[0.2, 0.4], num_angles=8)
      >>> d.shape, bool(jnp.abs(d[0] - d[0].mean()).max() > 0)
      ((162, 2, 8, 1), True)
    """
    mesh = as_mesh(mesh)
    fans = geodesic_fans(
        mesh, radii=radii, num_angles=num_angles, reference=reference, geometry=geometry
    )
    return filtered_fans(fans, jnp.asarray(values), smoother(mesh.faces, mesh.num_vertices))


def _smooth_host(values: np.ndarray, sm: Smoother, steps: int) -> np.ndarray:
    """:func:`smooth` on the host in float64: one sparse matrix ``(1 − λ) I + λ W``, ``steps``
    products (hundreds of steps cost a fraction of a second; eager JAX ops cost seconds)."""
    V, K = sm.index.shape
    rows = np.repeat(np.arange(V), K)
    step = sp.csr_matrix(
        (_SMOOTH_LAMBDA * np.asarray(sm.weight, np.float64).ravel(), (rows, sm.index.ravel())),
        shape=(V, V),
    )
    step = (step + (1.0 - _SMOOTH_LAMBDA) * sp.identity(V, format="csr")).tocsr()
    values = np.asarray(values, np.float64)
    for _ in range(int(steps)):
        values = step @ values
    return values

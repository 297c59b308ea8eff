"""Geodesic fans and shape features: the per-vertex descriptors MeshMatch compares (Chen et al. 2012 §3).

A *geodesic fan* of vertex p samples a signal at ``R`` radii × ``A`` angles along straightest
geodesics (the discrete exponential map of :func:`jmeshtex.geometry.trace_from_vertices`):

.. math:: F_p[i, a] = x\\bigl(\\exp_p(r_i\\, u_p\\, e^{2\\pi i a / A})\\bigr)

where ``u_p`` is a unit reference direction in p's tangent frame (default 1, the frame's x-axis).
Everything is intrinsic (edge lengths only), so fans are unchanged by rigid motions and bending;
a gauge rotation that turns the frame by α changes ``u_p`` to ``u_p e^{-iα}`` and leaves the sample
points where they were, and turning ``u_p`` by ``2πk/A`` shifts the fan's angular axis by k. The
signal is pre-filtered before sampling (ring i is blurred to about half its angular sample spacing
``2π r_i / A``) so sparse samples do not alias.

Shape features are the heat kernel signature (8 log-spaced times; Sun et al. 2009) and the normal's
dot product with a chosen up direction; optional *geodesic affinities* describe where a vertex is
relative to user correspondences.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from .._errors import InputError
from .._types import ArrayLike, Bool, Complex, Float, Int
from ..geometry import (
    MeshHierarchy,
    TracerGeometry,
    hks_times,
    laplacian_eigenpairs,
    one_rings,
    tangent_frames,
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
    """Padded one-ring averaging: ``mean(x)_p = Σ_k weight[p, k] x[index[p, k]]`` (rows sum to 1)."""

    index: Int[np.ndarray, "V K"]
    weight: Float[np.ndarray, "V K"]


def prefilter_steps(radii, num_angles: int, edge: float) -> np.ndarray:
    """Smoothing steps that blur ring i to a Gaussian of σ_i = half its angular sample spacing.

    .. math:: \\sigma_i = \\frac{\\pi r_i}{A}, \\qquad n_i = \\operatorname{round}\\Bigl(
              \\frac{2\\sigma_i^2}{\\lambda h^2}\\Bigr)

    One step ``x ← (1 − λ) x + λ · mean(one-ring)`` on a mesh of mean edge ``h`` adds a variance of
    about ``λ h² / 2`` per axis.

    Example:
      >>> prefilter_steps([1.0, 2.0, 6.0], 18, 1.0).tolist()
      [0, 0, 4]
    """
    radii = np.asarray(radii, dtype=np.float64)
    sigma = np.pi * radii / num_angles
    return np.rint(2.0 * sigma**2 / (_SMOOTH_LAMBDA * edge**2)).astype(np.int32)


def smoother(faces: Int[np.ndarray, "F 3"], num_vertices: int) -> Smoother:
    """Uniform one-ring averaging weights in padded form (combinatorial: no geometry involved).

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
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
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
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` consistently oriented manifold triangles.
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
      >>> v, f = grid(8)
      >>> fans = geodesic_fans(v, f, radii=[0.1], num_angles=4)
      >>> fans.face.shape, bool(fans.stopped[40].any())    # vertex 40 is the centre: nothing stops
      ((81, 1, 4), False)
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces)
    radii = np.asarray(radii, dtype=np.float64).reshape(-1)
    if radii.size == 0 or not np.all(np.isfinite(radii)) or np.any(radii <= 0):
        raise InputError(f"radii must be a non-empty list of positive finite numbers, got {radii}")
    if isinstance(num_angles, bool) or not isinstance(num_angles, (int, np.integer)) or num_angles < 1:
        raise InputError(f"num_angles must be a positive integer, got {num_angles!r}")
    if geometry is None:
        geometry = tracer_geometry(vertices, faces)
    V = len(vertices)
    if reference is None:
        reference = np.ones(V, np.complex128)
    reference = np.asarray(reference, dtype=np.complex128)
    if reference.shape != (V,) or not np.all(np.isfinite(reference)) or np.any(reference == 0):
        raise InputError(f"reference must be [V={V}] finite non-zero complex directions, got shape {reference.shape}")
    reference = reference / np.abs(reference)
    if edge is None:
        f = geometry.faces
        edge = float(np.linalg.norm(vertices[f] - vertices[np.roll(f, -1, axis=1)], axis=2).mean())
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
            tr = trace_geodesics(vertices, faces, tr.face, tr.bary, tr.direction,
                                 np.where(stopped, 0.0, radii[i] - radii[i - 1]), geometry=geometry)
            stopped = stopped | tr.stopped
            rings.append(tr._replace(stopped=stopped))
        face = np.stack([t.face for t in rings], axis=1).reshape(V, A, R).transpose(0, 2, 1)
        bary = np.stack([t.bary for t in rings], axis=1).reshape(V, A, R, 3).transpose(0, 2, 1, 3)
        stop = np.stack([t.stopped for t in rings], axis=1).reshape(V, A, R).transpose(0, 2, 1)
    else:
        tr = trace_from_vertices(vertices, faces, np.repeat(vertex, R), np.repeat(direction, R),
                                 np.tile(radii, V * A), geometry=geometry)
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
      >>> fans = geodesic_fans(v, f, radii=[0.1], num_angles=4)
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
      >>> fans = geodesic_fans(v, f, radii=[0.05, 0.1], num_angles=6)
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
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
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
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` triangles.
      values: ``[V, C]`` per-vertex signal (colours).
      radii: ``[R]`` ring radii.
      num_angles: ``A``.
      reference: ``[V]`` complex angle-0 direction in each intrinsic vertex frame (default 1).
      geometry: precomputed tracer tables.

    Returns:
      ``[V, R, A, C]`` JAX array in ``values``' dtype.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> v, f = icosphere(2)
      >>> d = fan_descriptor(v, f, jnp.asarray(v[:, 2:]), radii=[0.2, 0.4], num_angles=8)
      >>> d.shape, bool(jnp.abs(d[0] - d[0].mean()).max() > 0)
      ((162, 2, 8, 1), True)
    """
    fans = geodesic_fans(vertices, faces, radii=radii, num_angles=num_angles, reference=reference,
                         geometry=geometry)
    return filtered_fans(fans, jnp.asarray(values), smoother(faces, len(vertices)))


# ---------------------------------------------------------------------------------------------
# shape features


def hks_level(hierarchy: MeshHierarchy, max_vertices: int) -> int:
    """The finest hierarchy level with at most ``max_vertices`` vertices (the coarsest if none).

    Example:
      >>> from jmeshtex.geometry import mesh_hierarchy
      >>> from jmeshtex.data import icosphere
      >>> hks_level(mesh_hierarchy(*icosphere(3), levels=3), 400)
      1
    """
    for level, v in enumerate(hierarchy.vertices):
        if len(v) <= max_vertices:
            return level
    return hierarchy.num_levels - 1


def ancestors(hierarchy: MeshHierarchy, start: int, stop: int) -> np.ndarray:
    """``[V_start]`` index, at level ``stop``, of each level-``start`` vertex's ancestor (parent chain).

    Example:
      >>> from jmeshtex.geometry import mesh_hierarchy
      >>> from jmeshtex.data import icosphere
      >>> h = mesh_hierarchy(*icosphere(2), levels=3)
      >>> a = ancestors(h, 0, 2)
      >>> a.shape, int(a.max()) < len(h.vertices[2])
      ((162,), True)
    """
    out = np.arange(len(hierarchy.vertices[start]))
    for level in range(start, stop):
        out = np.asarray(hierarchy.pooling[level].parent)[out]
    return out


def hks_features(
    hierarchy: MeshHierarchy, *, level: int, times=None, num_times: int = 8, k: int = 32
) -> tuple[Float[np.ndarray, "V T"], Float[np.ndarray, " T"]]:
    """Log heat kernel signature of every input vertex, computed on one coarse level.

    The HKS (Sun et al. 2009) of level ``level`` is copied to the finer vertices through the parent
    maps and smoothed over a few one-rings (it varies slowly), then log-transformed.

    Args:
      hierarchy: :func:`~jmeshtex.geometry.mesh_hierarchy` of the mesh.
      level: the level to compute the spectrum on (see :func:`hks_level`).
      times: ``[T]`` diffusion times (share them between meshes you compare); default ``num_times``
        log-spaced times from this spectrum.
      num_times: number of default times.
      k: eigenpairs.

    Returns:
      ``(log_hks [V_0, T], times [T])``.

    Example:
      >>> from jmeshtex.geometry import mesh_hierarchy
      >>> from jmeshtex.data import icosphere
      >>> h = mesh_hierarchy(*icosphere(3), levels=2)
      >>> f, t = hks_features(h, level=1, k=12)
      >>> f.shape, t.shape
      ((642, 8), (8,))
    """
    v, f = hierarchy.vertices[level], hierarchy.faces[level]
    k = int(min(k, len(v) - 1))
    ev = laplacian_eigenpairs(v, f, k=k)
    if times is None:
        times = hks_times(ev.values, num=num_times)
    times = np.asarray(times, dtype=np.float64)
    hks = (ev.vectors**2) @ np.exp(-np.outer(ev.values, times))
    values = np.log(np.maximum(hks, 1e-300))
    values = values[ancestors(hierarchy, 0, level)]
    if level > 0:
        sm = smoother(hierarchy.faces[0], len(hierarchy.vertices[0]))
        values = _smooth_host(values, sm, 2 ** (2 * level))
    return values, times


def _smooth_host(values: np.ndarray, sm: Smoother, steps: int) -> np.ndarray:
    """:func:`smooth` on the host in float64: one sparse matrix ``(1 − λ) I + λ W``, ``steps``
    products (hundreds of steps cost a fraction of a second; eager JAX ops cost seconds)."""
    V, K = sm.index.shape
    rows = np.repeat(np.arange(V), K)
    step = sp.csr_matrix((_SMOOTH_LAMBDA * np.asarray(sm.weight, np.float64).ravel(), (rows, sm.index.ravel())),
                         shape=(V, V))
    step = (step + (1.0 - _SMOOTH_LAMBDA) * sp.identity(V, format="csr")).tocsr()
    values = np.asarray(values, np.float64)
    for _ in range(int(steps)):
        values = step @ values
    return values


def shape_features(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    log_hks: Float[np.ndarray, "V T"],
    *,
    up=None,
) -> Float[np.ndarray, "V D"]:
    """Standardised shape features: z-scored log HKS (block weight 1) and ``n · up`` (weight 1).

    .. math:: \\phi_p = \\Bigl(\\tfrac{1}{\\sqrt{2T}}\\,\\tfrac{h_p - \\bar h}{s_h},\\;
              \\tfrac{1}{\\sqrt 2}\\, n_p\\cdot \\hat u\\Bigr)

    so ``|φ_p − φ_q|²`` is a dimension-normalised shape distance (each block contributes at most
    about 1). The HKS is standardised per mesh (per time), which removes the mesh's scale.

    Args:
      vertices: ``[V, 3]`` input positions (for normals).
      faces: ``[F, 3]`` triangles.
      log_hks: ``[V, T]`` from :func:`hks_features`.
      up: a 3-vector, or None to leave the ``n · up`` feature out.

    Returns:
      ``[V, T (+1)]`` float64 features.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> v, f = icosphere(2)
      >>> shape_features(v, f, np.log(np.ones((162, 2)) + v[:, :2] ** 2), up=(0, 0, 1)).shape
      (162, 3)
    """
    h = np.asarray(log_hks, dtype=np.float64)
    z = (h - h.mean(axis=0)) / np.maximum(h.std(axis=0), 1e-12)
    blocks = 1 if up is None else 2
    parts = [z / np.sqrt(blocks * h.shape[1])]
    if up is not None:
        u = np.asarray(up, dtype=np.float64)
        u = u / np.linalg.norm(u)
        normal = tangent_frames(vertices, faces).normal
        parts.append((normal @ u)[:, None] / np.sqrt(blocks))
    return np.concatenate(parts, axis=1)


def _edge_graph(vertices, faces) -> sp.csr_matrix:
    f = np.asarray(faces, dtype=np.int64)
    a = f.ravel()
    b = np.roll(f, -1, axis=1).ravel()
    w = np.linalg.norm(vertices[a] - vertices[b], axis=1)
    n = len(vertices)
    g = sp.coo_matrix((w, (a, b)), shape=(n, n)).tocsr()
    return g.maximum(g.T)


def correspondence_affinities(
    source_vertices: Float[np.ndarray, "Vs 3"],
    source_faces: Int[np.ndarray, "Fs 3"],
    target_vertices: Float[np.ndarray, "Vt 3"],
    target_faces: Int[np.ndarray, "Ft 3"],
    pairs: Int[np.ndarray, "m 2"],
    *,
    ridge: float = 1e-2,
) -> tuple[Float[np.ndarray, "Vs m"], Float[np.ndarray, "Vt m"]]:
    """Geodesic affinities to user correspondences, made comparable between the two meshes.

    Each vertex gets its vector of (edge-graph) geodesic distances to the ``m`` corresponding points
    of its mesh; the target's vectors are mapped by the affine transform ``W`` that best makes the
    corresponding points agree (ridge-regularised least squares towards the identity, since
    ``m`` points cannot determine an ``(m+1) × m`` map alone),

    .. math:: \\min_W \\lVert [D_t(c_t), 1]\\, W - D_s(c_s) \\rVert^2 + \\lambda \\lVert W - W_0\\rVert^2,

    then turned into affinities ``exp(−d² / 2σ²)`` with ``σ`` a third of the largest source
    distance, scaled by ``1/√m`` so the block's squared distance is at most about 1.

    Args:
      source_vertices, source_faces, target_vertices, target_faces: the two meshes.
      pairs: ``[m, 2]`` (source vertex, target vertex) correspondences, ``m >= 1``.
      ridge: λ relative to the mean squared distance.

    Returns:
      ``(source_affinities [Vs, m], target_affinities [Vt, m])``.

    Raises:
      InputError: bad pair shapes or indices.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> v, f = icosphere(2)
      >>> a, b = correspondence_affinities(v, f, v, f, np.array([[0, 0], [5, 5], [40, 40]]))
      >>> bool(np.abs(a - b).max() < 1e-6)
      True
    """
    pairs = np.asarray(pairs)
    vs, vt = np.asarray(source_vertices, np.float64), np.asarray(target_vertices, np.float64)
    if pairs.ndim != 2 or pairs.shape[1] != 2 or len(pairs) == 0 or not np.issubdtype(pairs.dtype, np.integer):
        raise InputError(f"correspondences must be an integer array [m >= 1, 2] of (source, target) vertices, got {pairs.dtype} {pairs.shape}")
    if pairs[:, 0].min() < 0 or pairs[:, 0].max() >= len(vs) or pairs[:, 1].min() < 0 or pairs[:, 1].max() >= len(vt):
        raise InputError(f"correspondence vertex indices out of range (source V={len(vs)}, target V={len(vt)})")
    ds = dijkstra(_edge_graph(vs, source_faces), indices=pairs[:, 0]).T  # [Vs, m]
    dt = dijkstra(_edge_graph(vt, target_faces), indices=pairs[:, 1]).T
    finite_s = np.isfinite(ds)
    dmax = float(ds[finite_s].max()) if finite_s.any() else 1.0
    ds = np.where(finite_s, ds, 10 * dmax)
    dt = np.where(np.isfinite(dt), dt, 10 * dmax)
    m = len(pairs)
    x = np.concatenate([dt[pairs[:, 1]], np.ones((m, 1))], axis=1)  # [m, m+1]
    y = ds[pairs[:, 0]]  # [m, m]
    w0 = np.concatenate([np.eye(m), np.zeros((1, m))], axis=0)
    lam = ridge * max(float(np.mean(x * x)), 1e-12) * (m + 1)
    w = w0 + np.linalg.solve(x.T @ x + lam * np.eye(m + 1), x.T @ (y - x @ w0))
    dt_mapped = np.concatenate([dt, np.ones((len(dt), 1))], axis=1) @ w
    sigma = max(dmax / 3.0, 1e-12)
    scale = 1.0 / np.sqrt(m)
    return (np.exp(-(ds**2) / (2 * sigma**2)) * scale, np.exp(-(dt_mapped**2) / (2 * sigma**2)) * scale)

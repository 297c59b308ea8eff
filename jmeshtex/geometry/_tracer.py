"""Straightest geodesics on triangle meshes (the discrete exponential map), traced intrinsically.

A trace starts at a surface point with a tangent direction and walks a given distance in a straight
line, unfolding the mesh triangle by triangle (Polthier & Schmies 1998, "Straightest geodesics on
polyhedral surfaces"). Only edge lengths enter the walk, so a trace is unchanged when the mesh is
bent isometrically; vertex positions are used for nothing but the returned 3D ``point``.

**Face frame.** Every face ``f = (a, b, c)`` has a local 2D frame, written as complex numbers: corner
0 (``a``) at the origin, corner 1 (``b``) on the positive x-axis at ``l_ab``, corner 2 (``c``) in the
upper half plane, so the corners run counter-clockwise seen from the side the face normal points to.
Tangent directions of :func:`trace_geodesics` and of :class:`TraceResult` are complex numbers in
this frame. In 3D the frame's x-axis is ``(b - a) / |b - a|`` and its y-axis ``n × x`` with ``n`` the
unit face normal; :func:`face_frame_to_world` converts.

**Vertex frame.** :func:`trace_from_vertices` takes directions in the intrinsic vertex gauge of
docs/concepts.md: the x-axis is the edge to slot 0 of :func:`~jmeshtex.geometry.one_rings`, angles grow
counter-clockwise and corner angles are scaled to sum to 2π at interior vertices (not at boundary
vertices). The slot angles come from :func:`~jmeshtex.geometry.one_ring_angles`, the same source as
the one-ring log maps (:func:`~jmeshtex.geometry.one_ring_neighborhood`), so
``exp_p(log_p(q)) = q`` holds to rounding.

All traces advance in lockstep: each iteration is a handful of vectorised NumPy operations over the
traces that are still walking, one face crossing each.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from jaxtyping import Bool, Complex, Float, Int

from .._errors import (
    DegenerateFaceError,
    InputError,
)
from .._mesh import accepts_mesh
from ._adjacency import face_neighborhood
from ._intrinsic import edge_lengths, face_areas, flat_faces
from ._log_map import _angles_from_lengths, _wedge_corners
from ._validate import check_mesh_arrays

# A ray is taken to leave a face through an edge only if it points outwards by more than this
# cosine; rays (numerically) parallel to an edge walk along it instead of bouncing across it.
_PARALLEL_COS = 1e-12
# A walk whose remaining length overshoots its exit edge by less than this fraction of the mean
# altitude ends on that edge instead of crossing it for a rounding-sized remainder (which could
# otherwise turn an exact arrival at a boundary vertex into a spurious boundary stop).
_LENGTH_TOL = 1e-12
# Directions at a boundary vertex this close (radians) to a boundary edge are snapped onto it.
_ANGLE_TOL = 1e-10


class TraceResult(NamedTuple):
    """End points of traced geodesics.

    Attributes:
      face: ``[N]`` int32 face the trace ended in.
      bary: ``[N, 3]`` float64 barycentric coordinates of the end point in ``face`` (one weight per
        corner, non-negative, summing to 1).
      point: ``[N, 3]`` float64 end point in 3D.
      stopped: ``[N]`` bool, True where a boundary edge stopped the walk before the full length.
      travelled: ``[N]`` float64 distance walked (the requested length unless ``stopped``).
      direction: ``[N]`` complex128 unit direction of the walk at its end, in the end face's local
        frame (module docstring); continue a walk from ``(face, bary, direction)`` or transport a
        vector along it by the same rotation.
    """

    face: Int[np.ndarray, " N"]
    bary: Float[np.ndarray, "N 3"]
    point: Float[np.ndarray, "N 3"]
    stopped: Bool[np.ndarray, " N"]
    travelled: Float[np.ndarray, " N"]
    direction: Complex[np.ndarray, " N"]


class TracerGeometry(NamedTuple):
    """Per-face and per-vertex tables the tracer walks over; build once with :func:`tracer_geometry`.

    Attributes:
      vertices: ``[V, 3]`` float64 positions (only used for ``TraceResult.point``).
      faces: ``[F, 3]`` int64 vertex indices.
      corners: ``[F, 3]`` complex128 corner positions in each face's local frame.
      exit_table: ``[F, 5]`` float64 per face ``(n0x, n0y, n1x, n1y, c0)``: unit inward normals
        ``n_k`` of the edges opposite corners 0 and 1 and the offset ``c0 = n0·P1``; the signed
        distances of a point z to the three edges are ``n0·z − c0``, ``n1·z`` and ``Im z`` (the
        edge opposite corner 2 is the x-axis).
      altitude: ``[F, 3]`` float64 distance from corner k to the opposite edge; a point's
        barycentric coordinate k is its distance to that edge over this altitude.
      neighbor: ``[F, 3]`` int64 face across edge k (``faces[f, k] → faces[f, k+1]``), -1 on a
        boundary.
      neighbor_edge: ``[F, 3]`` int64 which edge of the neighbour is the shared one (0 on a boundary).
      crossing: ``[F, 3]`` complex128 unit rotation that maps a direction in f's frame to the
        neighbour's frame across edge k (1 on a boundary).
      crossing_offset: ``[F, 3]`` complex128 translation completing the unfolding: a point z of f's
        frame is ``crossing · z + crossing_offset`` in the neighbour's frame (0 on a boundary).
      ring_faces: ``[V, K]`` int64 face of each one-ring wedge (counter-clockwise, padded with 0).
      ring_corner: ``[V, K]`` int64 which corner of that face the vertex is.
      ring_theta: ``[V, K]`` float64 angle, in the vertex frame (normalised angles), where wedge j
        starts: ``theta`` of :func:`~jmeshtex.geometry.one_ring_angles`; ``inf`` on padded wedges.
      angle_range: ``[V]`` float64 angular extent of the vertex frame: 2π inside, the sum of the
        corner angles on the boundary.
      angle_scale: ``[V]`` float64 ``2π / Σ corner angles`` at interior vertices, 1 on the boundary:
        vertex-frame angle = scale × Euclidean angle inside a wedge.
      boundary: ``[V]`` bool, True on boundary vertices.
    """

    vertices: Float[np.ndarray, "V 3"]
    faces: Int[np.ndarray, "F 3"]
    corners: Complex[np.ndarray, "F 3"]
    exit_table: Float[np.ndarray, "F 5"]
    altitude: Float[np.ndarray, "F 3"]
    neighbor: Int[np.ndarray, "F 3"]
    neighbor_edge: Int[np.ndarray, "F 3"]
    crossing: Complex[np.ndarray, "F 3"]
    crossing_offset: Complex[np.ndarray, "F 3"]
    ring_faces: Int[np.ndarray, "V K"]
    ring_corner: Int[np.ndarray, "V K"]
    ring_theta: Float[np.ndarray, "V K"]
    angle_range: Float[np.ndarray, " V"]
    angle_scale: Float[np.ndarray, " V"]
    boundary: Bool[np.ndarray, " V"]


# --------------------------------------------------------------------------------------------
# tables


def _face_layouts(lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Corner positions ``[F, 3]`` (complex) and doubled areas ``[F]`` from edge lengths ``[F, 3]``.

    ``lengths[:, k]`` is the length of edge k (corner k to corner k+1).
    """
    l0, l1, l2 = lengths.T
    double_area = 2.0 * face_areas(lengths)  # Kahan's stable Heron formula
    # validation's definition (flat_faces); the area test only adds faces whose area under- or
    # overflows float64 (lengths near 1e-154 or 1e154)
    bad = np.nonzero(flat_faces(lengths) | ~(double_area > 0.0) | ~np.isfinite(double_area))[0]
    if bad.size:
        raise DegenerateFaceError(indices=bad)
    x2 = (l0 * l0 + l2 * l2 - l1 * l1) / (2.0 * l0)
    y2 = double_area / l0
    corners = np.stack([np.zeros_like(l0), l0, x2], axis=1) + 1j * np.stack(
        [np.zeros_like(l0), np.zeros_like(l0), y2], axis=1
    )
    return corners, double_area


@accepts_mesh
def tracer_geometry(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    *,
    lengths: Float[np.ndarray, "F 3"] | None = None,
) -> TracerGeometry:
    """Precompute the tables :func:`trace_geodesics` and :func:`trace_from_vertices` walk over.

    Building them costs about as much as tracing a few hundred thousand short geodesics; pass the
    result as ``geometry=`` when tracing the same mesh repeatedly.

    Face layouts come from edge lengths only: for face ``(a, b, c)`` with edge lengths
    ``l0 = |ab|, l1 = |bc|, l2 = |ca|`` the corners sit at ``0``, ``l0`` and
    ``x + iy`` with ``x = (l0² + l2² − l1²) / (2 l0)`` and ``y = 2A / l0`` (A from Kahan's stable
    Heron formula). Crossing edge k into the neighbour rotates a direction by the ratio of the shared
    edge's unit vectors in the two layouts (unfolding).

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` consistently oriented, manifold triangles.
      lengths: ``[F, 3]`` intrinsic edge lengths to lay the faces out with instead of the
        positions' (edge k from corner k to corner k+1, e.g. a coarse level's
        :attr:`~jmeshtex.geometry.MeshHierarchy.lengths`, whose copied positions can make a face
        flat in space that is not flat intrinsically). Default: from ``vertices``.

    Returns:
      :class:`TracerGeometry`.

    Raises:
      DegenerateFaceError: a zero-area face (in ``lengths`` when given).
      InputError: ``lengths`` not ``[F, 3]``, not finite or not positive.
      NonManifoldEdgeError, InconsistentOrientationError, NonManifoldVertexError: from the
        adjacency builders.

    Example:
      >>> from jmeshtex.data import single_triangle
      >>> g = tracer_geometry(*single_triangle())
      >>> bool(np.abs(g.corners - np.array([[0, 1, 1j]])).max() < 1e-15)
      True
      >>> g.neighbor.tolist()
      [[-1, -1, -1]]
    """
    vertices, faces = check_mesh_arrays(vertices, faces)
    if lengths is None:
        lengths = edge_lengths(vertices, faces)
    else:
        lengths = np.asarray(lengths, dtype=np.float64)
        if lengths.shape != faces.shape or not (np.isfinite(lengths).all() and (lengths > 0).all()):
            raise InputError(
                f"tracer_geometry: lengths must be finite, positive and [F, 3] = {faces.shape}, "
                f"got shape {lengths.shape}"
            )
    corners, double_area = _face_layouts(lengths)

    # edge opposite corner k runs from corner k+1 to corner k+2; its inward unit normal is
    # i·(P_{k+2} − P_{k+1}) / |·| and the altitude from corner k is 2A / |edge|
    opposite_edge = np.roll(corners, -2, axis=1) - np.roll(corners, -1, axis=1)
    opposite_len = np.roll(lengths, -1, axis=1)
    normal = 1j * opposite_edge / opposite_len
    altitude = double_area[:, None] / opposite_len
    c0 = (np.conj(normal[:, 0]) * corners[:, 1]).real
    exit_table = np.stack(
        [normal[:, 0].real, normal[:, 0].imag, normal[:, 1].real, normal[:, 1].imag, c0], axis=1
    )

    nb = face_neighborhood(faces, len(vertices))
    has = nb.mask
    g = nb.neighbors.astype(np.int64)
    # which edge m of g is the shared one: g's edge m runs faces[f, k+1] -> faces[f, k]
    start_vertex = np.roll(faces, -1, axis=1)  # faces[f, k+1]
    m = np.argmax(faces[g] == start_vertex[:, :, None], axis=2)
    m = np.where(has, m, 0)
    neighbor = np.where(has, g, -1)

    edge_vec = np.roll(corners, -1, axis=1) - corners  # P_{k+1} − P_k in f's frame
    # the same edge, corner k -> corner k+1 of f, is corner m+1 -> corner m of g
    flat = corners.ravel()
    g_edge = flat[3 * g + m] - flat[3 * g + (m + 1) % 3]
    crossing = g_edge * np.conj(edge_vec)
    crossing = np.where(has, crossing / np.where(has, np.abs(crossing), 1.0), 1.0 + 0j)
    # corner k of f is corner m+1 of g: z_g = Q_{m+1} + crossing · (z_f − P_k)
    crossing_offset = np.where(has, flat[3 * g + (m + 1) % 3] - crossing * corners, 0j)

    # the vertex gauge: the same slot angles as the one-ring log maps
    rings, theta, angle_scale = _angles_from_lengths(faces, lengths, len(vertices))
    ring_faces = rings.wedge_faces.astype(np.int64)
    ring_corner = _wedge_corners(rings, faces).astype(np.int64)
    ring_theta = np.where(rings.wedge_mask, theta, np.inf)
    closing = theta[np.arange(len(vertices)), np.maximum(rings.degree - 1, 0)]
    angle_range = np.where(rings.boundary, closing, np.where(rings.degree > 0, 2.0 * np.pi, 0.0))
    return TracerGeometry(
        vertices=vertices,
        faces=faces,
        corners=corners,
        exit_table=exit_table,
        altitude=altitude,
        neighbor=neighbor,
        neighbor_edge=m,
        crossing=crossing,
        crossing_offset=crossing_offset,
        ring_faces=ring_faces,
        ring_corner=ring_corner,
        ring_theta=ring_theta,
        angle_range=angle_range,
        angle_scale=angle_scale,
        boundary=np.asarray(rings.boundary, bool),
    )


@accepts_mesh
def face_frame_to_world(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    face: Int[np.ndarray, " N"],
    direction: Complex[np.ndarray, " N"],
) -> Float[np.ndarray, "N 3"]:
    """Convert tangent vectors from face-local frames (module docstring) to 3D vectors.

    .. math:: w = \\operatorname{Re}(z)\\, \\hat x_f + \\operatorname{Im}(z)\\, (\\hat n_f \\times \\hat x_f),
       \\qquad \\hat x_f = \\frac{b - a}{|b - a|}

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` triangles ``(a, b, c)``.
      face: ``[N]`` face of each vector.
      direction: ``[N]`` complex vectors in that face's frame.

    Returns:
      ``[N, 3]`` vectors in the plane of each face, of the same length.

    Example:
      >>> from jmeshtex.data import single_triangle
      >>> v, f = single_triangle()
      >>> face_frame_to_world(v, f, np.array([0]), np.array([1j])).tolist()
      [[0.0, 1.0, 0.0]]
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    tri = vertices[np.asarray(faces)[np.asarray(face)]]
    x = tri[:, 1] - tri[:, 0]
    n = np.cross(x, tri[:, 2] - tri[:, 0])
    x = x / np.linalg.norm(x, axis=1, keepdims=True)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    y = np.cross(n, x)
    z = np.asarray(direction, dtype=np.complex128)
    return z.real[:, None] * x + z.imag[:, None] * y


# --------------------------------------------------------------------------------------------
# the walk


def _default_max_steps(geometry: TracerGeometry, length: np.ndarray) -> int:
    """A generous bound on face crossings per trace, only there to turn a hang into an error."""
    min_altitude = float(geometry.altitude.min())
    max_degree = geometry.ring_faces.shape[1]
    span = float(length.max(initial=0.0)) / min_altitude
    return int(64 + 4 * (max_degree + 2) * (2.0 + 2.0 * span))


class _Finished:
    """The traces that ended, collected in chunks while walking and scattered once at the end."""

    def __init__(self):
        self.idx, self.face, self.state, self.stopped = [], [], [], []

    def retire(self, mask, stop: bool, idx, f, state):
        """Move the traces under ``mask`` out of the walking ``(idx, f, state)``; returns those of
        the traces that walk on and the ``keep`` mask."""
        self.idx.append(np.compress(mask, idx))
        self.face.append(np.compress(mask, f))
        self.state.append(np.compress(mask, state, axis=1))
        self.stopped.append(np.full(self.idx[-1].size, stop))
        keep = ~mask
        return np.compress(keep, idx), np.compress(keep, f), np.compress(keep, state, axis=1), keep

    def ends(self, face, position, direction):
        """``(face, position, direction, stopped, remaining)`` of every trace: the retired ones'
        ends, the start for those that never walked (zero length)."""
        end_face = face.copy()
        end = np.stack(
            [position.real, position.imag, direction.real, direction.imag, np.zeros(len(face))]
        )
        stopped = np.zeros(len(face), bool)
        if self.idx:
            out = np.concatenate(self.idx)
            end_face[out] = np.concatenate(self.face)
            end[:, out] = np.concatenate(self.state, axis=1)
            stopped[out] = np.concatenate(self.stopped)
        end_position = end[0] + 1j * end[1]
        end_direction = end[2] + 1j * end[3]
        end_direction = end_direction / np.where(end_direction == 0, 1.0, np.abs(end_direction))
        return end_face, end_position, end_direction, stopped, end[4]


def _exit_times(table, f, state):
    """``(t0, t1, t_exit)``: the distances along each walking trace's unit direction to the edges
    opposite corners 0 and 1 of its face, and to the nearest edge it leaves through (inf: none
    ahead)."""
    x, y, dx, dy, _ = state
    n0x, n0y, n1x, n1y, c0 = np.take(table, f, axis=1)
    # distance to the edge opposite corner k shrinks at rate -cos_k along the unit direction
    cos0 = n0x * dx + n0y * dy
    cos1 = n1x * dx + n1y * dy
    t0 = np.maximum(n0x * x + n0y * y - c0, 0.0) / -cos0
    t1 = np.maximum(n1x * x + n1y * y, 0.0) / -cos1
    t2 = np.maximum(y, 0.0) / -dy
    t0[cos0 >= -_PARALLEL_COS] = np.inf
    t1[cos1 >= -_PARALLEL_COS] = np.inf
    t2[dy >= -_PARALLEL_COS] = np.inf
    return t0, t1, np.minimum(np.minimum(t0, t1), t2)


def _unfold(state, unfold, fe) -> None:
    """Carry positions and directions (rows 0-3 of ``state``, in place) across the face edges
    ``fe`` (``3 * face + edge``) into the next faces' frames."""
    x, y, dx, dy, _ = state
    ar, ai, br, bi = np.take(unfold, fe, axis=1)
    state[0], state[1] = ar * x - ai * y + br, ai * x + ar * y + bi
    state[2], state[3] = ar * dx - ai * dy, ai * dx + ar * dy


def _walk(
    geometry: TracerGeometry,
    face: np.ndarray,
    position: np.ndarray,
    direction: np.ndarray,
    length: np.ndarray,
    max_steps: int | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Walk every trace to its end.

    ``position`` and ``direction`` are complex, in the start face's frame. Returns ``(face,
    position, direction, stopped, remaining)`` at the ends, in the end faces' frames.
    """
    if max_steps is None:
        max_steps = _default_max_steps(geometry, length)
    # row-major tables gathered with np.take (several times faster than fancy indexing)
    table = np.ascontiguousarray(geometry.exit_table.T)
    neighbor = geometry.neighbor.ravel()
    length_tol = _LENGTH_TOL * float(geometry.altitude.mean())
    unfold = np.stack(
        [
            geometry.crossing.real,
            geometry.crossing.imag,
            geometry.crossing_offset.real,
            geometry.crossing_offset.imag,
        ]
    ).reshape(4, -1)

    # state of the walking traces, one column each: x, y, dx, dy, remaining
    idx = np.nonzero(length > 0)[0]
    f = face[idx]
    state = np.stack([position.real, position.imag, direction.real, direction.imag, length])
    state = np.take(state, idx, axis=1)
    finished = _Finished()
    steps = 0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        while idx.size:
            if steps >= max_steps:
                raise InputError(
                    f"{idx.size} traces still walking after {max_steps} face crossings; pass a "
                    "larger max_steps (very long traces) or check the mesh for near-degenerate faces"
                )
            steps += 1
            t0, t1, t_exit = _exit_times(table, f, state)
            x, y, dx, dy, r = state
            # reaching the exit edge within rounding of the remaining length ends the walk there
            done = t_exit >= r - length_tol
            step = np.minimum(t_exit, r)
            x += step * dx
            y += step * dy
            r -= step
            r[done] = 0.0
            if done.any():
                idx, f, state, keep = finished.retire(done, False, idx, f, state)
                if not idx.size:
                    break
                t0, t1, t_exit = (
                    np.compress(keep, t0),
                    np.compress(keep, t1),
                    np.compress(keep, t_exit),
                )

            # leave through the edge opposite corner k (ties, i.e. a vertex hit: lowest k);
            # edge e = k + 1 runs from corner e to corner e + 1
            e = np.where(t0 == t_exit, 1, np.where(t1 == t_exit, 2, 0))
            fe = 3 * f + e
            g = np.take(neighbor, fe)
            wall = g < 0
            if wall.any():
                idx, f, state, keep = finished.retire(wall, True, idx, f, state)
                fe, g = np.compress(keep, fe), np.compress(keep, g)
            _unfold(state, unfold, fe)
            f = g
    return finished.ends(face, position, direction)


def _barycentric(geometry: TracerGeometry, face: np.ndarray, position: np.ndarray) -> np.ndarray:
    """Barycentric coordinates ``[N, 3]`` of face-frame points, clipped into the face."""
    n0x, n0y, n1x, n1y, c0 = np.take(geometry.exit_table, face, axis=0).T
    x, y = position.real, position.imag
    dist = np.stack([n0x * x + n0y * y - c0, n1x * x + n1y * y, y], axis=1)
    bary = np.maximum(dist / np.take(geometry.altitude, face, axis=0), 0.0)
    return bary / bary.sum(axis=1, keepdims=True)


def _trace_indices(index, count: int, name: str) -> np.ndarray:
    """``index`` (the start face or vertex of each trace) as a 1-D integer array in ``[0, count)``,
    or an :class:`~jmeshtex.InputError` that names ``name`` and the first bad traces."""
    index = np.asarray(index)
    if index.ndim != 1 or not np.issubdtype(index.dtype, np.integer):
        raise InputError(f"{name} must be a 1-D integer array [N], got {index.dtype} {index.shape}")
    bad = np.nonzero((index < 0) | (index >= count))[0]
    if bad.size:
        raise InputError(f"{name} out of range [0, {count}) at traces {bad[:10].tolist()}")
    return index


def _as_traces(n_expected: int | None, direction, length, name: str):
    direction = np.asarray(direction)
    if direction.ndim != 1:
        raise InputError(
            f"direction must be a 1-D array of complex numbers [N], got shape {direction.shape}"
        )
    if not np.issubdtype(direction.dtype, np.number) or np.issubdtype(direction.dtype, np.bool_):
        raise InputError(
            f"direction must be complex (or real) numbers, got dtype {direction.dtype}"
        )
    direction = direction.astype(np.complex128)
    n = len(direction) if n_expected is None else n_expected
    if len(direction) != n:
        raise InputError(f"direction has {len(direction)} entries but {name} has {n}")
    length = np.asarray(length, dtype=np.float64)
    if length.ndim > 1 or (length.ndim == 1 and len(length) != n):
        raise InputError(f"length must be a scalar or have shape [{n}], got {length.shape}")
    length = np.broadcast_to(length, (n,)).copy()
    bad = np.nonzero(~np.isfinite(length) | (length < 0))[0]
    if bad.size:
        raise InputError(f"length must be finite and >= 0; bad at traces {bad[:10].tolist()}")
    bad = np.nonzero(~np.isfinite(direction))[0]
    if bad.size:
        raise InputError(f"direction must be finite; bad at traces {bad[:10].tolist()}")
    bad = np.nonzero((direction == 0) & (length > 0))[0]
    if bad.size:
        raise InputError(
            f"direction is zero at traces {bad[:10].tolist()} with a positive length; give a "
            "non-zero direction or length 0"
        )
    unit = direction / np.where(direction == 0, 1.0, np.abs(direction))
    return unit, length


def _geometry_for(vertices, faces, geometry: TracerGeometry | None) -> TracerGeometry:
    if geometry is None:
        return tracer_geometry(vertices, faces)
    if np.shape(faces) != geometry.faces.shape or np.shape(vertices) != geometry.vertices.shape:
        raise InputError(
            "geometry was built for a different mesh (shapes differ); rebuild it with "
            "tracer_geometry(vertices, faces)"
        )
    return geometry


def _result(geometry: TracerGeometry, face, position, direction, stopped, length, remaining):
    bary = _barycentric(geometry, face, position)
    corners = np.take(geometry.vertices, np.take(geometry.faces, face, axis=0), axis=0)
    point = np.einsum("nk,nkd->nd", bary, corners)
    return TraceResult(
        face=face.astype(np.int32),
        bary=bary,
        point=point,
        stopped=stopped,
        travelled=length - remaining,
        direction=direction,
    )


@accepts_mesh
def trace_geodesics(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    start_face: Int[np.ndarray, " N"],
    start_bary: Float[np.ndarray, "N 3"],
    direction: Complex[np.ndarray, " N"],
    length: Float[np.ndarray, " N"] | float,
    *,
    geometry: TracerGeometry | None = None,
    max_steps: int | None = None,
) -> TraceResult:
    """Trace straightest geodesics from points inside faces (discrete exponential map).

    Each trace walks the straight line ``x(t) = x_0 + t·d`` (``|d| = 1``, ``0 ≤ t ≤ length``) in the
    current face's layout; where it leaves through edge k it continues in the neighbour face, its
    position and direction re-expressed by unfolding the two triangles into one plane (Polthier &
    Schmies 1998, straightest geodesics; all data intrinsic: edge lengths only).

    Special cases: a walk that hits a vertex exactly leaves through the edge opposite the
    lowest-numbered corner among the tied ones and keeps unfolding around the vertex until the
    direction lies inside a face (deterministic); a zero length leaves the start point unchanged;
    a walk that reaches a boundary edge stops on it with ``stopped=True``.

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` consistently oriented, manifold triangles.
      start_face: ``[N]`` face each trace starts in.
      start_bary: ``[N, 3]`` barycentric coordinates of the start point in that face (corner
        order of ``faces``); small negative rounding is clipped.
      direction: ``[N]`` complex start direction in the start face's local frame (corner 0 at the
        origin, x along edge 0→1, counter-clockwise; see the module docstring); normalised inside,
        so only its angle matters. May be 0 where ``length`` is 0.
      length: ``[N]`` (or a scalar) geodesic distance to walk, ``>= 0``.
      geometry: tables from :func:`tracer_geometry` for this mesh, to skip rebuilding them.
      max_steps: most face crossings any trace may make (default: a generous bound from the
        lengths and the smallest altitude); exceeding it raises :class:`~jmeshtex.InputError`.

    Returns:
      :class:`TraceResult` with end face, barycentric coordinates, 3D point, boundary flag,
      distance travelled and the unit end direction in the end face's frame.

    Raises:
      InputError: shapes, out-of-range faces, invalid barycentric coordinates, negative or
        non-finite lengths, zero directions with a positive length.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(4)                        # unit square, z = 0, cells of 0.25
      >>> r = trace_geodesics(v, f, np.array([0]), np.array([[1.0, 0.0, 0.0]]),
      ...                     np.array([np.exp(0.25j * np.pi)]), np.array([0.5]))
      >>> r.point.round(6).tolist(), r.stopped.tolist()
      ([[0.353553, 0.353553, 0.0]], [False])
      >>> r = trace_geodesics(v, f, np.array([0]), np.array([[1.0, 0.0, 0.0]]),
      ...                     np.array([1.0 + 0j]), np.array([2.0]))
      >>> r.point.round(6).tolist(), r.stopped.tolist(), r.travelled.tolist()
      ([[1.0, 0.0, 0.0]], [True], [1.0])
    """
    geometry = _geometry_for(vertices, faces, geometry)
    start_face = _trace_indices(start_face, len(geometry.faces), "start_face")
    n = len(start_face)
    bary = np.asarray(start_bary, dtype=np.float64)
    if bary.shape != (n, 3):
        raise InputError(f"start_bary must have shape [{n}, 3], got {bary.shape}")
    sums = bary.sum(axis=1)
    bad = np.nonzero(
        ~np.isfinite(bary).all(1)
        | (bary.min(axis=1, initial=0.0) < -1e-9)
        | (np.abs(sums - 1.0) > 1e-6)
    )[0]
    if bad.size:
        raise InputError(
            f"start_bary must be barycentric coordinates (>= 0, summing to 1); bad at traces "
            f"{bad[:10].tolist()}"
        )
    bary = np.maximum(bary, 0.0)
    bary /= bary.sum(axis=1, keepdims=True)
    unit, length = _as_traces(n, direction, length, "start_face")
    start_face = start_face.astype(np.int64)
    position = np.einsum("nk,nk->n", bary, np.take(geometry.corners, start_face, axis=0))
    face, position, end_dir, stopped, remaining = _walk(
        geometry, start_face, position, unit, length, max_steps
    )
    return _result(geometry, face, position, end_dir, stopped, length, remaining)


def vertex_direction_to_face(
    geometry: TracerGeometry,
    vertex: Int[np.ndarray, " N"],
    direction: Complex[np.ndarray, " N"],
) -> tuple[
    Int[np.ndarray, " N"], Int[np.ndarray, " N"], Complex[np.ndarray, " N"], Bool[np.ndarray, " N"]
]:
    """Find the one-ring wedge a vertex-frame direction points into, and re-express it there.

    The wedge j of vertex p is the one whose vertex-frame range ``[θ_pj, θ_p,j+1)`` (the slot angles
    of :func:`~jmeshtex.geometry.one_ring_angles`) contains ``φ = arg(direction) mod 2π``; inside
    it the direction makes the Euclidean angle ``(φ − θ_pj) / s_p`` with the edge from p to ring
    slot j (``s_p`` the angle scale), so in the face's frame it is ``u_j · e^{i(φ − θ_pj)/s_p}``
    with ``u_j`` that edge's unit vector in the face layout.

    Args:
      geometry: tables from :func:`tracer_geometry`.
      vertex: ``[N]`` vertex indices.
      direction: ``[N]`` complex directions in each vertex's frame (only the angle is used).

    Returns:
      ``(face [N], corner [N], face_direction [N] unit complex, outside [N] bool)``: ``corner`` is
      the vertex's corner in ``face``; ``outside`` is True where a boundary vertex's direction
      points off the surface (then ``face`` is the nearer of the two end wedges).

    Example:
      >>> from jmeshtex.data import grid
      >>> g = tracer_geometry(*grid(2))
      >>> face, corner, d, outside = vertex_direction_to_face(g, np.array([4]), np.array([1j]))
      >>> bool(outside[0]), int(g.faces[face[0], corner[0]])
      (False, 4)
    """
    vertex = np.asarray(vertex, dtype=np.int64)
    phi = np.mod(np.angle(np.asarray(direction, dtype=np.complex128)), 2.0 * np.pi)
    starts = geometry.ring_theta[vertex]
    slot = np.maximum((phi[:, None] >= starts).sum(axis=1) - 1, 0)
    total = geometry.angle_range[vertex]
    boundary = geometry.boundary[vertex]
    # past the last wedge of a boundary vertex (scale 1): continue from the nearer end wedge
    to_first = boundary & (phi > total) & (2.0 * np.pi - phi < phi - total)
    phi = np.where(to_first, phi - 2.0 * np.pi, phi)
    slot = np.where(to_first, 0, slot)
    slot = np.minimum(slot, np.maximum(np.isfinite(starts).sum(axis=1) - 1, 0))
    # off the surface, beyond rounding of the angles; within rounding, snap onto the boundary edge
    outside = boundary & ((phi > total + _ANGLE_TOL) | (phi < -_ANGLE_TOL))
    phi = np.where(boundary & ~outside, np.clip(phi, 0.0, total), phi)
    face = geometry.ring_faces[vertex, slot]
    corner = geometry.ring_corner[vertex, slot]
    layout = geometry.corners[face]
    rows = np.arange(len(vertex))
    edge = layout[rows, (corner + 1) % 3] - layout[rows, corner]
    inside = (phi - starts[rows, slot]) / geometry.angle_scale[vertex]
    face_dir = edge / np.abs(edge) * np.exp(1j * inside)
    return face, corner, face_dir, outside


@accepts_mesh
def trace_from_vertices(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    vertex: Int[np.ndarray, " N"],
    direction: Complex[np.ndarray, " N"],
    length: Float[np.ndarray, " N"] | float,
    *,
    geometry: TracerGeometry | None = None,
    max_steps: int | None = None,
) -> TraceResult:
    """Trace straightest geodesics from vertices, directions given in the intrinsic vertex frames.

    ``exp_p(r e^{iφ})``: the direction's angle φ is measured in p's intrinsic gauge (x-axis along
    the edge to slot 0 of :func:`~jmeshtex.geometry.one_rings`, corner angles scaled to sum to 2π at
    interior vertices, unscaled on the boundary — the frame of the one-ring log maps), turned into a
    Euclidean angle inside one wedge (:func:`vertex_direction_to_face`), and traced from that face
    as in :func:`trace_geodesics`. Hence ``exp_p(log_p(q)) = q`` for every one-ring neighbour q.

    At a boundary vertex a direction outside the surface's angular range ends at once with
    ``stopped=True`` and ``travelled=0`` (unless the length is 0).

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` consistently oriented, manifold triangles.
      vertex: ``[N]`` start vertex of each trace.
      direction: ``[N]`` complex direction in the start vertex's frame (only the angle is used; may
        be 0 where ``length`` is 0).
      length: ``[N]`` (or a scalar) geodesic distance to walk, ``>= 0``.
      geometry: tables from :func:`tracer_geometry` for this mesh, to skip rebuilding them.
      max_steps: see :func:`trace_geodesics`.

    Returns:
      :class:`TraceResult`; ``direction`` is in the end face's local frame.

    Raises:
      InputError: out-of-range or isolated vertices, bad lengths or directions.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)       # vertex 4 is the centre (0.5, 0.5); its x-axis points to vertex 0
      >>> r = trace_from_vertices(v, f, np.array([4, 4]), np.array([1, 1j]), np.sqrt(0.5))
      >>> r.point.round(6).tolist()     # 90° counter-clockwise of (0, 0) is (1, 0)
      [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    """
    geometry = _geometry_for(vertices, faces, geometry)
    vertex = _trace_indices(vertex, len(geometry.vertices), "vertex")
    isolated = np.nonzero(geometry.angle_range[vertex] <= 0)[0]
    if isolated.size:
        raise InputError(
            f"vertices {np.unique(vertex[isolated])[:10].tolist()} belong to no face; "
            "trace only from vertices of the surface"
        )
    unit, length = _as_traces(len(vertex), direction, length, "vertex")
    face, corner, face_dir, outside = vertex_direction_to_face(geometry, vertex, unit)
    face_dir = np.where(unit == 0, 0j, face_dir)
    position = geometry.corners[face, corner]
    walk_length = np.where(outside, 0.0, length)
    face, position, end_dir, stopped, remaining = _walk(
        geometry, face, position, face_dir, walk_length, max_steps
    )
    blocked = outside & (length > 0)
    stopped = stopped | blocked
    remaining = np.where(blocked, length, remaining)
    return _result(geometry, face, position, end_dir, stopped, length, remaining)

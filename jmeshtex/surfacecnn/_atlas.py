"""The texel atlas of a surface CNN: which texels of a ``size × size`` texture lie on the mesh, where.

A texel is *valid* when its square overlaps a triangle of the UV layout (a positive-area
intersection, tested exactly with the separating-axis theorem by
:func:`~jmeshtex.geometry.rasterize_uv` with ``coverage="overlap"``). Its *surface point* is its
centre mapped through the triangle that contains the centre in UV space or, where the centre lies
outside every triangle (texels on chart borders), through the UV triangle nearest to it (the centre
is snapped onto that triangle). Every valid texel also carries an orthonormal tangent frame
``(t, d)``: the exemplar's growing column is read along ``t``, its growing row along ``d``.

**Frames** (``frames=``). The texture is laid out by the UV charts, but the frames must not be: a
frame taken from the UV layout (``"uv"``: ``t`` = growing texel column of the face's chart) jumps at
every chart seam, so an oriented exemplar turns at every seam. ``"global"`` (default; Kovács et al.
2024, Sec. 4.2, and their reference tool) interpolates the per-vertex field
:func:`~jmeshtex.geometry.global_direction_field` of a world vector (``frame_vector``) at the
texel's surface point and projects it on the face plane; ``"smooth"`` does the same with the
smoothest field :func:`~jmeshtex.geometry.smoothest_direction_field` (Knöppel et al. 2013), whose
singularities the geometry places. Both depend only on the surface, so they are continuous across
UV seams. ``d = −i·t`` (``t`` turned clockwise seen from outside) so the exemplar is not mirrored;
the reference tool uses ``n × t`` (mirrored). ``"uv"`` is kept as the ablation. Texel coordinates follow
:mod:`jmeshtex.geometry` (``_texture``): texel ``(row, col)`` is the square
``[col, col + 1] × [row, row + 1]`` of ``(x, y) = (u W, (1 − v) H)``, row 0 at the top (v = 1).

Everything is vectorised NumPy over (triangle, candidate texel) pairs; no loop runs per texel.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from jaxtyping import Complex, Float, Int

from .._config import is_finite_number, is_int
from .._errors import InputError, MeshError
from ..geometry import (
    TracerGeometry,
    check_mesh_scale,
    connection_laplacian,
    face_frame_to_world,
    fill_unused_texels,
    global_direction_field,
    one_ring_neighborhood,
    project_direction,
    rasterize_uv,
    smoothest_direction_field,
    tangent_frames,
    tangent_from_3d,
    tangent_to_3d,
    tracer_geometry,
)
from ._config import FRAME_MODES, FRAME_SMOOTHING


class TextureAtlas(NamedTuple):
    """The valid texels of a square texture on a mesh, with surface points and tangent frames.

    Texel ``n`` (0-based, ``N`` valid texels in row-major order) is pixel ``texel[n]`` =
    ``row · size + col`` of the texture image.

    Attributes:
      size: texture resolution (``size × size``).
      texel: ``[N]`` int64 flat pixel index of each valid texel, increasing.
      index_of: ``[size · size]`` int64 valid-texel number of each pixel, -1 for invalid pixels.
      face: ``[N]`` int64 mesh face of the texel's surface point.
      bary: ``[N, 3]`` float64 barycentric coordinates of the surface point in ``face``.
      point: ``[N, 3]`` float64 surface point (world).
      tangent: ``[N]`` complex128 unit direction ``t`` along which the exemplar's columns grow, in
        ``face``'s local frame (:mod:`jmeshtex.geometry` tracer convention).
      down: ``[N]`` complex128 unit direction ``d`` of growing exemplar row: ``−i·t`` for surface
        frames; for ``frames="uv"`` ``±i·t`` following the chart's orientation (mirrored charts).
      frame: ``[N, 3, 3]`` float64 world frame rows ``(t, d, n)`` (n the face normal).
      uv: ``[F, 3, 2]`` float64 per-corner texture coordinates used.
      texel_size: world length of one texel side: the median over UV triangles of
        ``sqrt(area_3D / area_texels)``.
      local_size: ``[N]`` float64 the same ratio for the texel's own face (texel density varies
        across an atlas: Spot's ranges over a factor of ~10).
    """

    size: int
    texel: Int[np.ndarray, " N"]
    index_of: Int[np.ndarray, " P"]
    face: Int[np.ndarray, " N"]
    bary: Float[np.ndarray, "N 3"]
    point: Float[np.ndarray, "N 3"]
    tangent: Complex[np.ndarray, " N"]
    down: Complex[np.ndarray, " N"]
    frame: Float[np.ndarray, "N 3 3"]
    uv: Float[np.ndarray, "F 3 2"]
    texel_size: float
    local_size: Float[np.ndarray, " N"]

    @property
    def num_texels(self) -> int:
        return int(self.texel.shape[0])

    def rows_cols(self) -> tuple[np.ndarray, np.ndarray]:
        """``(row [N], col [N])`` of every valid texel."""
        return np.divmod(self.texel, self.size)


def unwrap_uv(
    vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"]
) -> Float[np.ndarray, "F 3 2"]:
    """Per-corner texture coordinates of an untextured mesh from an automatic xatlas unwrap.

    xatlas (Young, after Zhou et al. 2004 and Lévy et al. 2002) cuts the surface into charts,
    parametrises each with low distortion and packs them into ``[0, 1]²``. Faces keep their order.

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` triangles.

    Returns:
      ``[F, 3, 2]`` float64 UVs (u right, v up).

    Example:
      >>> from jmeshtex.data import icosphere
      >>> uv = unwrap_uv(*icosphere(1))
      >>> uv.shape, bool(uv.min() >= 0 and uv.max() <= 1)
      ((80, 3, 2), True)
    """
    import xatlas

    check_mesh_scale(vertices, faces, what="unwrap_uv: mesh")  # xatlas loops or fails outside it
    v = np.ascontiguousarray(vertices, dtype=np.float32)
    f = np.ascontiguousarray(faces, dtype=np.uint32)
    vmapping, indices, uvs = xatlas.parametrize(v, f)
    if indices.shape != f.shape or not np.array_equal(vmapping[indices], f):
        raise MeshError(
            "xatlas changed the face order or count; cannot map its UVs back to the faces"
        )
    return uvs.astype(np.float64)[indices]


def uv_face_tangents(
    geometry: TracerGeometry, uv: Float[np.ndarray, "F 3 2"]
) -> tuple[np.ndarray, np.ndarray]:
    """The UV layout's frame of every face: the direction of growing texel column, and the chart side.

    From the Jacobian of the map face plane (tracer layout) → texel coordinates ``(u, 1 − v)``:
    ``t ∝ ∂p/∂col`` and ``side = sign Im(conj(t) · ∂p/∂row)``: −1 where growing row is ``−i·t`` (a
    chart laid out with u right and v up), +1 on mirrored charts. Faces with a degenerate UV
    triangle get ``t = 1``.

    Args:
      geometry: :func:`~jmeshtex.geometry.tracer_geometry` tables.
      uv: ``[F, 3, 2]`` per-corner UVs.

    Returns:
      ``(t [F] complex128 unit in each face's frame, side [F] float64 ±1)``.

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.geometry import tracer_geometry
      >>> v, f = grid(1)
      >>> t, side = uv_face_tangents(tracer_geometry(v, f), v[f][..., :2])
      >>> side.tolist()                                # rows grow downwards: −i·t
      [-1.0, -1.0]
    """
    e1, e2, _, usable, P = _face_edges(geometry, uv, 1.0)
    Q = np.stack([e1, e2], axis=2)  # [F, 2 (col, row), 2 (edge)]
    M = P @ np.linalg.inv(
        np.where(usable[:, None, None], Q, np.eye(2))
    )  # face-plane step per (col, row)
    t = M[:, 0, 0] + 1j * M[:, 1, 0]
    r = M[:, 0, 1] + 1j * M[:, 1, 1]
    t = np.where(usable, t / np.where(np.abs(t) > 0, np.abs(t), 1.0), 1.0 + 0j)
    side = np.sign((np.conj(t) * r).imag)
    return t, np.where(side == 0, 1.0, side)


def _face_edges(geometry: TracerGeometry, uv: Float[np.ndarray, "F 3 2"], size: float):
    """Per face, the edges 0→1 and 0→2 in texel coordinates ``(col, row) = (u, 1 − v) · size``
    (``[F, 2]`` each), their determinant ``[F]``, whether the UV triangle is non-degenerate ``[F]``,
    and the same edges in the face plane of the tracer layout, ``[F, 2 (x, y), 2 (edge)]``."""
    tex = np.stack([uv[..., 0], 1.0 - uv[..., 1]], axis=-1) * size  # [F, 3, 2] (x=col, y=row)
    e1, e2 = tex[:, 1] - tex[:, 0], tex[:, 2] - tex[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    usable = np.abs(det) > 1e-12 * np.maximum(
        np.abs(e1).max(axis=1) * np.abs(e2).max(axis=1), 1e-300
    )
    corners = geometry.corners
    dp = np.stack([corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]], axis=1)
    return e1, e2, det, usable, np.stack([dp.real, dp.imag], axis=1)


def vertex_directions(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    *,
    frames: str = "global",
    frame_vector=(1.0, 0.0, 0.0),
    smoothing: float = 0.0,
) -> Float[np.ndarray, "V 3"]:
    """The per-vertex direction field the texel frames follow (``frames`` ``"global"`` or ``"smooth"``).

    ``"global"``: :func:`~jmeshtex.geometry.global_direction_field` of ``frame_vector`` (the paper's
    construction), heat-smoothed intrinsically over ``smoothing`` (world units; 0 keeps the paper's
    field); ``"smooth"``: :func:`~jmeshtex.geometry.smoothest_direction_field` started from
    ``frame_vector`` (Knöppel et al. 2013).

    **Smoothing.** Projected on each face's plane, a global vector turns across a crease by the
    crease's whole intrinsic kink within one face (the faces' planes jump), so a texture that
    follows the frames must either break its colours along the crease or turn its structure there.
    ``smoothing = r > 0`` spreads that turn over a distance ``r`` on either side: one implicit heat
    step of the field with the connection Laplacian ``L`` (intrinsic transport, so across a fold it
    compares directions *unfolded*) and the vertex areas ``M``,

    .. math:: (M + r^2 L)\\, u = M\\, u_0,

    normalised per vertex. A field that is already parallel (a flat sheet) is unchanged; on smooth
    surfaces it moves by second-order terms; at a crease it no longer turns within a face.
    :func:`texture_atlas` carries the smoothed field into the faces with
    :func:`intrinsic_tangents`; the 3D vectors returned here are for display.

    Returns:
      ``[V, 3]`` unit tangent vectors.

    Example:
      >>> from jmeshtex.data import grid
      >>> vertex_directions(*grid(1))[0].tolist()
      [1.0, 0.0, 0.0]
      >>> vertex_directions(*grid(2), smoothing=0.5)[4].round(12).tolist()  # flat: unchanged
      [1.0, 0.0, 0.0]
    """
    p = np.asarray(frame_vector, dtype=np.float64)
    if not (is_finite_number(smoothing) and smoothing >= 0):
        raise InputError(f"vertex_directions: smoothing must be a number >= 0, got {smoothing!r}")
    if frames == "global":
        field = global_direction_field(vertices, faces, primary=p, secondary=_second(p))
        return _heat_smoothed(vertices, faces, field, float(smoothing), p)
    if frames == "smooth":
        return smoothest_direction_field(vertices, faces, primary=p)
    raise InputError(f"vertex_directions: frames must be 'global' or 'smooth', got {frames!r}")


def _heat_smoothed(vertices, faces, field, radius: float, p: np.ndarray) -> np.ndarray:
    """``field`` after one implicit heat step with the connection Laplacian (:func:`vertex_directions`),
    back in 3D; ``radius = 0`` returns it unchanged."""
    if radius == 0.0:
        return field
    frames = tangent_frames(vertices, faces)
    u = _smoothed_intrinsic(vertices, faces, field, radius, frames)
    return project_direction(
        tangent_to_3d(u, frames), frames.normal, primary=p, secondary=_second(p)
    )


def _smoothed_intrinsic(vertices, faces, field, radius: float, frames) -> np.ndarray:
    """``[V]`` complex unit directions in the one-ring gauges: ``(M + r² L) u = M u₀``, ``u₀`` the 3D
    ``field`` in the vertex frames (vertices where ``u`` vanishes keep ``u₀``)."""
    from scipy.sparse import diags
    from scipy.sparse.linalg import splu

    L, area = connection_laplacian(vertices, faces)
    u0 = tangent_from_3d(np.asarray(field, np.float64), frames).astype(np.complex128)
    u = splu((diags(area.astype(np.complex128)) + radius**2 * L).tocsc()).solve(area * u0)
    small = np.abs(u) <= 1e-9 * max(float(np.abs(u).max(initial=0.0)), 1e-300)
    u = np.where(small, u0, u)
    return u / np.maximum(np.abs(u), 1e-300)


def intrinsic_tangents(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    u: Complex[np.ndarray, " V"],
    face: Int[np.ndarray, " N"],
    bary: Float[np.ndarray, "N 3"],
) -> Complex[np.ndarray, " N"]:
    """Unit tangents at surface points from an intrinsic vertex field, carried into each face
    intrinsically.

    Corner ``k`` of face ``f`` carries ``u_{v_k}`` (one-ring gauge) into ``f``'s local frame by the
    angle between the face's edges at the corner and the same edges in the one-ring,
    ``z_k = u_{v_k} e^{i(\\arg_f e - \\theta_e)}`` (averaged over the corner's two edges), then

    .. math:: t = \\textstyle\\sum_k b_k z_k \\,/\\, \\lVert\\cdot\\rVert.

    Unlike projecting a 3D vertex vector on the face plane, this uses edge lengths only: across a
    fold both faces receive the vertex's direction unfolded, at its intrinsic angle (a projection
    from the vertex's averaged plane squeezes it towards the fold line, so a smoothed field would
    turn within the faces next to a crease again; measured in ``tests/surfacecnn``).

    Args:
      vertices, faces: the mesh.
      u: ``[V]`` complex directions in the one-ring gauges of
        :func:`~jmeshtex.geometry.one_ring_neighborhood` (slot 0 the reference edge).
      face: ``[N]`` faces of the points.
      bary: ``[N, 3]`` barycentric coordinates in them.

    Returns:
      ``[N]`` complex128 unit tangents in each face's local frame (tracer convention, as
      :func:`surface_tangents`).

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.geometry import tangent_frames, tangent_from_3d
      >>> v, f = grid(2)
      >>> u = tangent_from_3d(np.tile([1.0, 0.0, 0.0], (len(v), 1)), tangent_frames(v, f))
      >>> t = intrinsic_tangents(v, f, u, np.arange(len(f)), np.full((len(f), 3), 1 / 3))
      >>> bool(np.allclose(t, surface_tangents(v, f, np.tile([1.0, 0, 0], (len(v), 1)),
      ...     np.arange(len(f)), np.full((len(f), 3), 1 / 3))))
      True
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    V = len(vertices)
    nb = one_ring_neighborhood(vertices, faces, scale=None)
    index, mask = np.asarray(nb.index, np.int64), np.asarray(nb.mask, bool)
    rows = np.broadcast_to(np.arange(V)[:, None], index.shape)
    keys = rows[mask] * V + index[mask]
    order = np.argsort(keys)
    keys, unit_log = keys[order], np.asarray(nb.log)[mask][order]
    unit_log = unit_log / np.maximum(np.abs(unit_log), 1e-300)

    def ring_direction(a, b):  # unit direction of edge a→b in a's one-ring gauge
        return unit_log[np.clip(np.searchsorted(keys, a * V + b), 0, len(keys) - 1)]

    tri = vertices[faces[face]]  # [N, 3, 3]
    x = tri[:, 1] - tri[:, 0]
    n = np.cross(x, tri[:, 2] - tri[:, 0])
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    y = np.cross(n, x)
    rel = tri - tri[:, :1]
    corner = np.sum(rel * x[:, None], axis=2) + 1j * np.sum(rel * y[:, None], axis=2)  # [N, 3]
    t = np.zeros(len(face), np.complex128)
    vs = faces[face]
    for k in range(3):
        turn = 0.0
        for j in (1, 2):
            edge = corner[:, (k + j) % 3] - corner[:, k]
            turn = turn + edge / np.abs(edge) * np.conj(
                ring_direction(vs[:, k], vs[:, (k + j) % 3])
            )
        turn /= np.maximum(np.abs(turn), 1e-300)
        t += bary[:, k] * u[vs[:, k]] * turn
    return t / np.maximum(np.abs(t), 1e-300)


def _second(p: np.ndarray) -> np.ndarray:
    """The fallback vector where a face is orthogonal to ``p``: the axis least along ``p`` (y for the
    default x, as in the reference tool)."""
    p = np.asarray(p, dtype=np.float64)
    if p.shape != (3,) or not np.isfinite(p).all() or not np.any(p):
        raise InputError(f"frame_vector must be a finite non-zero 3-vector, got {p!r}")
    return np.eye(3)[np.argmin(np.abs(p))]


def surface_tangents(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    field: Float[np.ndarray, "V 3"],
    face: Int[np.ndarray, " N"],
    bary: Float[np.ndarray, "N 3"],
    *,
    frame_vector=(1.0, 0.0, 0.0),
) -> np.ndarray:
    """Unit tangents at surface points: the vertex field interpolated, projected on the face plane.

    .. math:: t = \\Pi_{n_f} \\textstyle\\sum_k b_k\\, t_{v_k} \\,/\\, \\lVert\\cdot\\rVert

    (the reference tool's construction); where it vanishes, the projection of ``frame_vector``.

    Args:
      vertices, faces: the mesh.
      field: ``[V, 3]`` vertex directions (:func:`vertex_directions`).
      face: ``[N]`` faces of the points.
      bary: ``[N, 3]`` barycentric coordinates in them.
      frame_vector: the fallback's global vector.

    Returns:
      ``[N]`` complex128 unit tangents in each face's local frame (tracer convention).

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(1)
      >>> surface_tangents(v, f, vertex_directions(v, f), np.array([0]), np.array([[1, 1, 1]]) / 3).round(6)
      array([1.+0.j])
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    tri = vertices[np.asarray(faces)[face]]
    x = tri[:, 1] - tri[:, 0]
    n = np.cross(x, tri[:, 2] - tri[:, 0])
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    y = np.cross(n, x)
    p = np.asarray(frame_vector, dtype=np.float64)
    interp = np.einsum("nk,nkd->nd", bary, field[np.asarray(faces)[face]])
    t = project_direction(interp, n, primary=p, secondary=_second(p))
    z = np.sum(t * x, axis=1) + 1j * np.sum(t * y, axis=1)
    return z / np.abs(z)


def texture_atlas(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    uv: Float[np.ndarray, "F 3 2"] | None,
    *,
    size: int,
    frames: str = "global",
    frame_vector=(1.0, 0.0, 0.0),
    frame_smoothing: float = FRAME_SMOOTHING,
    geometry: TracerGeometry | None = None,
) -> TextureAtlas:
    """Valid texels, surface points, world texel size and tangent frames of a ``size²`` texture.

    For each triangle with UV corners in texel coordinates ``P_k = (u_k W, (1 − v_k) H)`` the
    candidate texels are those of its bounding box; a candidate is valid where its square and the
    triangle overlap with positive area (separating axes: the square's two and the triangle's three
    edge normals). The surface point of a valid texel is the centre ``c`` mapped through the triangle
    containing it, or through the overlapping triangle whose closest point to ``c`` is nearest (snap).
    The tangent frame follows ``frames`` (module docstring): a surface direction field interpolated
    at the point (``"global"``, ``"smooth"``), or the Jacobian of the face's map from its plane to
    texel coordinates, ``t ∝ ∂p/∂x`` (``"uv"``, :func:`uv_face_tangents`). The world texel size is

    .. math:: h = \\operatorname{median}_f \\sqrt{A^{3D}_f / A^{tex}_f}

    over faces with a non-degenerate UV triangle (Kovács et al. 2024, Sec. 4.1).

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` consistently oriented, manifold triangles.
      uv: ``[F, 3, 2]`` per-corner UVs (``Mesh.uv``), or None to unwrap with :func:`~jmeshtex.surfacecnn.unwrap_uv`.
      size: texture resolution.
      frames: ``"global"`` (default), ``"smooth"`` or ``"uv"`` (module docstring).
      frame_vector: the world vector of the ``"global"`` field (start of the ``"smooth"`` one).
      frame_smoothing: radius, in texels, over which the ``"global"`` field turns at creases
        (:func:`vertex_directions` ``smoothing``; default ``FRAME_SMOOTHING``, measured in
        ``docs/results.md``); 0 is the paper's field.
      geometry: :func:`~jmeshtex.geometry.tracer_geometry` tables, to skip rebuilding them.

    Returns:
      :class:`TextureAtlas`.

    Raises:
      InputError: bad ``size``, ``frames`` or ``uv`` shape / values; no valid texel.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> atlas = texture_atlas(v, f, v[f][..., :2], size=4)       # identity UVs
      >>> atlas.num_texels, round(atlas.texel_size, 12), atlas.point[0].round(3).tolist()
      (16, 0.25, [0.125, 0.875, 0.0])
    """
    if not is_int(size, 1):
        raise InputError(f"texture_atlas: size must be a positive integer, got {size!r}")
    size = int(size)
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if geometry is None:
        geometry = tracer_geometry(vertices, faces)
    uv = _checked_uv(vertices, faces, uv)
    texel, index_of, face, bary = _nearest_triangle_texels(uv, size)
    point = np.einsum("nk,nkd->nd", bary, vertices[faces[face]])
    if frames not in FRAME_MODES:
        raise InputError(f"texture_atlas: frames must be one of {FRAME_MODES}, got {frames!r}")
    if not (is_finite_number(frame_smoothing) and frame_smoothing >= 0):
        raise InputError(
            f"texture_atlas: frame_smoothing must be a number of texels >= 0, got {frame_smoothing!r}"
        )
    ratio, usable = _world_per_texel(geometry, uv, size)
    texel_size = float(np.median(ratio[usable]))
    tangent, down, frame = _texel_frames(
        vertices,
        faces,
        geometry,
        uv,
        face,
        bary,
        frames=frames,
        frame_vector=frame_vector,
        smoothing=float(frame_smoothing) * texel_size,
    )
    return TextureAtlas(
        size=size,
        texel=texel,
        index_of=index_of,
        face=face,
        bary=bary,
        point=point,
        tangent=tangent,
        down=down,
        frame=frame,
        uv=uv,
        texel_size=texel_size,
        local_size=ratio[face],
    )


def _checked_uv(
    vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"], uv
) -> Float[np.ndarray, "F 3 2"]:
    """Per-corner UVs as float64 ``[F, 3, 2]``, unwrapped when None; bad shape or values refused."""
    if uv is None:
        uv = unwrap_uv(vertices, faces)
    uv = np.asarray(uv, dtype=np.float64)
    if uv.shape != (len(faces), 3, 2):
        raise InputError(
            f"texture_atlas: uv must be [F, 3, 2] = [{len(faces)}, 3, 2], got {uv.shape}"
        )
    if not np.isfinite(uv).all():
        raise InputError(
            "texture_atlas: uv contains NaN or infinite values; fix the UVs or pass uv=None to unwrap"
        )
    return uv


def _nearest_triangle_texels(uv: Float[np.ndarray, "F 3 2"], size: int) -> tuple:
    """Valid texels (increasing flat pixel index), each with the UV triangle that holds its surface
    point: the nearest overlapping one, the lowest face index on ties.

    Returns ``(texel [N], index_of [size²], face [N], bary [N, 3])``."""
    texels = rasterize_uv(uv, size, coverage="overlap")
    if texels.face.size == 0:
        raise InputError(
            f"texture_atlas: no texel of the {size}×{size} texture overlaps a UV triangle; check that the "
            "UVs lie in [0, 1]² and are not degenerate, or pass uv=None to unwrap with xatlas"
        )
    tri, row, col, bary, dist = texels.face, texels.row, texels.col, texels.bary, texels.distance
    pixel = row * size + col
    order = np.lexsort((tri, dist, pixel))  # per pixel: nearest triangle first, then lowest index
    pixel, tri, bary = pixel[order], tri[order], bary[order]
    first = np.ones(len(pixel), bool)
    first[1:] = pixel[1:] != pixel[:-1]
    texel, face, bary = pixel[first], tri[first], bary[first]
    index_of = np.full(size * size, -1, np.int64)
    index_of[texel] = np.arange(len(texel))
    return texel, index_of, face, bary


def _texel_frames(
    vertices, faces, geometry, uv, face, bary, *, frames, frame_vector, smoothing=0.0
) -> tuple:
    """Each texel's tangent ``t`` and ``down`` in its face's frame and its world frame
    ``[N, 3 (t, d, n), 3]`` (module docstring, "Frames")."""
    t, side = uv_face_tangents(geometry, uv)
    if frames == "uv":
        tangent = t[face]
        down = (1j * side)[face] * tangent
        normal_sign = side[face][:, None]
    else:
        field = vertex_directions(vertices, faces, frames=frames, frame_vector=frame_vector)
        if frames == "global" and smoothing > 0:  # intrinsic all the way (vertex_directions)
            u = _smoothed_intrinsic(
                vertices, faces, field, smoothing, tangent_frames(vertices, faces)
            )
            tangent = intrinsic_tangents(vertices, faces, u, face, bary)
        else:
            tangent = surface_tangents(
                vertices, faces, field, face, bary, frame_vector=frame_vector
            )
        down = -1j * tangent  # t turned clockwise seen from outside: the exemplar is not mirrored
        normal_sign = -1.0
    tw = face_frame_to_world(vertices, faces, face, tangent)
    dw = face_frame_to_world(vertices, faces, face, down)
    return tangent, down, np.stack([tw, dw, np.cross(tw, dw) * normal_sign], axis=1)


def _world_per_texel(
    geometry: TracerGeometry, uv: Float[np.ndarray, "F 3 2"], size: int
) -> tuple[Float[np.ndarray, " F"], np.ndarray]:
    """Per face, world length per texel ``sqrt(A3D / Atex)`` and whether its UV triangle is
    non-degenerate (the faces the median texel size is taken over)."""
    _, _, tex_det, usable, P = _face_edges(geometry, uv, size)
    area3 = 0.5 * np.abs(P[:, 0, 0] * P[:, 1, 1] - P[:, 0, 1] * P[:, 1, 0])
    ratio = np.sqrt(area3 / np.where(usable, 0.5 * np.abs(tex_det), 1.0))
    return ratio, usable


def texels_to_image(
    atlas: TextureAtlas, values: Float[np.ndarray, "N C"], *, fill: str = "nearest"
) -> Float[np.ndarray, "S S C"]:
    """Scatter per-texel values into a ``size × size`` image in the mesh's UV layout.

    Invalid pixels take the value of the nearest valid texel (``fill="nearest"``, a dilation that
    keeps bilinear lookups and mip-maps from bleeding background into the charts' borders) or 0
    (``fill="zero"``).

    Args:
      atlas: the :class:`TextureAtlas`.
      values: ``[N, C]`` one row per valid texel (atlas order).
      fill: ``"nearest"`` or ``"zero"`` for the invalid pixels.

    Returns:
      ``[size, size, C]`` image, row 0 at the top (v = 1), dtype of ``values``.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(1)
      >>> atlas = texture_atlas(v, f, v[f][..., :2] * 0.5, size=4)  # the lower-left quarter
      >>> img = texels_to_image(atlas, np.arange(atlas.num_texels, dtype=float)[:, None])
      >>> img[..., 0].tolist()
      [[0.0, 1.0, 1.0, 1.0], [0.0, 1.0, 1.0, 1.0], [0.0, 1.0, 1.0, 1.0], [2.0, 3.0, 3.0, 3.0]]
    """
    values = np.asarray(values)
    if values.ndim != 2 or len(values) != atlas.num_texels:
        raise InputError(
            f"texels_to_image: values must be [N, C] with N = {atlas.num_texels}, got {values.shape}"
        )
    if fill not in ("nearest", "zero"):
        raise InputError(f"texels_to_image: fill must be 'nearest' or 'zero', got {fill!r}")
    size = atlas.size
    image = np.zeros((size * size, values.shape[1]), values.dtype)
    image[atlas.texel] = values
    image = image.reshape(size, size, -1)
    if fill == "nearest":
        image = fill_unused_texels(image, (atlas.index_of >= 0).reshape(size, size))
    return image


def image_to_texels(
    atlas: TextureAtlas, image: Float[np.ndarray, "H W C"]
) -> Float[np.ndarray, "N C"]:
    """Read a texture image at the valid texels (resampled bilinearly when its size differs).

    Args:
      atlas: the :class:`TextureAtlas`.
      image: ``[H, W, C]`` texture in the mesh's UV layout, row 0 at the top (v = 1).

    Returns:
      ``[N, C]`` values at the valid texels' centres (atlas order).

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(1)
      >>> atlas = texture_atlas(v, f, v[f][..., :2], size=2)
      >>> image_to_texels(atlas, np.arange(4.0).reshape(2, 2, 1))[:, 0].tolist()
      [0.0, 1.0, 2.0, 3.0]
    """
    image = np.asarray(image)
    if image.ndim != 3:
        raise InputError(f"image_to_texels: image must be [H, W, C], got {image.shape}")
    if image.shape[:2] == (atlas.size, atlas.size):
        return image.reshape(-1, image.shape[2])[atlas.texel]
    from ..geometry import sample_texture

    row, col = atlas.rows_cols()
    centre = np.stack([(col + 0.5) / atlas.size, 1.0 - (row + 0.5) / atlas.size], axis=1)
    return sample_texture(image.astype(np.float64), centre)


def texel_density_spread(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    uv: Float[np.ndarray, "F 3 2"],
) -> dict[str, float]:
    """How much the world size of a texel varies over a UV layout (1 = an even texel density).

    Every face with a non-degenerate UV triangle has the scale ``sqrt(area_3D / area_UV)``; the
    spread is the ratio of its 95th to its 5th percentile over the surface (area-weighted), and of
    its largest to its smallest value. An xatlas unwrap (:func:`~jmeshtex.surfacecnn.unwrap_uv`)
    keeps it near 1.

    Returns:
      ``{"ratio_p95_p5": r, "ratio_max_min": r, "degenerate_share": share of faces skipped}``.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> uv = v[f][..., :2].copy()
      >>> uv[:4] *= 0.5                                # two of the 8 faces drawn at half size
      >>> texel_density_spread(v, f, uv)["ratio_max_min"]
      2.0
    """
    tri = np.asarray(vertices, np.float64)[np.asarray(faces)]
    area3 = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    area2 = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    ok = (area2 > 1e-14 * max(float(area2.max(initial=0.0)), 1e-300)) & (area3 > 0)
    if not ok.any():
        raise InputError("texel_density_spread: every UV triangle is degenerate; give real UVs")
    scale = np.sqrt(area3[ok] / area2[ok])
    order = np.argsort(scale)
    cum = np.cumsum(area3[ok][order]) / area3[ok].sum()
    p5, p95 = scale[order][np.searchsorted(cum, [0.05, 0.95])]
    return {
        "ratio_p95_p5": float(p95 / p5),
        "ratio_max_min": float(scale.max() / scale.min()),
        "degenerate_share": float(1.0 - ok.mean()),
    }

"""Intrinsic one-ring log maps and discrete Levi-Civita transport, from edge lengths only.

Each vertex p gets a tangent frame whose x-axis is the edge to the first neighbour of its
counter-clockwise one-ring (slot 0, the gauge). Corner angles come from edge lengths
(:func:`~jmeshtex.geometry.corner_angles`), accumulate counter-clockwise from slot 0, and at interior
vertices are rescaled so they sum to 2π (boundary vertices keep their true angles). Then

.. math::
    \\log_p(q_j) = \\ell_{pq_j}\\, e^{i\\theta_{pj}}, \\qquad
    \\rho_{q\\to p} = e^{i(\\theta_{pq} - \\theta_{qp} + \\pi)},

where ``θ_qp`` is the angle of edge (q, p) in q's frame. The transport carries the direction of the
edge as seen from q, reversed, onto the direction of the edge as seen from p; it is the discrete
Levi-Civita connection with the angle defect of each vertex spread over its corners in proportion to
their angles (Knöppel et al. 2013, "Globally optimal direction fields", §6; Sharp et al. 2019,
"The Vector Heat Method", §5.1). Consequences used in tests: ``ρ_{q→p} log_q(p) = -log_p(q)`` holds to
rounding for every edge, and the transport around the boundary of a face (a, b, c) rotates by
``Σ_v (s_v - 1) α_v`` with ``s_v`` the angle scale of each corner's vertex.

Nothing here reads vertex positions except through edge lengths, so every output is unchanged (to
~1e-14 in float64) when a sheet is folded along mesh lines.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._config import is_finite_number
from .._errors import DegenerateFaceError, InputError
from .._mesh import accepts_mesh
from .._neighborhoods import VertexNeighborhood, scale_log_maps
from .._types import Float, Int
from ._adjacency import OneRings, one_rings
from ._intrinsic import check_mesh, corner_angles, edge_lengths, face_areas, vertex_areas
from ._validate import check_mesh_arrays


class OneRingAngles(NamedTuple):
    """Ordered one-rings with the angle of every slot in its vertex's (normalised) frame.

    The exp-map tracer (``jmeshtex/geometry/_tracer.py``) relies on this record to turn a tangent
    direction ``φ`` at a vertex into a face and an in-face direction: the wedge ``j`` with
    ``theta[p, j] <= φ < theta[p, j + 1]`` (the last wedge of an interior vertex ends at 2π) is the
    face ``rings.wedge_faces[p, j]``, and inside it the direction makes the Euclidean angle
    ``(φ - theta[p, j]) / scale[p]`` with the edge from p to ``rings.ring[p, j]``.

    Attributes:
      rings: the counter-clockwise :class:`~jmeshtex.geometry.OneRings` (topology).
      theta: ``[V, K]`` angle of slot j (edge p → ``ring[p, j]``) in p's frame: the scaled sum of
        the corner angles of wedges ``0 .. j-1``; 0 on slot 0 and on padding.
      scale: ``[V]`` ``2π / Σ corner angles`` at interior vertices, 1 at boundary (and isolated)
        vertices.
    """

    rings: OneRings
    theta: Float[np.ndarray, "V K"]
    scale: Float[np.ndarray, " V"]


@accepts_mesh
def one_ring_angles(
    vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"]
) -> OneRingAngles:
    """Ordered one-rings and the normalised angle of every slot (the gauge of each vertex).

    .. math:: \\theta_{pj} = s_p \\sum_{i<j} \\alpha_{p,i}, \\qquad
              s_p = 2\\pi / \\textstyle\\sum_i \\alpha_{p,i}\\ \\text{(interior)},\\ 1\\ \\text{(boundary)}

    with ``α_{p,i}`` the corner angle of p in wedge i (from edge lengths).

    Args:
      vertices: ``[V, 3]`` positions (only edge lengths are used).
      faces: ``[F, 3]`` consistently oriented manifold triangles.

    Returns:
      :class:`OneRingAngles` ``(rings, theta [V, K], scale [V])``.

    Raises:
      MeshError: (a subclass) malformed or non-manifold input.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import icosahedron
      >>> rings, theta, scale = one_ring_angles(*icosahedron())
      >>> np.round(theta[0, :5] / (2 * np.pi / 5), 12).tolist(), round(float(scale[0]), 12)
      ([0.0, 1.0, 2.0, 3.0, 4.0], 1.2)
    """
    v, f = check_mesh(vertices, faces)
    return _angles_from_lengths(f, edge_lengths(v, f), len(v))


@accepts_mesh
def one_ring_neighborhood(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    *,
    lengths: Float[np.ndarray, "F 3"] | None = None,
    scale: str | float | None = "mean_edge",
) -> VertexNeighborhood:
    """Intrinsic one-ring neighbourhoods: log map, transport and areas of every vertex.

    .. math::
        \\log_p(q_j) = \\ell_{pq_j} e^{i\\theta_{pj}}, \\qquad
        \\rho_{q\\to p} = e^{i(\\theta_{pq} - \\theta_{qp} + \\pi)}

    (Mitchel et al. 2021, "Field Convolutions", §4: one-ring log map and transport; angles from
    edge lengths; the docs' Concepts page, "Frames and gauges").

    Args:
      vertices: ``[V, 3]`` positions (only edge lengths are used).
      faces: ``[F, 3]`` consistently oriented manifold triangles.
      lengths: ``[F, 3]`` intrinsic edge lengths to use instead of the positions' (edge k from
        corner k to corner k+1; e.g. :attr:`~jmeshtex.geometry.MeshHierarchy.lengths` of a coarse
        level, whose copied positions can make a face flat in space). Then only the arrays' shapes
        and indices are checked (the faces must already be a valid manifold), and the lengths
        must be finite, positive and give every face a positive area.
      scale: the unit of ``log``. ``"mean_edge"`` (default): the mean edge length
        (:func:`~jmeshtex.geometry.mean_edge_length`, or of ``lengths``), so a neighbour one edge
        away sits at ``|log|`` ≈ 1 on any mesh, the scale field-convolution filters see. A
        positive float: that length. Either is recorded in ``log_unit``
        (:func:`~jmeshtex.scale_log_maps`). ``None``: mesh units, unrecorded (``log_unit`` None;
        for geometry that measures lengths, e.g. MeshMatch's fans).

    Returns:
      :class:`~jmeshtex.VertexNeighborhood` with ``K`` = maximum degree: ``index`` the
      counter-clockwise one-ring (slot 0 = gauge reference edge, no self slot), ``log`` in p's
      frame, ``transport`` from q's frame to p's, ``weight`` the barycentric area of q, ``area``
      the barycentric area of p. Padding: index 0, mask False, log 0, transport 1, weight 0.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import grid
      >>> nb = one_ring_neighborhood(*grid(2), scale=None)  # in mesh units
      >>> p = 4  # the centre vertex (1/2, 1/2)
      >>> nb.index[p, :nb.mask[p].sum()].tolist()  # counter-clockwise, from the corner (0, 0)
      [0, 1, 2, 5, 8, 7, 6, 3]
      >>> z = nb.log[p, :3] / nb.log[p, 0]  # 45° steps; the diagonal neighbours are √2 farther
      >>> np.round(np.angle(z, deg=True), 9).tolist(), np.round(np.abs(z) ** 2, 12).tolist()
      ([0.0, 45.0, 90.0], [1.0, 0.5, 1.0])
      >>> unit = one_ring_neighborhood(*grid(2))  # default: mean edges (12 of 1/2, 4 of √2/2), recorded
      >>> round(float(unit.log_unit), 6), round(float(abs(unit.log[p, 0]) * unit.log_unit), 6)
      (0.551777, 0.707107)
    """
    check_scale(scale)
    if lengths is None:
        v, f = check_mesh(vertices, faces)
        lengths = edge_lengths(v, f)
        return apply_scale(_neighborhood_from_lengths(f, lengths, len(v)), scale, f, lengths)
    v, f = check_mesh_arrays(vertices, faces)
    lengths = np.asarray(lengths, dtype=np.float64)
    if lengths.shape != f.shape or not (np.isfinite(lengths).all() and (lengths > 0).all()):
        raise InputError(
            f"one_ring_neighborhood: lengths must be finite, positive and [F, 3] = {f.shape}, "
            f"got shape {lengths.shape}"
        )
    bad = np.nonzero(~(face_areas(lengths) > 0.0))[0]
    if bad.size:
        raise DegenerateFaceError(indices=bad)
    return apply_scale(_neighborhood_from_lengths(f, lengths, len(v)), scale, f, lengths)


def check_scale(scale) -> None:
    """Raise :class:`~jmeshtex.InputError` unless ``scale`` is None, ``"mean_edge"`` or a positive float."""
    if scale is None or (isinstance(scale, str) and scale == "mean_edge"):
        return
    if not (is_finite_number(scale) and scale > 0):
        raise InputError(f'scale must be None, "mean_edge" or a positive length, got {scale!r}')


def apply_scale(
    nbhd: VertexNeighborhood, scale, faces: np.ndarray, lengths: np.ndarray
) -> VertexNeighborhood:
    """``nbhd`` with log maps in units of ``scale`` (:func:`check_scale`'s values; ``None``: as is).

    ``"mean_edge"`` is the mean over the undirected edges of ``lengths`` (``[F, 3]``, edge k from
    corner k to corner k+1), each counted once.
    """
    if scale is None:
        return nbhd
    if scale == "mean_edge":
        a, b = faces, np.roll(faces, -1, axis=1)
        keys = np.minimum(a, b).astype(np.int64) * (int(faces.max()) + 1) + np.maximum(a, b)
        _, first = np.unique(keys.ravel(), return_index=True)
        scale = float(np.asarray(lengths, np.float64).ravel()[first].mean())
    return scale_log_maps(nbhd, scale)


# ---------------------------------------------------------------------------------------------
# building blocks shared with _knn and _hierarchy (which call them with intrinsic lengths that do
# not come from vertex positions)


def _wedge_corners(rings: OneRings, faces: np.ndarray) -> np.ndarray:
    """``[V, K]`` corner index (0, 1, 2) of p inside each wedge face ``rings.wedge_faces[p, j]``."""
    p = np.arange(rings.ring.shape[0])[:, None]
    corner = np.argmax(faces[rings.wedge_faces] == p[..., None], axis=-1)
    return np.where(rings.wedge_mask, corner, 0)


def _angles_from_lengths(
    faces: np.ndarray, lengths: np.ndarray, num_vertices: int
) -> OneRingAngles:
    rings = one_rings(faces, num_vertices)
    corner = _wedge_corners(rings, faces)
    alpha = np.where(rings.wedge_mask, corner_angles(lengths)[rings.wedge_faces, corner], 0.0)
    total = alpha.sum(axis=1)
    interior = ~rings.boundary & (total > 0.0)
    scale = np.where(interior, 2.0 * np.pi / np.where(interior, total, 1.0), 1.0)
    cum = np.cumsum(alpha, axis=1)
    theta = np.concatenate([np.zeros((len(total), 1)), cum[:, :-1]], axis=1) * scale[:, None]
    theta = np.where(rings.mask, theta, 0.0)
    return OneRingAngles(rings, theta, scale)


def _slot_lengths(rings: OneRings, faces: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """``[V, K]`` length of the edge p → ``ring[p, j]`` (0 on padding)."""
    corner = _wedge_corners(rings, faces)
    wf = rings.wedge_faces
    # slot j opens wedge j: its edge is the first edge of p's corner in that face
    out = np.where(rings.wedge_mask, lengths[wf, corner], 0.0)
    # the last slot of a boundary fan closes the last wedge: the edge entering p's corner
    last = np.nonzero(rings.boundary & (rings.degree >= 2))[0]
    j = rings.degree[last] - 1
    out[last, j] = lengths[wf[last, j - 1], (corner[last, j - 1] + 2) % 3]
    return out


def _reverse_slots(index: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``[V, K]`` slot of p in the ring of ``q = index[p, j]`` (0 on padding)."""
    V = index.shape[0]
    p, j = np.nonzero(mask)
    q = index[p, j].astype(np.int64)
    keys = p * V + q
    order = np.argsort(keys)
    pos = np.searchsorted(keys[order], q * V + p)
    rev = np.zeros_like(index, dtype=np.int64)
    rev[p, j] = j[order[pos]]
    return rev


def _neighborhood_from_lengths(
    faces: np.ndarray, lengths: np.ndarray, num_vertices: int
) -> VertexNeighborhood:
    rings, theta, _ = _angles_from_lengths(faces, lengths, num_vertices)
    mask = rings.mask
    index = rings.ring
    radius = _slot_lengths(rings, faces, lengths)
    log = np.where(mask, radius * np.exp(1j * theta), 0.0)
    rev = _reverse_slots(index, mask)
    theta_qp = theta[index, rev]
    transport = np.where(mask, np.exp(1j * (theta - theta_qp + np.pi)), 1.0)
    area = vertex_areas(faces, face_areas(lengths), num_vertices)
    return VertexNeighborhood(
        index=index.astype(np.int32),
        mask=mask,
        log=log,
        transport=transport,
        weight=np.where(mask, area[index], 0.0),
        area=area,
        vertex_mask=np.ones(num_vertices, bool),
    )

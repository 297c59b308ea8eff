"""A texture measure independent of tessellation: knobs per area and a patch distribution distance.

A transfer's output and its ground truth (:func:`~jmeshtex.dgts.core.oracle_texture`) share one
undisplaced base (``Transfer.base`` with ``.faces``). Everything here is measured on that base,
in units of the texture's period ``P`` (given in mean edges of the *base*, one length for every mesh
scored on it; no mesh is normalised by its own edges):

- heights: the displacement along the base's vertex normals, ``d_i = (v_i − b_i)·n_i / P``,
  band-passed with area-weighted Gaussians over Euclidean discs of the base (normals of the two
  vertices less than 90° apart, so the far side of a thin part does not leak in):
  ``h = G_{P/8} d − G_{P/2} d`` (fine noise below an eighth of a period and the shape's own
  low-frequency displacement are not texture);
- knobs: vertices whose ``h`` is the largest within ``P/2`` (non-maximum suppression) and above a
  threshold, half the median height of the truth's own maxima; counted per squared period of the
  base's area (:func:`detect_knobs`);
- shape: at fixed area-uniform centres on the base, the area-weighted mean and standard deviation
  of ``h`` in four rings of width ``P/4`` out to one period (rotation invariant,
  :func:`patch_descriptors`); the distance of two fields is the sliced Wasserstein-1 distance of
  their descriptor sets (:func:`sliced_wasserstein`). Euclidean discs stand in for geodesic ones
  (they agree to ``O(r³κ²)`` while the curvature radius exceeds the period).

:func:`knob_scores` scores a mesh against a truth; :func:`texture_noise` is the "right relief, no
structure" baseline matched on these heights. Evidence: ``tests/dgts/test_quality.py``.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import numpy as np
import scipy.sparse
import scipy.spatial

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._random import check_key, host_rng
from .._triangles import triangle_areas
from .._types import Float, Int
from ..geometry import mean_edge_length, vertex_normals

MeshLike = Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]]

#: widths of the band-pass, in periods: fine smoothing and the low-pass taken away
FINE, COARSE = 1.0 / 8.0, 1.0 / 2.0
#: non-maximum suppression radius, in periods
NMS_RADIUS = 0.5
#: rings of the patch descriptor (outer radius one period)
RINGS = 4
#: knob threshold: this fraction of the median height of the truth's own maxima
THRESHOLD_FRACTION = 0.5


class TextureOperators(NamedTuple):
    """The linear maps of one base at one period (:func:`texture_operators`); reuse for every mesh.

    Attributes:
      base: ``[V, 3]`` base vertices.
      faces: ``[F, 3]`` its faces.
      normals: ``[V, 3]`` its vertex normals.
      period: the period in the base's units.
      area: the base's area in squared periods.
      band: ``[V, V]`` sparse band-pass ``G_{P/8} − G_{P/2}``.
      nms: ``[V, V]`` sparse pattern of vertex pairs within ``P/2`` (the suppression discs).
      centres: ``[M]`` vertex indices of the descriptor centres.
      rings: ``[RINGS]`` sparse ``[M, V]`` row-normalised area weights of each ring.
    """

    base: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    period: float
    area: float
    band: scipy.sparse.csr_matrix
    nms: scipy.sparse.csr_matrix
    centres: np.ndarray
    rings: tuple


def _vertex_areas(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    a = triangle_areas(v[f])
    return np.bincount(f.ravel(), weights=np.repeat(a / 3.0, 3), minlength=len(v))


def _row_normalised(rows, cols, w, shape) -> scipy.sparse.csr_matrix:
    m = scipy.sparse.csr_matrix((w, (rows, cols)), shape=shape)
    s = np.asarray(m.sum(axis=1)).ravel()
    return scipy.sparse.diags(1.0 / np.maximum(s, 1e-300)) @ m


def texture_operators(
    base: MeshLike, *, period: float, centres: int = 512, key: jax.Array | None = None
) -> TextureOperators:
    """Band-pass, suppression discs and ring averages of ``base`` at ``period`` (base mean edges).

    Args:
      base: the shared undisplaced mesh (a transfer's ``(base, faces)``).
      period: the texture's period in mean edges of ``base`` (as :func:`oracle_texture` takes it).
      centres: number of descriptor centres (vertices drawn by area, without replacement).
      key: draws the centres; None (default) draws one fixed set, so every mesh on one base is
        described at the same centres.

    Returns:
      :class:`TextureOperators`.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> ops = texture_operators(icosphere(4), period=5.0)
      >>> ops.band.shape, len(ops.centres), round(ops.area, 1)  # ≈ 4π / (5 edges)², in squared periods
      ((2562, 2562), 512, 88.1)
    """
    v, f = as_mesh(base, what="base")
    v = np.asarray(v, np.float64)
    f = np.asarray(f, np.int64)
    if not period > 0:
        raise InputError(f"texture_operators: period must be > 0 mean edges, got {period!r}")
    p = float(period) * float(mean_edge_length(v, f))
    n = vertex_normals(v, f)
    va = _vertex_areas(v, f)
    tree = scipy.spatial.cKDTree(v)
    reach = max(2.0 * COARSE, 1.0) * p
    pairs = tree.query_pairs(reach, output_type="ndarray")
    i = np.concatenate([pairs[:, 0], pairs[:, 1], np.arange(len(v))])
    j = np.concatenate([pairs[:, 1], pairs[:, 0], np.arange(len(v))])
    keep = np.einsum("kd,kd->k", n[i], n[j]) > 0.0
    i, j = i[keep], j[keep]
    d = np.linalg.norm(v[i] - v[j], axis=1) / p
    shape = (len(v), len(v))

    def gauss(sigma: float) -> scipy.sparse.csr_matrix:
        near = d <= 3.0 * sigma
        w = va[j[near]] * np.exp(-0.5 * (d[near] / sigma) ** 2)
        return _row_normalised(i[near], j[near], w, shape)

    band = (gauss(FINE) - gauss(COARSE)).tocsr()
    near = d <= NMS_RADIUS
    nms = scipy.sparse.csr_matrix((np.ones(int(near.sum())), (i[near], j[near])), shape=shape)
    rng = (
        np.random.default_rng(0)
        if key is None
        else host_rng(check_key(key, "texture_operators: key"))
    )
    m = min(int(centres), len(v))
    c = np.sort(rng.choice(len(v), m, replace=False, p=va / va.sum()))
    row_of = np.full(len(v), -1)
    row_of[c] = np.arange(m)
    at = row_of[i] >= 0
    ci, cj, cd = row_of[i[at]], j[at], d[at]
    rings = []
    for k in range(RINGS):
        inside = (cd >= k / RINGS) & (cd < (k + 1) / RINGS)
        rings.append(_row_normalised(ci[inside], cj[inside], va[cj[inside]], (m, len(v))))
    return TextureOperators(v, f, n, p, float(va.sum()) / p**2, band, nms, c, tuple(rings))


def texture_heights(mesh: MeshLike, ops: TextureOperators) -> Float[np.ndarray, " V"]:
    """Band-passed displacement of ``mesh`` along the base's normals, in periods.

    .. math:: h = (G_{P/8} - G_{P/2})\\, \\frac{(v - b)\\cdot n_b}{P}

    Example:
      >>> from jmeshtex.data import icosphere
      >>> ops = texture_operators(icosphere(3), period=4.0)
      >>> float(np.abs(texture_heights(icosphere(3), ops)).max())
      0.0
    """
    v, f = as_mesh(mesh, what="mesh")
    v = np.asarray(v, np.float64)
    if v.shape != ops.base.shape or not np.array_equal(np.asarray(f), ops.faces):
        raise InputError(
            "texture_heights: the mesh must have the base's faces and vertex count (a transfer's "
            "output and its Transfer.base with .faces)"
        )
    d = np.einsum("vd,vd->v", v - ops.base, ops.normals) / ops.period
    return ops.band @ d


def detect_knobs(
    heights: Float[np.ndarray, " V"], ops: TextureOperators, *, threshold: float
) -> Int[np.ndarray, " K"]:
    """Vertices whose height is the largest within ``P/2`` and above ``threshold`` (periods).

    Ties within a disc go to the lowest vertex index.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.dgts.core import oracle_texture
      >>> ops = texture_operators(icosphere(4), period=5.0)
      >>> h = texture_heights(oracle_texture(icosphere(4), "knobs", period=5.0), ops)
      >>> bool(40 < len(detect_knobs(h, ops, threshold=0.02)) < 60)  # about area / period²
      True
    """
    h = np.asarray(heights, np.float64)
    nms = ops.nms.tocoo()
    beaten = (h[nms.col] > h[nms.row]) | ((h[nms.col] == h[nms.row]) & (nms.col < nms.row))
    lost = np.zeros(len(h), bool)
    lost[nms.row[beaten]] = True
    return np.flatnonzero(~lost & (h > float(threshold)))


def patch_descriptors(
    heights: Float[np.ndarray, " V"], ops: TextureOperators
) -> Float[np.ndarray, "M D"]:
    """Per centre, the area-weighted mean and std of the heights in each ring (``D = 2·RINGS``).

    .. math:: \\mu_k(c) = \\sum_{j \\in R_k(c)} w_j h_j,\\quad
       \\sigma_k(c) = \\sqrt{\\sum_{j \\in R_k(c)} w_j h_j^2 - \\mu_k^2}

    with ``R_k(c)`` the base vertices at distance ``[k/4, (k+1)/4)`` periods from ``c`` and ``w``
    their normalised areas: invariant to rotations about ``c``.
    """
    h = np.asarray(heights, np.float64)
    out = []
    for r in ops.rings:
        mu = r @ h
        out += [mu, np.sqrt(np.maximum(r @ (h * h) - mu * mu, 0.0))]
    return np.stack(out, axis=1)


def sliced_wasserstein(
    a: Float[np.ndarray, "M D"], b: Float[np.ndarray, "M D"], *, projections: int = 128
) -> float:
    """Sliced Wasserstein-1 distance of two equal-sized point sets (fixed directions, seed 0).

    .. math:: SW_1(a, b) = \\frac1K \\sum_{k} \\frac1M \\sum_m |(a\\theta_k)_{(m)} - (b\\theta_k)_{(m)}|

    Example:
      >>> x = np.random.default_rng(0).standard_normal((200, 3))
      >>> sliced_wasserstein(x, x), round(sliced_wasserstein(x, x + [1.0, 0, 0]), 2)  # E|θ_x| = 1/2
      (0.0, 0.48)
    """
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    if a.shape != b.shape:
        raise InputError(f"sliced_wasserstein: shapes differ, {a.shape} and {b.shape}")
    theta = np.random.default_rng(0).standard_normal((a.shape[1], int(projections)))
    theta /= np.linalg.norm(theta, axis=0, keepdims=True)
    pa, pb = np.sort(a @ theta, axis=0), np.sort(b @ theta, axis=0)
    return float(np.abs(pa - pb).mean())


class KnobScores(NamedTuple):
    """A mesh's texture against a truth on a shared base (:func:`knob_scores`); lengths in periods.

    Attributes:
      density: knobs per squared period of the base's area (the headline).
      distance: sliced Wasserstein-1 distance of the patch descriptors to the truth's.
      count: number of knobs.
      knob_height: median band-passed height of the knobs (periods; NaN without knobs).
      relief: std of the band-passed heights (periods).
      threshold: the knob threshold used (half the median height of the truth's own maxima).
    """

    density: float
    distance: float
    count: int
    knob_height: float
    relief: float
    threshold: float


def knob_threshold(truth_heights: Float[np.ndarray, " V"], ops: TextureOperators) -> float:
    """Half the median height of the truth's maxima above its mean + one std."""
    h = np.asarray(truth_heights, np.float64)
    peaks = detect_knobs(h, ops, threshold=float(h.mean() + h.std()))
    if len(peaks) == 0:
        raise InputError("knob_threshold: the truth has no maxima above its mean + std")
    return THRESHOLD_FRACTION * float(np.median(h[peaks]))


def knob_scores(
    mesh: MeshLike,
    truth: MeshLike,
    *,
    base: MeshLike | None = None,
    period: float | None = None,
    ops: TextureOperators | None = None,
    threshold: float | None = None,
) -> KnobScores:
    """Score ``mesh`` against ``truth``: both displaced copies of one base, at one period.

    Give either ``ops`` (from :func:`texture_operators`, reused across meshes) or ``base`` and
    ``period`` (mean edges of the base).

    Returns:
      :class:`KnobScores` (``knob_scores(truth, truth, ...)``: the truth's own, distance 0).

    Example:
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.dgts.core import oracle_texture
      >>> ops = texture_operators(icosphere(4), period=5.0)
      >>> truth = oracle_texture(icosphere(4), "knobs", period=5.0)
      >>> own, flat = knob_scores(truth, truth, ops=ops), knob_scores(icosphere(4), truth, ops=ops)
      >>> own.distance, flat.count, bool(0.4 < own.density < 0.9)
      (0.0, 0, True)
    """
    if ops is None:
        if base is None or period is None:
            raise InputError("knob_scores: give ops, or base and period")
        ops = texture_operators(base, period=period)
    ht = texture_heights(truth, ops)
    h = texture_heights(mesh, ops)
    thr = knob_threshold(ht, ops) if threshold is None else float(threshold)
    knobs = detect_knobs(h, ops, threshold=thr)
    return KnobScores(
        density=len(knobs) / ops.area,
        distance=sliced_wasserstein(patch_descriptors(h, ops), patch_descriptors(ht, ops)),
        count=int(len(knobs)),
        knob_height=float(np.median(h[knobs])) if len(knobs) else float("nan"),
        relief=float(h.std()),
        threshold=thr,
    )


def texture_noise(base: MeshLike, ops: TextureOperators, relief: float, *, key) -> Mesh:
    """Gaussian displacement of ``base`` along its normals whose :func:`texture_heights` have std
    ``relief`` (periods): the "right relief, no structure" baseline on this measure's heights.

    Example:
      >>> import jax
      >>> from jmeshtex.data import icosphere
      >>> ops = texture_operators(icosphere(3), period=4.0)
      >>> m = texture_noise(icosphere(3), ops, 0.02, key=jax.random.key(0))
      >>> round(float(texture_heights(m, ops).std()), 4)
      0.02
    """
    v, f = as_mesh(base, what="base")
    g = host_rng(check_key(key, "texture_noise")).standard_normal(len(ops.base))
    scale = float(relief) / max(float((ops.band @ g).std()), 1e-300)  # heights are linear in g
    return Mesh(ops.base + ops.normals * (scale * ops.period * g)[:, None], np.asarray(f))

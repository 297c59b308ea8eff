"""Structure-aware quality measures of a DGTS displacement field (host NumPy/SciPy).

These are diagnostics. The headline is the tessellation-independent measure
:func:`~jmeshtex.dgts.core.knob_scores` (knobs per squared period of the shared base, a patch
distribution distance): the peak density here normalises each mesh by its own mean edge, which
moves with the output's tessellation, and counts raw one-ring maxima. The oracle, the relief
heights and the reconstruction errors live here too.

A geometric texture is more than its distribution of heights: two fields with the same histogram
can have bumps of very different size and spacing. The measures here look at spatial structure of
the normal heights ``h`` (:func:`~jmeshtex.dgts.core.normal_heights`, in mean edges), with every length
also in mean edges of the mesh it is measured on, so a reference and a transfer at different
resolutions or sizes compare directly:

- :func:`height_autocorrelation`: the normalised correlation of heights at distance ``r``,
  and :func:`height_autocorrelation_length`, the first ``r`` where it falls below ``1/e``;
- :func:`peak_statistics`: local maxima of ``h`` above a threshold, their density per unit area
  and the mean distance from each peak to its nearest other peak (the texture's spacing);
- :func:`reconstruction_errors`: how far the reconstruction of every level is from its training
  mesh (mean vertex distance in mean edges);
- ground truth for a transfer: :func:`oracle_texture` puts the reference's procedural texture
  (:func:`jmeshtex.data.textured_mesh`) at the reference's period in mean edges
  (:func:`period_in_mean_edges`) on the transfer's own undisplaced output, and
  :func:`texture_scores` scores a mesh against it on that shared base: peak density (peaks per
  squared mean edge, a diagnostic), relief, W1 of the heights, ACL and spacing;
  :func:`matched_noise` is the "right relief, no structure" baseline.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.spatial

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._random import check_key, host_rng
from .._triangles import triangle_areas
from .._types import Float, Int
from ..data import textured_mesh
from ..geometry import mean_edge_length, unique_edges, vertex_normals
from ._model import Model
from ._multiscale import TrainingMeshes
from ._transfer import normal_heights, reconstruct

MeshLike = Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]]


#: Taubin smoothing pairs of the default heights: enough that bumps a few edges wide stay in the
#: heights instead of in the smoothed copy (measured on textured_sphere knobs: correlation with the
#: true radial heights 0.85 / 0.93 / 0.96 for 10 / 30 / 60 pairs at period 0.3, subdivisions 4)
SMOOTHING = 30


def _heights_and_frame(mesh: MeshLike, heights) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    v, f = as_mesh(mesh, what="mesh")
    v = np.asarray(v, np.float64)
    f = np.asarray(f, np.int64)
    h = (
        normal_heights((v, f), smoothing=SMOOTHING)
        if heights is None
        else np.asarray(heights, np.float64)
    )
    if h.shape != (len(v),):
        raise InputError(f"heights must be [V] = [{len(v)}], got {h.shape}")
    return v, f, h, float(mean_edge_length(v, f))


def height_autocorrelation(
    mesh: MeshLike,
    heights: Float[np.ndarray, " V"] | None = None,
    *,
    max_distance: float = 12.0,
    bin_width: float = 1.0,
    anchors: int = 1500,
) -> tuple[Float[np.ndarray, " B"], Float[np.ndarray, " B"]]:
    """Normalised autocorrelation of the heights against Euclidean distance (in mean edges).

    .. math:: C(r) = \\frac{\\overline{(h_i - \\bar h)(h_j - \\bar h)}_{|v_i - v_j| \\in \\text{bin}(r)}}{\\sigma_h^2}

    over pairs ``(i, j)``, ``i ≠ j``, with ``i`` among ``anchors`` evenly strided vertices (all
    vertices when fewer) and ``j`` any vertex within ``max_distance``. Bins are centred on whole
    multiples of ``bin_width`` (one mean edge: the lattice of a mesh makes finer bins noisy), with
    ``C(0) = 1`` first.

    Args:
      mesh: the displaced mesh (Mesh or pair).
      heights: ``[V]`` heights; default :func:`~jmeshtex.dgts.core.normal_heights` of ``mesh`` with
        ``SMOOTHING`` (30) Taubin pairs.
      max_distance, bin_width: the distance range and bin width, in mean edges.
      anchors: number of anchor vertices.

    Returns:
      ``(r [B], C [B])``: bin centres (mean edges) and correlations (NaN for an empty bin; 0 where
      the heights are constant).

    Example:
      >>> from jmeshtex.data import textured_sphere
      >>> r, c = height_autocorrelation(textured_sphere("knobs", subdivisions=4, period=0.6))
      >>> r[:3].tolist(), float(c[0]), bool(c[1] > 0.5 > abs(c[8]))
      ([0.0, 1.0, 2.0], 1.0, True)
    """
    v, _, h, ell = _heights_and_frame(mesh, heights)
    x = v / ell
    h = h - h.mean()
    var = float(np.mean(h * h))
    w = float(bin_width)
    edges = np.arange(0.5 * w, float(max_distance) + 0.5 * w + 1e-9, w)
    centres = np.concatenate([[0.0], 0.5 * (edges[1:] + edges[:-1])])
    if var <= 0:
        return centres, np.concatenate([[1.0], np.zeros(len(centres) - 1)])
    idx = np.unique(np.linspace(0, len(v) - 1, min(int(anchors), len(v))).astype(np.int64))
    tree = scipy.spatial.cKDTree(x)
    nbrs = tree.query_ball_point(x[idx], r=float(max_distance))
    i = np.repeat(idx, [len(n) for n in nbrs])
    j = np.concatenate([np.asarray(n, np.int64) for n in nbrs])
    d = np.linalg.norm(x[i] - x[j], axis=1)
    b = np.digitize(d, edges) - 1
    nb = len(centres) - 1
    ok = (b >= 0) & (b < nb) & (i != j)
    num = np.bincount(b[ok], weights=h[i[ok]] * h[j[ok]], minlength=nb)
    cnt = np.bincount(b[ok], minlength=nb)
    corr = np.where(cnt > 0, num / np.maximum(cnt, 1) / var, np.nan)
    return centres, np.concatenate([[1.0], corr])


def height_autocorrelation_length(
    mesh: MeshLike,
    heights: Float[np.ndarray, " V"] | None = None,
    *,
    max_distance: float = 12.0,
    bin_width: float = 1.0,
    anchors: int = 1500,
) -> float:
    """The distance (mean edges) where :func:`height_autocorrelation` first falls below ``1/e``.

    Linear interpolation between bins; ``max_distance`` when it never does, 0 for constant heights.
    For a field of isolated bumps of width ``w`` it is of order ``w``; for white noise, under one edge.

    Example:
      >>> from jmeshtex.data import textured_sphere
      >>> small = height_autocorrelation_length(textured_sphere("knobs", subdivisions=4, period=0.3))
      >>> large = height_autocorrelation_length(textured_sphere("knobs", subdivisions=4, period=0.6))
      >>> bool(1.3 * small < large)  # sub-linear: the Taubin high-pass of the heights damps wide bumps
      True
    """
    r, c = height_autocorrelation(
        mesh, heights, max_distance=max_distance, bin_width=bin_width, anchors=anchors
    )
    if not np.any(np.nan_to_num(c[1:])):
        return 0.0
    target = 1.0 / np.e
    prev_r, prev_c = 0.0, 1.0
    for ri, ci in zip(r[1:], c[1:], strict=True):
        if np.isnan(ci):
            continue
        if ci < target:
            return float(prev_r + (prev_c - target) / (prev_c - ci) * (ri - prev_r))
        prev_r, prev_c = float(ri), float(ci)
    return float(max_distance)


class PeakStatistics(NamedTuple):
    """Peaks of a height field (:func:`peak_statistics`); lengths in mean edges of the mesh.

    Attributes:
      count: number of peaks.
      density: peaks per unit area (area in squared mean edges).
      spacing: mean distance from each peak to its nearest other peak (``inf`` with < 2 peaks).
      threshold: the height threshold used (mean edges).
      peaks: ``[count]`` vertex indices of the peaks.
    """

    count: int
    density: float
    spacing: float
    threshold: float
    peaks: np.ndarray


def peak_statistics(
    mesh: MeshLike,
    heights: Float[np.ndarray, " V"] | None = None,
    *,
    threshold: float | None = None,
) -> PeakStatistics:
    """Local maxima of the heights above ``threshold``: their count, density and spacing.

    A vertex is a peak when its height exceeds every one-ring neighbour's and ``threshold``.

    .. math:: \\rho = \\frac{N_{\\text{peaks}}}{A / \\bar\\ell^2},\\qquad
       s = \\overline{\\min_{q \\ne p} |p - q|} / \\bar\\ell

    Args:
      mesh: the displaced mesh (Mesh or pair).
      heights: ``[V]`` heights in mean edges; default :func:`~jmeshtex.dgts.core.normal_heights` with
        ``SMOOTHING`` (30) Taubin pairs.
      threshold: minimum peak height (mean edges); default ``mean + std`` of ``heights``. Compare
        meshes with one threshold (e.g. the reference's): heights are in mean edges everywhere.

    Returns:
      :class:`PeakStatistics`.

    Example:
      >>> from jmeshtex.data import textured_sphere, texture_centers
      >>> m = textured_sphere("knobs", subdivisions=4, period=0.5)
      >>> s = peak_statistics(m)
      >>> s.count == len(texture_centers("sphere", period=0.5)), bool(5 < s.spacing < 9)  # 0.5 / 0.077 edges
      (True, True)
    """
    v, f, h, ell = _heights_and_frame(mesh, heights)
    thr = float(h.mean() + h.std()) if threshold is None else float(threshold)
    e = unique_edges(f, len(v))
    is_max = h > thr
    # a vertex is a peak when no neighbour is as high: drop the lower end of every edge (ties: both)
    lo = np.where(h[e[:, 0]] <= h[e[:, 1]], e[:, 0], e[:, 1])
    hi = np.where(h[e[:, 0]] <= h[e[:, 1]], e[:, 1], e[:, 0])
    is_max[lo] = False
    is_max[hi[h[e[:, 0]] == h[e[:, 1]]]] = False
    peaks = np.flatnonzero(is_max)
    area = float(triangle_areas(v[f]).sum()) / ell**2
    spacing = np.inf
    if len(peaks) >= 2:
        d, _ = scipy.spatial.cKDTree(v[peaks] / ell).query(v[peaks] / ell, k=2)
        spacing = float(d[:, 1].mean())
    return PeakStatistics(int(len(peaks)), len(peaks) / area, spacing, thr, peaks)


def reconstruction_errors(model: Model, meshes: TrainingMeshes) -> Float[np.ndarray, " L"]:
    """Per level, the mean distance between the reconstruction and the training mesh, in mean edges.

    .. math:: e_l = \\frac{1}{V_l \\bar\\ell_l} \\sum_i \\big| \\hat v^{(l)}_i - v^{(l)}_i \\big|

    with ``v̂^{(l)}`` the output of level ``l`` for the reconstruction noise
    (:func:`~jmeshtex.dgts.reconstruct`, :meth:`~jmeshtex.dgts.Model.reconstruction_noise`; training
    uses fresh noise for level 0's own reconstruction while ``Config.reconstruction_start`` = 1) and
    ``ℓ̄_l`` the training mesh's mean edge.

    Args:
      model: a trained model (its levels are compared).
      meshes: the training meshes it was trained on.

    Returns:
      ``[model.num_levels]`` float64 errors.

    Example:
      >>> import jax
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.dgts import Config, PrepareConfig, train, training_meshes
      >>> tm = training_meshes(icosahedron(), icosahedron(), config=PrepareConfig(levels=2, steps=0),
      ...                      key=jax.random.key(0))
      >>> cfg = Config(num_layers=3, start_features=4, min_features=4, max_features=4, steps=2, shared_levels=2)
      >>> reconstruction_errors(train(tm, cfg, key=jax.random.key(3), progress=False).model, tm).shape
      (2,)
    """
    if model.num_levels > meshes.num_levels:
        raise InputError(
            f"the model has {model.num_levels} levels, the training meshes {meshes.num_levels}"
        )
    rec = reconstruct(model, Mesh(np.asarray(meshes.template, np.float64), meshes.faces[0]))
    out = []
    for level in range(model.num_levels):
        real = np.asarray(meshes.vertices[level], np.float64)
        # the template's coordinates are the level-0 frame; level l's is that times scale_factor**l
        got = rec.level_vertices[level][0] * model.config.scale_factor**level
        ell = mean_edge_length(real, meshes.faces[level])
        out.append(float(np.linalg.norm(got - real, axis=1).mean() / ell))
    return np.asarray(out)


def relief_heights(mesh: MeshLike, base: MeshLike | None = None) -> Float[np.ndarray, " V"]:
    """Normal heights of ``mesh`` (mean edges, ``SMOOTHING`` Taubin pairs) less those of ``base``.

    .. math:: h = h_{\\text{Taubin}}(\\text{mesh}) - h_{\\text{Taubin}}(\\text{base})

    A transfer's base is the target subdivided without displacement; its own heights (the facets of
    midpoint subdivision, the curvature of the surface) are there with or without texture, so they
    are removed. ``base=None``: the plain heights (a mesh without a base, e.g. a training mesh).

    Args:
      mesh: the displaced mesh.
      base: the same connectivity without displacement, or None.

    Returns:
      ``[V]`` float64 heights in mean edges of ``mesh``.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> float(np.abs(relief_heights(icosphere(3), icosphere(3))).max())
      0.0
    """
    v, f = as_mesh(mesh, what="mesh")
    h = normal_heights((v, f), smoothing=SMOOTHING)
    if base is None:
        return h
    vb, fb = as_mesh(base, what="base")
    if np.shape(vb) != np.shape(v) or not np.array_equal(np.asarray(fb), np.asarray(f)):
        raise InputError(
            "relief_heights: base must have the mesh's faces and vertex count (the transfer's "
            "undisplaced output, Transfer.base with .faces)"
        )
    return h - normal_heights((vb, fb), smoothing=SMOOTHING)


def period_in_mean_edges(meshes: TrainingMeshes, period: float, *, level: int = -1) -> float:
    """A length of the reference (its own units) in mean edges of training level ``level``.

    .. math:: p_\\ell = p\\, s_l / \\bar\\ell_l

    with ``s_l`` the input-to-level scale (``meshes.scales``) and ``ℓ̄_l`` the level's mean edge.

    Example:
      >>> import jax
      >>> from jmeshtex.data import icosahedron, icosphere
      >>> from jmeshtex.dgts import PrepareConfig, training_meshes
      >>> tm = training_meshes(icosphere(2), icosahedron(), config=PrepareConfig(levels=2, steps=0),
      ...                      key=jax.random.key(0), progress=False)
      >>> round(period_in_mean_edges(tm, 1.0), 2), round(float(tm.scales[-1]), 2)  # edges of 1 there
      (1.62, 1.62)
    """
    lv = int(level) % meshes.num_levels
    ell = mean_edge_length(np.asarray(meshes.vertices[lv], np.float64), meshes.faces[lv])
    return float(period) * float(meshes.scales[lv]) / float(ell)


def oracle_texture(
    base: MeshLike,
    kind: str,
    *,
    period: float,
    amplitude: float | None = None,
    key=None,
) -> Mesh:
    """The ground truth of a transfer: ``base`` carrying the texture ``kind`` at ``period`` mean edges.

    :func:`jmeshtex.data.textured_mesh` with the period (and amplitude) given in mean edges of
    ``base``: the reference's texture at the reference's scale, on the transfer's own surface and
    tessellation (``Transfer.base`` and ``.faces``).

    Args:
      base: the undisplaced output of the transfer.
      kind: the reference's texture (``jmeshtex.data.GEOMETRIC_TEXTURES``).
      period: the reference's period in its mean edges (:func:`period_in_mean_edges`).
      amplitude: relief height in mean edges; default the kind's fraction of the period.
      key: a ``jax.random`` key placing the texture centres; None: the canonical placement (the
        one :func:`jmeshtex.data.textured_mesh` makes by default).

    Returns:
      The textured :class:`~jmeshtex.Mesh` (``base``'s faces).

    Example:
      >>> from jmeshtex.data import icosphere
      >>> truth = oracle_texture(icosphere(4), "knobs", period=5.0)
      >>> s = peak_statistics(truth, relief_heights(truth, icosphere(4)))
      >>> bool(0.02 < s.density < 0.035)  # about one knob per (5 edges)^2
      True
    """
    v, f = as_mesh(base, what="base")
    ell = float(mean_edge_length(np.asarray(v, np.float64), np.asarray(f, np.int64)))
    if not period > 0:
        raise InputError(f"oracle_texture: period must be > 0 mean edges, got {period!r}")
    return textured_mesh(
        Mesh(np.asarray(v, np.float64), np.asarray(f, np.int64)),
        kind,
        period=float(period) * ell,
        amplitude=None if amplitude is None else float(amplitude) * ell,
        seed=0 if key is None else int(host_rng(check_key(key, "oracle_texture")).integers(2**31)),
    )


def matched_noise(base: MeshLike, relief: float, *, key) -> Mesh:
    """Gaussian displacement of ``base`` along its normals whose relief heights have std ``relief``.

    The "right relief, no structure" baseline: the displacement's scale is set so that
    ``relief_heights(noise, base).std() == relief`` (one linear rescale: the heights are linear in
    a normal displacement). The Gaussian draw follows ``key`` (a ``jax.random`` key).

    Example:
      >>> import jax
      >>> from jmeshtex.data import icosphere
      >>> m = matched_noise(icosphere(3), 0.2, key=jax.random.key(0))
      >>> round(float(relief_heights(m, icosphere(3)).std()), 3)
      0.2
    """
    v, f = as_mesh(base, what="base")
    v = np.asarray(v, np.float64)
    f = np.asarray(f, np.int64)
    n = vertex_normals(v, f)
    g = host_rng(check_key(key, "matched_noise")).standard_normal(len(v))
    trial = Mesh(v + n * (g * mean_edge_length(v, f))[:, None], f)
    scale = float(relief) / max(float(relief_heights(trial, (v, f)).std()), 1e-12)
    for _ in range(3):  # normal_heights is nearly linear in a small displacement: a few rescales
        trial = Mesh(v + n * (scale * g * mean_edge_length(v, f))[:, None], f)
        scale *= float(relief) / max(float(relief_heights(trial, (v, f)).std()), 1e-12)
    return Mesh(v + n * (scale * g * mean_edge_length(v, f))[:, None], f)


class TextureScores(NamedTuple):
    """A mesh's texture against a ground truth (:func:`texture_scores`); lengths in mean edges.

    Attributes:
      peak_density: peaks per squared mean edge (a diagnostic; the headline is
        :func:`~jmeshtex.dgts.core.knob_scores`).
      relief: std of the relief heights.
      w1: Wasserstein-1 distance between the mesh's and the truth's relief heights.
      autocorrelation_length: :func:`height_autocorrelation_length` of the relief heights.
      spacing: mean nearest-peak distance.
      peaks: number of peaks.
      threshold: the peak threshold used (the truth's ``mean + std``).
    """

    peak_density: float
    relief: float
    w1: float
    autocorrelation_length: float
    spacing: float
    peaks: int
    threshold: float


def texture_scores(
    mesh: MeshLike,
    truth: MeshLike,
    *,
    base: MeshLike | None = None,
    threshold: float | None = None,
) -> TextureScores:
    """Score ``mesh``'s texture against ``truth`` (an oracle on the same base, or the training mesh).

    Heights are :func:`relief_heights` relative to ``base`` (both meshes share it: a transfer's
    output and its :func:`oracle_texture`), or plain normal heights with ``base=None`` (in-domain
    samples against the training mesh). Peaks use one threshold for both, the truth's.

    Args:
      mesh: the mesh to score.
      truth: the ground truth.
      base: the shared undisplaced mesh, or None.
      threshold: peak threshold in mean edges; default the truth's ``mean + std``.

    Returns:
      :class:`TextureScores` of ``mesh`` (``texture_scores(truth, truth, base=base)`` gives the
      truth's own, with ``w1 = 0``).

    Example:
      >>> from jmeshtex.data import icosphere
      >>> truth = oracle_texture(icosphere(4), "knobs", period=5.0)
      >>> flat = texture_scores(icosphere(4), truth, base=icosphere(4))
      >>> own = texture_scores(truth, truth, base=icosphere(4))
      >>> flat.peaks, own.w1, bool(own.peak_density > 0.02)
      (0, 0.0, True)
    """
    from scipy.stats import wasserstein_distance

    h_truth = relief_heights(truth, base)
    h = relief_heights(mesh, base)
    thr = float(h_truth.mean() + h_truth.std()) if threshold is None else float(threshold)
    peaks = peak_statistics(mesh, h, threshold=thr)
    return TextureScores(
        peak_density=float(peaks.density),
        relief=float(h.std()),
        w1=float(wasserstein_distance(h, h_truth)),
        autocorrelation_length=float(height_autocorrelation_length(mesh, h)),
        spacing=float(peaks.spacing),
        peaks=int(peaks.count),
        threshold=thr,
    )


def density_error(scores: TextureScores, truth: TextureScores) -> float:
    """How far a peak density is from the truth's, as a factor: ``|log(ρ / ρ*)|`` (``inf`` at 0).

    Example:
      >>> t = TextureScores(0.03, 0.1, 0.0, 2.0, 5.0, 30, 0.1)
      >>> round(density_error(t._replace(peak_density=0.06), t), 3), density_error(t, t)
      (0.693, 0.0)
    """
    if scores.peak_density <= 0 or truth.peak_density <= 0:
        return float("inf")
    return float(abs(np.log(scores.peak_density / truth.peak_density)))

"""Coarse-to-fine PatchMatch between two meshes (MeshMatch, Chen et al. 2012 §4): the driver.

:func:`meshmatch` prepares both meshes (:func:`~jmeshtex.meshmatch.core.prepare_side`), then runs the
levels from the coarsest to the finest: the coarsest starts from random matches, every finer level
from its parents' matches (upsampled through the parent maps: copied, or with
``Config(upsample="offset")`` moved by each vertex's geodesic offset from its parent and re-voted);
each level runs up to ``steps``
PatchMatch iterations (the jitted E-step + M-step of ``jmeshtex/meshmatch/_search.py``) and stops
early when few matches change. A final pass copies each target vertex's matched source colour (no
blur). Levels are padded in groups (:func:`~jmeshtex.meshmatch.core.level_groups`: every level with at
most ``bucket_vertices`` target vertices, then pairs of larger levels) to one shape each, so a
group shares one compiled step.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._types import Float, Int
from ..geometry import check_mesh_scale, vertex_normals
from ._config import MAX_FAN_RADIUS, Config
from ._features import ancestors
from ._prepare import (
    LevelArrays,
    Side,
    bucket_dims,
    level_arrays,
    level_groups,
    level_pairing,
    pad_axis,
    pad_level_arrays,
    pool_colors,
    prepare_side,
    scan_order,
    search_tables,
    side_affinities,
)
from ._search import SearchOptions, Source, StepWeights, iterate, make_source, vote_step


class Match(NamedTuple):
    """Output of :func:`meshmatch`: the nearest-neighbour field and the signal it carries.

    Attributes:
      colors: ``[Vt, C]`` final target colours: each vertex copies its matched source colour.
      voted: ``[Vt, C]`` the last Gaussian-weighted vote at the finest level (smoother).
      nnf: ``[Vt]`` matched source vertex (input indexing).
      rotation: ``[Vt]`` rotation step k: target frame → source frame by ``2πk/A``.
      cost: ``[Vt]`` patch distance of the match.
      stats: ``"levels"``: per level (coarsest first) ``level``, ``source_level``, ``vertices``,
        ``padded_vertices``, ``padded_source_vertices``, ``steps`` (iterations run), ``changed``
        (matches changed by the last one), ``mean_cost``, ``seconds``, ``iteration_seconds`` and
        ``iteration_cpu_seconds`` (wall and process CPU time of each iteration; the first of a
        group of levels includes compiling the step); ``prepare_s`` (when not given ``prepared``),
        ``fans_s`` (fan tracing and upload), ``total_s``.
    """

    colors: np.ndarray
    voted: np.ndarray
    nnf: np.ndarray
    rotation: np.ndarray
    cost: np.ndarray
    stats: dict


def nnf_colors(source: Mesh | tuple, nnf: Int[np.ndarray, " Vt"]) -> Float[np.ndarray, "Vt 3"]:
    """Colour-code a nearest-neighbour field: each target vertex shows its match's source position.

    .. math:: c_t = \\frac{x_{\\text{NNF}(t)} - x_{\\min}}{x_{\\max} - x_{\\min}}

    (per axis, over the source's bounding box), so a correct transfer between similar shapes shows
    a smooth rainbow and misplaced patches stand out.

    Args:
      source: the source :class:`~jmeshtex.Mesh` or ``(vertices [Vs, 3], faces)``.
      nnf: ``[Vt]`` matched source vertex per target vertex (:attr:`~jmeshtex.meshmatch.Match.nnf`).

    Returns:
      ``[Vt, 3]`` float64 colours in ``[0, 1]``.

    Example:
      >>> nnf_colors((np.array([[0.0, 0, 0], [1, 2, 3], [0, 2, 0]]), np.array([[0, 1, 2]])),
      ...            np.array([1, 0])).tolist()
      [[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]]
    """
    v = np.asarray(as_mesh(source, what="source").vertices, np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    return ((v - lo) / np.where(hi > lo, hi - lo, 1.0))[np.asarray(nnf)]


def meshmatch(
    source: Mesh | tuple,
    source_colors: Float[np.ndarray, "Vs C"],
    target: Mesh | tuple,
    *,
    key: jax.Array,
    config: Config | None = None,
    correspondences: Int[np.ndarray, "m 2"] | None = None,
    source_mask: np.ndarray | None = None,
    pin: Int[np.ndarray, " Vt"] | None = None,
    progress: bool | Callable[[str], Any] = False,
    prepared: tuple[Side, Side] | None = None,
    initial_nnf: Int[np.ndarray, " Vt"] | None = None,
) -> Match:
    """Transfer per-vertex signals from a source mesh to a target mesh by PatchMatch (MeshMatch).

    .. math:: \\text{NNF}(t) = \\arg\\min_{s, k} D_k(t, s), \\qquad
              c_t = \\frac{\\sum_{q \\in \\{t\\} \\cup N(t)} g_{tq}\\, c^{src}\\bigl(\\exp_{s_q}(e^{i\\theta_q}
              \\log_q t)\\bigr)}{\\sum_q g_{tq}}

    (Chen et al. 2012, §4: E-step / M-step; ``D`` is the patch distance of
    ``jmeshtex/meshmatch/_search.py``: fan distance at the best of ``A`` rotations plus the shape
    term.)

    Args:
      source: the exemplar :class:`~jmeshtex.Mesh` (or ``(vertices [Vs, 3], faces [Fs, 3])``).
      source_colors: ``[Vs, C]`` per-vertex signal on the source (colours, displacements, ...).
      target: the mesh to synthesise on (same units as the source: the texture keeps its
        world-space scale).
      key: a ``jax.random`` key for the random initialisation and search.
      config: :class:`~jmeshtex.meshmatch.Config` (default settings when None).
      correspondences: ``[m, 2]`` (source vertex, target vertex) pairs; adds geodesic affinities.
      source_mask: ``[Vs]`` bool, the source vertices a match may use (default all).
      pin: ``[Vt]`` source vertex each target vertex must match (−1: free) — for painting by
        example, where source and target are the same mesh.
      progress: True for a tqdm bar per level, or a callable receiving one line per level.
      prepared: ``(source_side, target_side)`` from :func:`~jmeshtex.meshmatch.core.prepare_side` to
        reuse preprocessing.
      initial_nnf: ``[Vt]`` source vertex per target vertex to start the coarsest level from
        (moved to the levels' ancestors), with the source colours there, instead of random
        matches: a warm start from an earlier field, or the truth when measuring how far the
        iterations move it (the seeded rows of ``docs/results.md``, MeshMatch).

    Returns:
      :class:`Match`.

    Raises:
      InputError: shapes of colours, masks, pins; an empty source mask; a mesh that is neither a
        ``Mesh`` nor a pair; source and target sizes differing by more than
        ``config.max_scale_ratio``; fans that would cross more than ``MAX_FAN_RADIUS`` mean edges
        of the finer mesh or span more than 8 bounding-box diagonals of
        the smaller mesh (a unit mismatch with ``max_scale_ratio=None``); an ``initial_nnf`` of
        the wrong shape or range.
      MeshScaleError: a mesh with a mean edge outside ``[1e-6, 1e8]`` or too far from the origin
        for float32 geometry (:func:`~jmeshtex.geometry.check_mesh_scale`).
      MeshError: (another subclass) a mesh that is not a triangle mesh.

    Example:
      >>> import jax
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import icosphere
      >>> v, f = icosphere(2)
      >>> v = v * (1 + 0.25 * np.sin(3 * v[:, :1] + 1) * np.cos(2 * v[:, 1:2]))   # no symmetry left
      >>> colors = 0.5 + 0.4 * np.sin(5 * v[:, :3])
      >>> r = meshmatch(Mesh(v, f), colors, Mesh(v, f), key=jax.random.key(0),
      ...               config=Config(levels=1, coarse_steps=25))
      >>> r.colors.shape, bool(np.abs(r.colors - colors).mean() < 0.05)      # self-transfer
      ((162, 3), True)
    """
    config = Config() if config is None else config
    if not isinstance(config, Config):
        raise InputError(
            f"config must be a jmeshtex.meshmatch.Config (Config.from_dict(d) reads a dict), "
            f"got {type(config).__name__}"
        )
    source, target = as_mesh(source, what="source"), as_mesh(target, what="target")
    t_start = time.perf_counter()
    # no UV unwrapper here: only float32's range bounds the edge length from below
    edges = (
        check_mesh_scale(source, what="source", min_edge=_MIN_EDGE),
        check_mesh_scale(target, what="target", min_edge=_MIN_EDGE),
    )
    colors, valid, pins = _checked_signals(source, target, source_colors, source_mask, pin)
    _check_scales(source, target, config.max_scale_ratio)
    _check_fan_extent(source, target, edges, config.fan_radius)
    initial_nnf = _checked_initial(source, target, initial_nnf)
    timings: dict[str, float] = {}
    if prepared is None:
        t0 = time.perf_counter()
        s_side, t_side = _prepare_sides(source, target, config)
        timings["prepare_s"] = time.perf_counter() - t0
    else:
        s_side, t_side = prepared
    result = match_levels(
        s_side,
        t_side,
        colors,
        config,
        key=key,
        features=_side_features(s_side, t_side, correspondences, config),
        source_mask=valid,
        pin=pins,
        progress=progress,
        initial=initial_nnf,
    )
    stats = {
        "levels": result.stats["levels"],
        **timings,
        "fans_s": result.stats["fans_s"],
        "total_s": time.perf_counter() - t_start,
    }
    return result._replace(stats=stats)


def _checked_initial(source: Mesh, target: Mesh, initial_nnf) -> np.ndarray | None:
    """``initial_nnf`` as an array, checked: ``[Vt]`` integer source vertices (or None)."""
    if initial_nnf is None:
        return None
    initial_nnf = np.asarray(initial_nnf)
    if (
        initial_nnf.shape != (target.num_vertices,)
        or not np.issubdtype(initial_nnf.dtype, np.integer)
        or initial_nnf.min(initial=0) < 0
        or initial_nnf.max(initial=0) >= source.num_vertices
    ):
        raise InputError(
            f"initial_nnf must be [Vt={target.num_vertices}] source vertices in "
            f"[0, {source.num_vertices}), got {initial_nnf.dtype} {initial_nnf.shape}"
        )
    return initial_nnf


def _prepare_sides(source: Mesh, target: Mesh, config: Config) -> tuple[Side, Side]:
    """Both meshes prepared; one side serves both when they are the same mesh, and the target's
    heat-kernel signature uses the source's times."""
    s_side = prepare_side(source, config)
    same = (
        source.vertices.shape == target.vertices.shape
        and source.faces.shape == target.faces.shape
        and np.array_equal(source.vertices, target.vertices)
        and np.array_equal(source.faces, target.faces)
    )
    return s_side, s_side if same else prepare_side(target, config, hks_times=s_side.hks_times)


def _side_features(
    s_side: Side, t_side: Side, correspondences, config: Config
) -> tuple[np.ndarray, np.ndarray]:
    """``([Vs, D], [Vt, D])`` the shape features of both sides, with the geodesic affinities to
    the ``correspondences`` appended (weighted by ``sqrt(config.affinity_weight)``) when given."""
    s_feat, t_feat = s_side.features, t_side.features
    if correspondences is not None:
        a_s, a_t = side_affinities(s_side, t_side, correspondences)
        w = math.sqrt(config.affinity_weight)
        s_feat = np.concatenate([s_feat, w * a_s], axis=1)
        t_feat = np.concatenate([t_feat, w * a_t], axis=1)
    return s_feat, t_feat


def _check_scales(source: Mesh, target: Mesh, max_ratio: float | None) -> None:
    """Raise when the bounding-box diagonals differ by more than ``max_ratio`` (None: no check)."""
    if max_ratio is None:
        return

    def size(mesh):
        v = np.asarray(mesh.vertices, np.float64)
        return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))

    s, t = size(source), size(target)
    ratio = max(s, t) / max(min(s, t), 1e-300)
    if ratio > max_ratio:
        raise InputError(
            f"source and target sizes differ by {ratio:.3g}x (bounding-box diagonals {s:.4g} and {t:.4g}): "
            "MeshMatch pairs levels and fans in world units, so both meshes must share units; rescale one "
            "(e.g. to the other's size) or set Config(max_scale_ratio=None) to transfer at this scale on purpose"
        )


#: the smallest mean edge length accepted (float32 squares of lengths stay normal far below it)
_MIN_EDGE = 1e-6
#: the largest outer fan radius, in bounding-box diagonals of the smaller mesh, that a match traces
_MAX_FAN_WRAP = 8.0


def _check_fan_extent(source: Mesh, target: Mesh, edges: tuple[float, float], fan_radius) -> None:
    """Raise when the finest level's fans (``fan_radius`` times the coarser mesh's mean edge) would
    cross more than ``MAX_FAN_RADIUS`` mean edges of the finer mesh (the traces' length, and so the
    compiled program's size, grows with it: a 60x edge ratio compiled for minutes to an allocation
    failure), or wrap around the smaller mesh more than ``_MAX_FAN_WRAP`` times (a ×1e6 scale
    mismatch with ``max_scale_ratio=None``)."""
    radius = float(fan_radius) * max(edges)
    diagonals = [
        float(np.linalg.norm(np.ptp(np.asarray(m.vertices, np.float64), axis=0)))
        for m in (source, target)
    ]
    smaller = min(diagonals)
    if radius > MAX_FAN_RADIUS * min(edges):  # each trace walks about radius / edge faces
        raise InputError(
            f"fans of radius {radius:.3g} (fan_radius {fan_radius:g} x the coarser mesh's mean edge "
            f"{max(edges):.3g}) would cross {radius / min(edges):.3g} mean edges of the finer mesh "
            f"(at most {MAX_FAN_RADIUS:g}; mean edges differ {max(edges) / min(edges):.3g}x): "
            "remesh the finer mesh coarser or the coarser finer, rescale one mesh to the other's "
            "units, or lower Config.fan_radius"
        )
    if radius > _MAX_FAN_WRAP * smaller:
        ratio = max(edges) / min(edges)
        raise InputError(
            f"fans of radius {radius:.3g} (fan_radius {fan_radius:g} x the coarser mesh's mean edge "
            f"{max(edges):.3g}) would span {radius / smaller:.3g} bounding-box diagonals of the "
            f"smaller mesh ({smaller:.3g}; mean edges differ {ratio:.3g}x): rescale one mesh to "
            "the other's units, or lower Config.fan_radius"
        )


def _checked_signals(source: Mesh, target: Mesh, source_colors, source_mask, pin):
    """The source signal ``[Vs, C]``, the source mask ``[Vs]`` and the pins ``[Vt]`` (or None), checked."""
    Vs, Vt = source.num_vertices, target.num_vertices
    colors = np.asarray(source_colors, np.float64)
    if colors.ndim == 1:
        colors = colors[:, None]
    if colors.ndim != 2 or len(colors) != Vs or not np.all(np.isfinite(colors)):
        raise InputError(f"source_colors must be finite [Vs={Vs}, C], got shape {colors.shape}")
    valid = np.ones(Vs, bool) if source_mask is None else np.asarray(source_mask, bool)
    if valid.shape != (Vs,):
        raise InputError(f"source_mask must have shape [Vs={Vs}], got {valid.shape}")
    if not valid.any():
        raise InputError("source_mask selects no source vertex: paint (mask) at least one region")
    pins = None if pin is None else np.asarray(pin, np.int64)
    if pins is not None and (
        pins.shape != (Vt,) or pins.max(initial=-1) >= Vs or pins.min(initial=0) < -1
    ):
        raise InputError(f"pin must be [Vt={Vt}] source vertices or -1, got shape {pins.shape}")
    return colors, valid, pins


class _Level(NamedTuple):
    """Everything one level's iterations read (device arrays) and its sizes."""

    tgt: LevelArrays
    src: Source
    pin: jax.Array
    weights: StepWeights
    options: SearchOptions
    num_target: int
    num_padded: int
    num_padded_source: int
    valid_index: np.ndarray
    num_valid: int
    source_level: int
    order: jax.Array | None = None


def _group_dims(source: Side, target: Side, pairing, config: Config) -> dict:
    """Per target level in a group of more than one level, the group's common padded sizes."""
    dims_of = {}
    if config.experimental.bucket_vertices > 0:
        sizes = [len(x) for x in target.hierarchy.vertices]
        for group in level_groups(sizes, config.experimental.bucket_vertices):
            if len(group) > 1:
                dims = bucket_dims(
                    source, target, pairing, group, config.experimental.random_search_levels
                )
                if config.propagation == "sequential":  # the wavefront tables share one shape too
                    shapes = [_wavefronts(target, lv).shape for lv in group]
                    dims["order"] = (max(a for a, _ in shapes), max(b for _, b in shapes))
                dims_of.update({lv: dims for lv in group})
    return dims_of


def _wavefronts(target: Side, level: int, pad_to=None, fill=None) -> np.ndarray:
    """:func:`~jmeshtex.meshmatch.core.scan_order` of a target level (sequential propagation)."""
    nb = target.neighborhoods[level]
    return scan_order(np.asarray(nb.index), np.asarray(nb.mask), pad_to=pad_to, fill=fill)


def _pad_to_dims(s_arr, t_arr, up, down, valid_index, dims: dict):
    """Both sides' level arrays and the source's search tables padded to a group's common sizes
    ``dims`` (:func:`~jmeshtex.meshmatch.core.bucket_dims`)."""
    s_arr = pad_level_arrays(
        s_arr, num_vertices=dims["Vs"], ring=dims["Ks"], smooth_ring=dims["Kss"]
    )
    t_arr = pad_level_arrays(
        t_arr, num_vertices=dims["Vt"], ring=dims["Kt"], smooth_ring=dims["Kst"]
    )
    up = [pad_axis(u, 0, dims["Vs"]) for u in up]
    down = [
        (pad_axis(pad_axis(c, 0, n), 1, k), pad_axis(cnt, 0, n, 1))
        for (c, cnt), (n, k) in zip(down, dims["down"], strict=True)
    ]
    valid_index = pad_axis(valid_index, 0, dims["Vs"], valid_index[0])
    return s_arr, t_arr, up, down, valid_index


def _step_weights(
    source: Side, target: Side, level: int, m: int, variance: float, config: Config, C: int, dtype
) -> StepWeights:
    """The weights of one level's E- and M-steps (``variance``: of the valid source colours)."""
    R, A = config.num_radii, config.num_angles
    fan_weight = None
    if config.vote == "fan":  # the fan vote's ring weights: a Gaussian of the ring radius
        radius = np.arange(1, R + 1) * config.fan_radius / R  # in the fans' edge lengths
        fan_weight = jnp.asarray(np.exp(-(radius**2) / (2 * config.vote_sigma**2)), dtype)
    return StepWeights(
        ring_weight=jnp.ones(R, dtype) / R,
        color_scale=jnp.asarray(config.color_weight / (R * A * C * variance), dtype),
        shape_weight=jnp.asarray(config.shape_weight_at(level), dtype),
        sigma2=jnp.asarray((config.vote_sigma * target.edge[level]) ** 2, dtype),
        tau2=jnp.asarray((config.experimental.interp_sigma * source.edge[m]) ** 2, dtype),
        fan_weight=fan_weight,
    )


def _level_pin(source: Side, target: Side, level: int, m: int, pin) -> np.ndarray:
    """``[Vt]`` int32 the source vertex (level ``m`` indexing) each target vertex of ``level`` is
    pinned to, -1 where free."""
    Vt = len(target.hierarchy.vertices[level])
    if pin is None:
        return np.full(Vt, -1, np.int32)
    p = pin[target.hierarchy.vertex_index[level]]
    mapped = np.where(p >= 0, source.inverse[m][np.maximum(p, 0)], -1)
    return np.where(mapped >= 0, mapped, -1).astype(np.int32)


def _level_inputs(
    source: Side,
    target: Side,
    level: int,
    m: int,
    colors,
    features,
    source_mask,
    pin,
    config: Config,
    dtype,
    dims,
) -> tuple[_Level, float]:
    """Trace both sides' fans at target level ``level`` / source level ``m``, pad them to ``dims``
    (None: no padding), build the device-side source; also returns the seconds spent on the fans."""
    t0 = time.perf_counter()
    s_feat, t_feat = features
    sh = source.hierarchy
    # fans never smaller than the paired source level's edges: a target level finer than the
    # source's finest would otherwise sample within a source triangle or two (64K torus
    # self-transfer from 10K: 26.7 -> 28.0 dB)
    radii = config.radii(max(target.edge[level], source.edge[m]))
    valid_m = source_mask[sh.vertex_index[m]]
    if not valid_m.any():  # a tiny painted region may vanish at a coarse level
        valid_m = np.ones_like(valid_m)
    s_arr, s_steps = level_arrays(source, m, radii, config, colors, valid_m, s_feat, dtype)
    Vt = len(target.hierarchy.vertices[level])
    t_arr, t_steps = level_arrays(
        target,
        level,
        radii,
        config,
        np.zeros((Vt, colors.shape[1])),
        np.ones(Vt, bool),
        t_feat,
        dtype,
    )
    up, down = search_tables(sh, m, config.experimental.random_search_levels)
    valid_index = np.nonzero(valid_m)[0].astype(np.int32)
    num_valid = len(valid_index)
    if dims is not None:
        s_arr, t_arr, up, down, valid_index = _pad_to_dims(
            s_arr, t_arr, up, down, valid_index, dims
        )
    Vp = t_arr.nb_index.shape[0]
    order = None
    if config.propagation == "sequential":
        order = jnp.asarray(
            _wavefronts(target, level, None if dims is None else dims["order"], fill=Vp)
        )
    t_arr = jax.tree.map(jnp.asarray, t_arr)
    fan_seconds = time.perf_counter() - t0

    variance = float(np.var(colors[valid_m])) + 1e-8
    weights = _step_weights(source, target, level, m, variance, config, colors.shape[1], dtype)
    src = make_source(
        s_arr,
        up,
        down,
        valid_index,
        num_valid,
        weights.ring_weight,
        steps=s_steps,
        num_angles=config.num_angles,
    )
    level_in = _Level(
        tgt=t_arr,
        src=src,
        pin=jnp.asarray(pad_axis(_level_pin(source, target, level, m, pin), 0, Vp, -1)),
        weights=weights,
        options=SearchOptions.of(config, t_steps),
        num_target=Vt,
        num_padded=Vp,
        num_padded_source=s_arr.nb_index.shape[0],
        valid_index=valid_index,
        num_valid=num_valid,
        source_level=m,
        order=order,
    )
    return level_in, fan_seconds


def _frames(side: Side, level: int, cache: dict) -> tuple[np.ndarray, np.ndarray]:
    """``([V, 3], [V, 3])`` the 3D tangent axes of each vertex's frame at ``level`` (the frame of
    ``side.neighborhoods[level]``: x along the tangent projection of the edge to ring slot 0, y
    counter-clockwise from it about the area-weighted normal)."""
    key = (id(side), level)
    if key not in cache:
        v = np.asarray(side.hierarchy.vertices[level], np.float64)
        f = np.asarray(side.hierarchy.faces[level], np.int64)
        nb = side.neighborhoods[level]
        index, mask, log = np.asarray(nb.index), np.asarray(nb.mask), np.asarray(nb.log)
        normal = vertex_normals(v, f, weighting="area")
        d = v[index] - v[:, None, :]  # [V, K, 3]
        d0 = d[:, 0] - np.sum(d[:, 0] * normal, axis=1, keepdims=True) * normal
        e1 = d0 / np.maximum(np.linalg.norm(d0, axis=1, keepdims=True), 1e-30)
        e2 = np.cross(normal, e1)
        # the log map's angles run counter-clockwise about the orientation of the faces; check
        sign = np.sign(
            np.sum(np.where(mask, log.imag * np.einsum("vkd,vd->vk", d, e2), 0.0), axis=1)
        )
        cache[key] = (e1, e2 * np.where(sign == 0, 1.0, sign)[:, None])
    return cache[key]


def _offset_upsample(
    source: Side,
    target: Side,
    level: int,
    m: int,
    prev_m: int,
    nnf_c,
    rot_c,
    valid_m,
    A: int,
    cache: dict,
) -> tuple[np.ndarray, np.ndarray]:
    """Matches and rotations of target level ``level`` from the coarser level's (``nnf_c`` /
    ``rot_c`` at source level ``prev_m``) moved by each fine vertex's geodesic offset.

    A fine vertex v with coarse parent P sits at offset ``z = log_P(v)`` in P's frame (the
    tangent-plane projection of ``x_v − x_P``); in the source frame of P's match ``s_P`` that is
    ``e^{2πi k_P / A} z``, the 3D point ``x_{s_P} + Re(·) e_1 + Im(·) e_2``. v's match is the source
    vertex of level ``m`` reached from ``s_P`` by walking to the nearest star vertex of that point
    (a greedy descent, 8 steps at most, over the valid source vertices); its rotation carries v's
    frame axis through P's frame and the same rotation into the new match's frame.
    """
    th, sh = target.hierarchy, source.hierarchy
    parent = np.asarray(th.pooling[level].parent)
    xt, xp = (
        np.asarray(th.vertices[level], np.float64),
        np.asarray(th.vertices[level + 1], np.float64)[parent],
    )
    e1p, e2p = (e[parent] for e in _frames(target, level + 1, cache))
    s_c = nnf_c[parent]
    xs_c = np.asarray(sh.vertices[prev_m], np.float64)[s_c]
    e1s, e2s = (e[s_c] for e in _frames(source, prev_m, cache))
    turn = np.exp(2j * np.pi * rot_c[parent] / A)

    def to_source(
        vec,
    ):  # a 3D tangent vector at the target parent -> at its match, rotated by its k
        z = (np.sum(vec * e1p, axis=1) + 1j * np.sum(vec * e2p, axis=1)) * turn
        return z.real[:, None] * e1s + z.imag[:, None] * e2s

    goal = xs_c + to_source(xt - xp)
    xs = np.asarray(sh.vertices[m], np.float64)
    nb = source.neighborhoods[m]
    index, mask = np.asarray(nb.index), np.asarray(nb.mask) & valid_m[np.asarray(nb.index)]
    s = source.inverse[m][sh.vertex_index[prev_m][s_c]].astype(np.int64)
    for _ in range(8):
        star = np.concatenate([s[:, None], index[s]], axis=1)
        dist = np.where(
            np.concatenate([np.ones((len(s), 1), bool), mask[s]], axis=1),
            np.linalg.norm(xs[star] - goal[:, None, :], axis=2),
            np.inf,
        )
        step = star[np.arange(len(s)), np.argmin(dist, axis=1)]
        if np.array_equal(step, s):
            break
        s = step
    e1t, _ = _frames(target, level, cache)
    w = to_source(e1t)  # v's frame axis, carried into the source
    e1n, e2n = _frames(source, m, cache)
    c = np.sum(w * e1n[s], axis=1) + 1j * np.sum(w * e2n[s], axis=1)
    rot = np.round(np.angle(c) * A / (2 * np.pi)).astype(np.int64) % A
    return s.astype(np.int32), rot.astype(np.int32)


class _Progress:
    """A tqdm bar per level (``progress=True``) or one line per level to a callable."""

    def __init__(self, progress: bool | Callable[[str], Any], total: int):
        self.report = progress if callable(progress) else None
        self.bar = None
        if progress is True:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, desc="meshmatch", unit="level")

    def level(self, line: str) -> None:
        if self.bar is not None:
            self.bar.set_postfix_str(line)
            self.bar.update(1)
        if self.report is not None:
            self.report(line)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _start_matches(
    source: Side,
    target: Side,
    level: int,
    lv: _Level,
    s_colors: np.ndarray,
    config: Config,
    *,
    key: jax.Array,
    initial: np.ndarray | None,
    previous: tuple | None,
    frames: dict,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, jax.Array]:
    """Where the search of target level ``level`` starts: ``(nnf [Vt], rotation [Vt], colours
    [Vt, C] or None (re-vote them), key)``.

    The coarsest level (``previous`` None) starts from ``initial`` or from random valid source
    vertices; a finer level from ``previous``, the coarser level's ``(source level, nnf, rotation,
    colours)``, upsampled as ``config.upsample`` says (``s_colors``: the pooled source colours at
    this level's source level).
    """
    sh, m, Vt = source.hierarchy, lv.source_level, lv.num_target
    if previous is None and initial is not None:  # coarsest level from the given matches
        src0 = source.inverse[0][initial[target.hierarchy.vertex_index[level]]]  # level-0 source
        nnf = ancestors(sh, 0, m)[np.maximum(src0, 0)].astype(np.int32)
        return nnf, np.zeros(Vt, np.int32), np.asarray(s_colors[nnf]), key
    if previous is None:  # coarsest level: random matches among the valid source vertices
        key, sub = jax.random.split(key)
        pick = np.asarray(jax.random.randint(sub, (Vt,), 0, lv.num_valid))
        nnf = lv.valid_index[pick]
        return nnf, np.zeros(Vt, np.int32), np.asarray(s_colors[nnf]), key
    prev_m, nnf_c, rot_c, colors_c = previous
    if config.upsample == "offset":  # the parent's match moved by the geodesic offset, re-voted
        valid_m = np.zeros(lv.num_padded_source, bool)
        valid_m[lv.valid_index[: lv.num_valid]] = True
        nnf, rot = _offset_upsample(
            source, target, level, m, prev_m, nnf_c, rot_c, valid_m, config.num_angles, frames
        )
        return nnf, rot, None, key
    # each vertex starts from its parent's match, moved to this source level
    parent = np.asarray(target.hierarchy.pooling[level].parent)
    nnf = source.inverse[m][sh.vertex_index[prev_m][nnf_c[parent]]].astype(np.int32)
    return nnf, rot_c[parent], colors_c[parent], key


def _start_arrays(
    lv: _Level, nnf: np.ndarray, rot: np.ndarray, colors: np.ndarray | None, config: Config, dtype
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The starting matches padded to the level's padded size on the device, ``(nnf, rotation,
    colours)``; colours None are voted from the matches."""
    Vp = lv.num_padded
    nnf_j = jnp.asarray(pad_axis(nnf.astype(np.int32), 0, Vp, lv.valid_index[0]))
    rot_j = jnp.asarray(pad_axis(rot.astype(np.int32), 0, Vp))
    if colors is not None:
        return nnf_j, rot_j, jnp.asarray(pad_axis(np.asarray(colors), 0, Vp), dtype)
    colors_j = vote_step(
        lv.tgt,
        lv.src.arr,
        nnf_j,
        rot_j,
        lv.weights,
        lv.pin,
        num_angles=config.num_angles,
        vote=config.vote,
    )
    return nnf_j, rot_j, colors_j


def _search_level(
    lv: _Level,
    start: tuple[jax.Array, jax.Array, jax.Array],
    config: Config,
    *,
    key: jax.Array,
    budget: int,
    shape_only_first: bool,
) -> tuple[tuple, int, list[float], list[float], jax.Array]:
    """Up to ``budget`` PatchMatch iterations of one level from ``start`` (``(nnf, rotation,
    colours)``), stopping when fewer than ``config.tolerance`` of the vertices change.

    ``shape_only_first``: the first iteration matches shape only (a random start's colours mean
    nothing). Returns ``((nnf, rotation, cost, colours), changed, wall seconds, CPU seconds per
    iteration, key)``.
    """
    nnf_j, rot_j, colors_j = start
    Vt = lv.num_target
    wall, cpu = [], []
    changed, cost = Vt, None
    for it in range(budget):
        t0, c0 = time.perf_counter(), time.process_time()
        key, sub = jax.random.split(key)
        weights = lv.weights
        if shape_only_first and it == 0:
            weights = weights._replace(color_scale=weights.color_scale * 0)
        nnf_j, rot_j, cost, colors_j, changed = iterate(
            lv.tgt,
            lv.src,
            nnf_j,
            rot_j,
            colors_j,
            sub,
            weights,
            lv.pin,
            lv.order,
            options=lv.options,
        )
        changed = int(changed)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        if changed < config.tolerance * Vt:
            break
    return (nnf_j, rot_j, cost, colors_j), changed, wall, cpu, key


def _level_record(
    level: int, lv: _Level, cost: np.ndarray, changed: int, wall: list, cpu: list, t_level: float
) -> dict:
    """One row of ``Match.stats["levels"]`` (``t_level``: when the level started)."""
    finite = np.isfinite(cost)
    return {
        "level": level,
        "source_level": lv.source_level,
        "vertices": lv.num_target,
        "padded_vertices": lv.num_padded,
        "padded_source_vertices": lv.num_padded_source,
        "steps": len(wall),
        "changed": changed,
        "mean_cost": float(cost[finite].mean()) if finite.any() else float("inf"),
        "seconds": time.perf_counter() - t_level,
        "iteration_seconds": wall,
        "iteration_cpu_seconds": cpu,
    }


def match_levels(
    source: Side,
    target: Side,
    colors: Float[np.ndarray, "Vs C"],
    config: Config,
    *,
    key: jax.Array,
    features: tuple[np.ndarray, np.ndarray],
    source_mask: np.ndarray,
    pin: np.ndarray | None,
    progress: bool | Callable[[str], Any] = False,
    initial: np.ndarray | None = None,
) -> Match:
    """Coarse-to-fine PatchMatch of prepared sides (the loop of :func:`meshmatch`).

    Args:
      source, target: :class:`~jmeshtex.meshmatch.core.Side` of each mesh.
      colors: ``[Vs, C]`` float64 source signal.
      config: :class:`~jmeshtex.meshmatch.Config`.
      key: PRNG key.
      features: ``([Vs, D], [Vt, D])`` shape features (with affinities when there are
        correspondences).
      source_mask: ``[Vs]`` bool, the source vertices a match may use.
      pin: ``[Vt]`` int64 source vertex each target vertex must match (-1: free), or None.
      progress: as :func:`meshmatch`.
      initial: ``[Vt]`` (input indexing) matches to start the coarsest level from, or None.

    Returns:
      :class:`Match` whose ``stats`` holds ``levels`` and ``fans_s``.
    """
    dtype = jnp.float32 if config.dtype == "float32" else jnp.float64
    pairing = level_pairing(source, target)
    s_colors = pool_colors(source.hierarchy, colors)
    dims_of = _group_dims(source, target, pairing, config)
    bar = _Progress(progress, target.num_levels)
    level_stats, fan_s = [], 0.0
    previous = cost = None
    frames: dict = {}  # per (side, level) 3D frame axes, for offset upsampling
    for level in range(target.num_levels - 1, -1, -1):
        t_level = time.perf_counter()
        m = pairing[level]
        lv, seconds = _level_inputs(
            source,
            target,
            level,
            m,
            s_colors[m],
            features,
            source_mask,
            pin,
            config,
            dtype,
            dims_of.get(level),
        )
        fan_s += seconds
        *start, key = _start_matches(
            source,
            target,
            level,
            lv,
            s_colors[m],
            config,
            key=key,
            initial=initial,
            previous=previous,
            frames=frames,
        )
        coarsest = level == target.num_levels - 1
        found, changed, wall, cpu, key = _search_level(
            lv,
            _start_arrays(lv, *start, config, dtype),
            config,
            key=key,
            budget=config.coarse_steps if coarsest else config.steps,
            shape_only_first=coarsest and config.shape_weight_at(level) > 0 and initial is None,
        )
        nnf, rot, cost, colors_t = (np.asarray(a)[: lv.num_target] for a in found)
        level_stats.append(_level_record(level, lv, cost, changed, wall, cpu, t_level))
        bar.level(
            f"level {level}: {lv.num_target} vertices, {len(wall)} iterations, mean cost "
            f"{level_stats[-1]['mean_cost']:.4g}, {changed} changed"
        )
        previous = (m, nnf, rot, colors_t)
    bar.close()

    nnf_input = source.hierarchy.vertex_index[pairing[0]][nnf]
    return Match(
        colors=colors[nnf_input],
        voted=np.asarray(colors_t, np.float64),
        nnf=nnf_input,
        rotation=rot,
        cost=cost,
        stats={"levels": level_stats, "fans_s": fan_s},
    )

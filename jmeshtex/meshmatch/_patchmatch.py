"""Coarse-to-fine PatchMatch between two meshes (MeshMatch, Chen et al. 2012 §4), jit-compiled.

For every target vertex t the nearest-neighbour field (NNF) holds a source vertex ``s`` and a
rotation ``k`` (target frame → source frame by ``2πk/A``). One iteration at a level is

- **E-step**, ``sweeps`` times per iteration (each sweep starts from the matches the previous one
  found, so good matches travel ``sweeps`` rings per iteration): candidates are one *propagated*
  match per one-ring neighbour q (q's match moved by p's offset from q, carried into the source
  frame with q's rotation and the target transport: ``e^{iθ_q} log_q(p)``, snapped to the nearest
  vertex of the source star), *random search* through the source hierarchy (hop up j levels from
  the current match, come down through random children) and uniformly random source vertices.
  All of them are pre-scored with a rotation-invariant lower bound of the patch distance (ring
  means and AC norms of the fans, :func:`fan_distance_bound`, plus the shape term: 27 numbers per
  vertex); only the ``exact_candidates`` best (and, once per iteration, the current match) get
  the exact score, at the best of the ``A`` cyclic rotations of the fans at once (cyclic
  cross-correlation through a real DFT of the angular axis) plus the rotation-invariant shape term.
- **M-step**: every target vertex's colour is the Gaussian-weighted vote of the source colours
  its own and its neighbours' matches put at its position.

Levels run from the coarsest to the finest; the NNF is upsampled through the parent maps; a final
pass copies each target vertex's matched source colour (no blur). Levels are padded in groups
(:func:`level_groups`: every level with at most ``bucket_vertices`` target vertices, then pairs of
larger levels) to one shape each (:func:`pad_level_arrays`) so a group shares one compiled step;
random numbers are hashed per vertex, so padding changes no real vertex.

Patch distance (``w_r`` ring weights, ``φ`` shape features, ``σ²_c`` the source colour variance):

.. math:: D(t, s) = \\min_k\\, \\frac{w_c}{R A C\\, \\sigma_c^2} \\sum_{i,a,c} w_i
          \\bigl(F_t[i, a, c] - F_s[i, (a + k) \\bmod A, c]\\bigr)^2 + w_\\phi \\lVert\\phi_t - \\phi_s\\rVert^2
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._types import Float, Int
from ..geometry import (
    MeshHierarchy,
    mesh_hierarchy,
    one_ring_neighborhood,
    tracer_geometry,
)
from ._config import MeshMatchConfig
from ._fans import (
    ancestors,
    geodesic_fans,
    hks_features,
    hks_level,
    shape_features,
    smoother,
)

# ---------------------------------------------------------------------------------------------
# host-side preparation


@dataclasses.dataclass
class Side:
    """One mesh prepared for MeshMatch: its hierarchy and per-level host geometry.

    Attributes:
      hierarchy: :class:`~jmeshtex.geometry.MeshHierarchy`.
      edge: per level mean edge length.
      neighborhoods: per level one-ring :class:`~jmeshtex.geometry.VertexNeighborhood` of the
        level mesh (the tracer's frames).
      smoothers: per level :class:`~jmeshtex.meshmatch._fans.Smoother`.
      tracers: per level :class:`~jmeshtex.geometry.TracerGeometry`.
      log_hks: ``[V_0, T]`` log heat kernel signature.
      features: ``[V_0, D]`` standardised shape features (plus affinities when given).
      inverse: per level ``[V_0]`` position of each input vertex in that level (-1 if absent).
      hks_times: ``[T]`` the HKS times used (pass them to the other mesh's :func:`prepare_side`).
    """

    hierarchy: MeshHierarchy
    edge: list
    neighborhoods: list
    smoothers: list
    tracers: list
    log_hks: np.ndarray
    features: np.ndarray
    inverse: list
    hks_times: np.ndarray

    @property
    def num_levels(self) -> int:
        return self.hierarchy.num_levels


def _mean_edge(v, f) -> float:
    return float(np.linalg.norm(v[f] - v[np.roll(f, -1, axis=1)], axis=2).mean())


def prepare_side(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    config: MeshMatchConfig,
    *,
    hks_times=None,
    hierarchy: MeshHierarchy | None = None,
) -> Side:
    """Hierarchy, per-level one-rings / tracer tables / smoothers and the log HKS of one mesh.

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` triangles.
      config: :class:`MeshMatchConfig`.
      hks_times: shared HKS times (default: from this mesh's spectrum).
      hierarchy: reuse a hierarchy.

    Returns:
      :class:`Side` (shape features still without affinities).

    Example:
      >>> from jmeshtex.data import icosphere
      >>> side = prepare_side(*icosphere(3), MeshMatchConfig(min_vertices=100))
      >>> side.num_levels, side.features.shape
      (3, (642, 9))
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if hierarchy is None:
        if config.levels == 1:
            hierarchy = mesh_hierarchy(vertices, faces, levels=1)
        else:
            hierarchy = mesh_hierarchy(vertices, faces, levels=config.levels, min_vertices=config.min_vertices)
    edge, nbs, sms, trs, inverse = [], [], [], [], []
    n0 = len(vertices)
    for level in range(hierarchy.num_levels):
        v, f = hierarchy.vertices[level], hierarchy.faces[level]
        edge.append(_mean_edge(v, f))
        nbs.append(one_ring_neighborhood(v, f))
        sms.append(smoother(f, len(v)))
        trs.append(tracer_geometry(v, f))
        inv = np.full(n0, -1, np.int64)
        inv[hierarchy.vertex_index[level]] = np.arange(len(v))
        inverse.append(inv)
    level = hks_level(hierarchy, config.hks_max_vertices)
    log_hks, times = hks_features(hierarchy, level=level, times=hks_times, num_times=config.hks_times,
                              k=config.hks_eigenpairs)
    features = shape_features(vertices, faces, log_hks, up=config.up)
    return Side(hierarchy, edge, nbs, sms, trs, log_hks, features, inverse, times)


# ---------------------------------------------------------------------------------------------
# jitted kernels


class LevelArrays(NamedTuple):
    """JAX arrays of one side at one level (see :func:`level_arrays`)."""

    nb_index: jax.Array  # [V, K]
    nb_mask: jax.Array  # [V, K]
    nb_log: jax.Array  # [V, K] complex
    nb_transport: jax.Array  # [V, K] complex
    fan_corners: jax.Array  # [V, R, A, 3]
    fan_bary: jax.Array  # [V, R, A, 3]
    sm_index: jax.Array  # [V, Ks]
    sm_weight: jax.Array  # [V, Ks]
    features: jax.Array  # [V, D]
    colors: jax.Array  # [V, C] (source: level colours; target: unused zeros)
    valid: jax.Array  # [V] bool (source: allowed matches)


def _dft_mats(A: int, dtype):
    m = np.arange(A // 2 + 1)
    a = np.arange(A)
    ang = 2 * np.pi * np.outer(a, m) / A  # [A, M]
    cm = np.where((m == 0) | ((A % 2 == 0) & (m == A // 2)), 1.0, 2.0)
    fwd_c, fwd_s = np.cos(ang), -np.sin(ang)
    inv_r = (cm[:, None] * np.cos(ang.T)) / A  # [M, A]
    inv_i = -(cm[:, None] * np.sin(ang.T)) / A
    return tuple(jnp.asarray(x, dtype) for x in (fwd_c, fwd_s, inv_r, inv_i))


def _gather(x, index):
    """``x[index]`` along axis 0 for in-range ``index`` of any shape, as one flat clipped take
    (about 2× faster on CPU than fancy indexing with a multi-dimensional index)."""
    flat = jnp.take(x, index.reshape(-1), axis=0, mode="clip")
    return flat.reshape(index.shape + x.shape[1:])


def _fan_values(arr: LevelArrays, colors, steps: tuple[int, ...]):
    """Pre-filtered fan samples ``[V, R, A, C]`` of per-vertex colours (as ``filtered_fans``)."""
    lam = jnp.asarray(0.5, colors.dtype)
    rings, current, done = [], colors, 0
    for i, s in enumerate(steps):
        for _ in range(s - done):
            current = (1 - lam) * current + lam * jnp.einsum("vk,vkc->vc", arr.sm_weight, _gather(current, arr.sm_index))
        done = max(done, s)
        corners, bary = arr.fan_corners[:, i], arr.fan_bary[:, i]
        rings.append(jnp.einsum("vak,vakc->vac", bary, _gather(current, corners)))
    return jnp.stack(rings, axis=1)


def fan_spectrum(fans, ring_weight, dtype=None):
    """Real DFT of the angular axis of weighted fans: ``(re, im) [V, R·C, M]`` and energies ``[V]``.

    .. math:: \\hat F[i c, m] = \\sum_a \\sqrt{w_i}\\, F[i, a, c]\\, e^{-2\\pi i m a / A}

    Example:
      >>> f = jnp.ones((2, 1, 4, 1))
      >>> re, im, e = fan_spectrum(f, jnp.ones(1))
      >>> np.round(re[0, 0], 6).tolist(), e.tolist()
      ([4.0, -0.0, 0.0], [4.0, 4.0])
    """
    dtype = fans.dtype if dtype is None else dtype
    V, R, A, C = fans.shape
    x = fans * jnp.sqrt(ring_weight).astype(fans.dtype)[None, :, None, None]
    x = jnp.transpose(x, (0, 1, 3, 2)).reshape(V, R * C, A)
    fwd_c, fwd_s, _, _ = _dft_mats(A, dtype)
    return x @ fwd_c, x @ fwd_s, jnp.sum(x * x, axis=(1, 2))


def rotation_distances(t_re, t_im, t_energy, s_re, s_im, s_energy, num_angles: int):
    """Squared fan distances at every cyclic shift k: ``‖T‖² + ‖S‖² − 2 Σ_a T[a] S[(a+k) mod A]``.

    All arguments are spectra from :func:`fan_spectrum` (leading axes broadcast).

    Example:
      >>> t = jnp.arange(6.0).reshape(1, 1, 6, 1)
      >>> s = jnp.roll(t, -2, axis=2)                       # S[a] = T[a + 2], so T[a] = S[a - 2]
      >>> d = rotation_distances(*fan_spectrum(t, jnp.ones(1)), *fan_spectrum(s, jnp.ones(1)), 6)
      >>> int(jnp.argmin(d[0])), float(jnp.round(d[0].min(), 6))
      (4, 0.0)
    """
    _, _, inv_r, inv_i = _dft_mats(num_angles, t_re.dtype)
    xr = jnp.sum(t_re * s_re + t_im * s_im, axis=-2)
    xi = jnp.sum(t_re * s_im - t_im * s_re, axis=-2)
    corr = xr @ inv_r + xi @ inv_i
    return t_energy[..., None] + s_energy[..., None] - 2.0 * corr


def _fan_summaries(re, im, num_angles: int):
    """Rotation-invariant summaries ``[V, 2·R·C]`` of fan spectra: ring means and AC norms.

    Per row (ring × channel) of a weighted fan ``x``: ``Σ_a x[a] / √A`` and ``‖x − mean(x)‖``
    (Parseval on the spectrum). Their squared distance is a lower bound of the fan distance at
    every rotation (see :func:`fan_distance_bound`).
    """
    M = re.shape[-1]
    m = np.arange(M)
    cm = np.where((m == 0) | ((num_angles % 2 == 0) & (m == num_angles // 2)), 0.0, 2.0) / num_angles
    power = re * re + im * im
    ac = jnp.sqrt(jnp.maximum(power @ jnp.asarray(cm, re.dtype), 0.0))
    dc = re[..., 0] / jnp.asarray(math.sqrt(num_angles), re.dtype)
    return jnp.concatenate([dc, ac], axis=-1)


def fan_distance_bound(t_re, t_im, s_re, s_im, num_angles: int):
    """Rotation-invariant lower bound of :func:`rotation_distances` (min over rotations).

    Per row (ring × channel), with ``μ`` the angular mean and ``x̃ = x − μ``:

    .. math:: \\min_k \\lVert T - S_{\\cdot + k} \\rVert^2 \\ge \\sum_{\\text{rows}}
              A(\\mu_T - \\mu_S)^2 + \\bigl(\\lVert \\tilde T\\rVert - \\lVert \\tilde S\\rVert\\bigr)^2

    (the mean and zero-mean parts are orthogonal; ``‖T̃ − S̃_k‖ ≥ |‖T̃‖ − ‖S̃‖|``). PatchMatch
    pre-scores every candidate with this 2·R·C-number summary and computes the exact rotation
    search only for the few best.

    Example:
      >>> t = jnp.arange(6.0).reshape(1, 1, 6, 1)
      >>> s = jnp.roll(t, -2, axis=2) + 0.5
      >>> ts, ss = fan_spectrum(t, jnp.ones(1)), fan_spectrum(s, jnp.ones(1))
      >>> exact = rotation_distances(*ts, *ss, 6).min()
      >>> bound = fan_distance_bound(ts[0], ts[1], ss[0], ss[1], 6)
      >>> float(jnp.round(bound[0], 6)), float(jnp.round(exact, 6))     # shift only: bound is tight
      (1.5, 1.5)
    """
    d = _fan_summaries(t_re, t_im, num_angles) - _fan_summaries(s_re, s_im, num_angles)
    return jnp.sum(d * d, axis=-1)


class _Src(NamedTuple):
    arr: LevelArrays
    pack: jax.Array  # [Vs, 2·RC·M + 1 + D]: re | im | energy | features, one row per vertex
    summary: jax.Array  # [Vs, 2·RC] ring means and AC norms (lower-bound pre-scoring)
    up: tuple  # per hop j: [Vs] ancestor at level min(m + j + 1, top)
    down: tuple  # per hop j: (children [V, M], count [V]) from level m + j + 1 to m + j (identity above top)
    valid_index: jax.Array  # [Nv] valid source vertices (padded with the first one)
    num_valid: jax.Array  # scalar


def _source_pack(re, im, energy, features):
    V = re.shape[0]
    return jnp.concatenate([re.reshape(V, -1), im.reshape(V, -1), energy[:, None], features], axis=1)


def _exact_cost(t_re, t_im, t_energy, t_feat, src: _Src, cand, A, color_scale, shape_weight):
    """Exact patch distance of candidates ``cand [V]`` at the best rotation: ``(cost, k)``."""
    V, RC, M = t_re.shape
    row = _gather(src.pack, cand)
    s_re = row[:, : RC * M].reshape(V, RC, M)
    s_im = row[:, RC * M : 2 * RC * M].reshape(V, RC, M)
    s_energy = row[:, 2 * RC * M]
    s_feat = row[:, 2 * RC * M + 1 :]
    d = rotation_distances(t_re, t_im, t_energy, s_re, s_im, s_energy, A)
    k = jnp.argmin(d, axis=1).astype(jnp.int32)
    dc = jnp.maximum(jnp.min(d, axis=1), 0.0)
    df = jnp.sum((t_feat - s_feat) ** 2, axis=1)
    cost = color_scale * dc + shape_weight * df
    return jnp.where(_gather(src.arr.valid, cand), cost, jnp.inf), k


def _offsets(tgt: LevelArrays, rot, A):
    """``[V, K]`` each target vertex p's position in the source frame of its neighbour q's match."""
    angle = (2 * np.pi / A) * rot.astype(tgt.nb_log.real.dtype)
    turn = jax.lax.complex(jnp.cos(angle), jnp.sin(angle))
    log_qp = -jnp.conj(tgt.nb_transport) * tgt.nb_log  # log_q(p) in q's frame
    return _gather(turn, tgt.nb_index) * log_qp


def _star(src_arr: LevelArrays, s):
    """Source star of ``s`` [..]: vertices ``[.., 1+K]``, offsets (log) and mask, self first."""
    idx = jnp.concatenate([s[..., None], _gather(src_arr.nb_index, s)], axis=-1)
    log = jnp.concatenate([jnp.zeros(s.shape + (1,), src_arr.nb_log.dtype), _gather(src_arr.nb_log, s)], axis=-1)
    mask = jnp.concatenate([jnp.ones(s.shape + (1,), bool), _gather(src_arr.nb_mask, s)], axis=-1)
    return idx, log, mask


def _star_nearest(src_arr, s, off):
    idx, log, mask = _star(src_arr, s)
    d = jnp.where(mask, jnp.abs(log - off[..., None]) ** 2, jnp.inf)
    j = jnp.argmin(d, axis=-1)
    return jnp.take_along_axis(idx, j[..., None], axis=-1)[..., 0]


def _star_interp(src_arr, s, off, tau2):
    idx, log, mask = _star(src_arr, s)
    logits = jnp.where(mask, -(jnp.abs(log - off[..., None]) ** 2) / (2 * tau2), -jnp.inf)
    w = jax.nn.softmax(logits, axis=-1)
    return jnp.einsum("...k,...kc->...c", w, _gather(src_arr.colors, idx))


def _vote(tgt: LevelArrays, src_arr: LevelArrays, nnf, rot, A, sigma2, tau2, pin):
    off = _offsets(tgt, rot, A)  # [V, K]
    sq = _gather(nnf, tgt.nb_index)  # [V, K]
    cols = _star_interp(src_arr, sq, off, tau2)  # [V, K, C]
    dist2 = jnp.abs(tgt.nb_log) ** 2
    w = jnp.where(tgt.nb_mask, jnp.exp(-dist2 / (2 * sigma2)), 0.0).astype(cols.dtype)
    own = _gather(src_arr.colors, nnf)
    out = (own + jnp.einsum("vk,vkc->vc", w, cols)) / (1.0 + jnp.sum(w, axis=1, keepdims=True))
    return jnp.where((pin >= 0)[:, None], src_arr.colors[jnp.maximum(pin, 0)], out)


def _mix32(h):
    """A 32-bit integer hash with good avalanche (``lowbias32``: xor-shift / multiply rounds)."""
    h = h ^ (h >> 16)
    h = h * jnp.uint32(0x7FEB352D)
    h = h ^ (h >> 15)
    h = h * jnp.uint32(0x846CA68B)
    return h ^ (h >> 16)


def _vertex_uniform(key, num_vertices: int, n: int):
    """``[n, V]`` uniforms in [0, 1): vertex v's numbers depend only on ``(key, v)``, so padding
    the vertex axis leaves every real vertex's random search unchanged.

    A counter-based hash of (vertex, per-draw seed from ``key``): far cheaper to compile and run
    than one threefry stream per vertex.
    """
    seed = jax.random.bits(key, (n, 1), jnp.uint32)
    i = jnp.arange(num_vertices, dtype=jnp.uint32)[None, :]
    h = _mix32(_mix32(i * jnp.uint32(0x9E3779B9) ^ seed) + seed)
    return (h >> 8).astype(jnp.float32) * jnp.float32(2.0**-24)


def _random_candidates(src: _Src, nnf, key, globals_: int):
    """Random search: up j levels from the current match and down through random children; then
    uniformly random valid source vertices. ``[H + globals_, V]``."""
    H = len(src.up)
    uniform = _vertex_uniform(key, nnf.shape[0], H * (H + 1) // 2 + globals_)
    cands, n = [], 0
    for j in range(H):
        a = src.up[j][nnf]
        for i in range(j, -1, -1):
            children, count = src.down[i]
            pick = jnp.minimum((uniform[n] * count[a].astype(jnp.float32)).astype(jnp.int32), count[a] - 1)
            n += 1
            a = children[a, pick]
        cands.append(a)
    for _ in range(globals_):
        pick = jnp.minimum((uniform[n] * src.num_valid.astype(jnp.float32)).astype(jnp.int32), src.num_valid - 1)
        n += 1
        cands.append(src.valid_index[pick])
    return cands


def _smallest(cands, bound, count: int):
    """The ``count`` candidates with the smallest bounds per row, ``([V, count], [V, count])``
    (repeated argmin: cheaper to compile and run on CPU than ``top_k`` for a handful)."""
    slots = jnp.arange(bound.shape[1])[None, :]
    picked_c, picked_b = [], []
    for _ in range(count):
        j = jnp.argmin(bound, axis=1)[:, None]
        picked_c.append(jnp.take_along_axis(cands, j, axis=1))
        picked_b.append(jnp.take_along_axis(bound, j, axis=1))
        bound = jnp.where(slots == j, jnp.inf, bound)
    return jnp.concatenate(picked_c, axis=1), jnp.concatenate(picked_b, axis=1)


@functools.partial(jax.jit, static_argnames=("A", "steps", "globals_", "sweeps", "exact"))
def _iterate(tgt, src: _Src, nnf, rot, colors, key, ring_weight, color_scale, shape_weight, sigma2,
             tau2, pin, *, A, steps, globals_, sweeps, exact):
    """One PatchMatch iteration at a level: E-step (``sweeps`` sweeps of re-scoring, random search
    and propagation), M-step (vote). Target vertices with ``tgt.valid`` False are padding (ignored
    in ``changed``).

    The current match is re-scored once; each sweep pre-scores its candidates with the
    rotation-invariant bound of :func:`fan_distance_bound` (a few numbers per vertex) and gives
    only the ``exact`` best the full rotation search; a sweep propagates from the matches the previous
    sweep found, so one iteration moves good matches ``sweeps`` rings. The sweeps run in a
    ``lax.scan``: one compiled body whatever their number.
    """
    t_re, t_im, t_energy = fan_spectrum(_fan_values(tgt, colors, steps), ring_weight)
    sc, sw = jnp.sqrt(color_scale), jnp.sqrt(shape_weight)
    t_desc = jnp.concatenate([sc * _fan_summaries(t_re, t_im, A), sw * tgt.features], axis=1)
    s_desc = jnp.concatenate([sc * src.summary, sw * src.arr.features], axis=1)

    def exact_cost(cand):
        return _exact_cost(t_re, t_im, t_energy, tgt.features, src, cand, A, color_scale, shape_weight)

    def sweep(state, key):
        """Pre-score random-search and propagated candidates (from this sweep's start), exact-score
        the ``exact`` best, keep improvements."""
        best, best_cost, best_rot = state
        prop = _star_nearest(src.arr, _gather(best, tgt.nb_index), _offsets(tgt, best_rot, A))  # [V, K]
        cands = jnp.stack(_random_candidates(src, best, key, globals_), axis=1) if num_random else prop[:, :0]
        allowed = jnp.concatenate([jnp.ones(cands.shape, bool), tgt.nb_mask], axis=1)
        cands = jnp.concatenate([cands, prop], axis=1)  # [V, N]
        diff = t_desc[:, None, :] - _gather(s_desc, cands)
        bound = jnp.sum(diff * diff, axis=-1)
        bound = jnp.where(allowed & (cands != best[:, None]) & _gather(src.arr.valid, cands), bound, jnp.inf)
        if cands.shape[1] > exact:
            cands, bound = _smallest(cands, bound, exact)

        def body(carry, xs):
            b, bc, br = carry
            cand, lb = xs
            c, k = exact_cost(cand)
            better = (c < bc) & jnp.isfinite(lb)  # an infinite bound marks a slot not to use
            return (jnp.where(better, cand, b), jnp.where(better, c, bc), jnp.where(better, k, br)), None

        state, _ = jax.lax.scan(body, (best, best_cost, best_rot), (cands.T, bound.T))
        return state, None

    num_random = len(src.up) + globals_
    # the current match is re-scored once (its cost changes with the target's colours, which stay
    # fixed during the sweeps)
    cost0, rot0 = exact_cost(nnf)
    (best, best_cost, best_rot), _ = jax.lax.scan(sweep, (nnf, cost0, rot0), jax.random.split(key, sweeps))

    best = jnp.where(pin >= 0, jnp.maximum(pin, 0), best)
    best_rot = jnp.where(pin >= 0, 0, best_rot)
    colors = _vote(tgt, src.arr, best, best_rot, A, sigma2, tau2, pin)
    changed = jnp.sum((best != nnf) & tgt.valid)
    return best, best_rot, jnp.where(pin >= 0, 0.0, best_cost), colors, changed


@functools.partial(jax.jit, static_argnames=("steps", "num_angles"))
def _source_tables(arr: LevelArrays, ring_weight, *, steps, num_angles):
    re, im, energy = fan_spectrum(_fan_values(arr, arr.colors, steps), ring_weight)
    return _source_pack(re, im, energy, arr.features), _fan_summaries(re, im, num_angles)


def _make_src(arr: LevelArrays, up, down, valid_index, num_valid: int, ring_weight, *, steps, num_angles) -> _Src:
    """Device-side source of one level: fan spectra packed per vertex, summaries, search maps."""
    arr = jax.tree.map(jnp.asarray, arr)
    pack, summary = _source_tables(arr, ring_weight, steps=steps, num_angles=num_angles)
    return _Src(arr, pack, summary, tuple(jnp.asarray(u, jnp.int32) for u in up),
                tuple((jnp.asarray(c, jnp.int32), jnp.asarray(n, jnp.int32)) for c, n in down),
                jnp.asarray(valid_index, jnp.int32), jnp.asarray(num_valid, jnp.int32))


# ---------------------------------------------------------------------------------------------
# driver


class MeshMatchResult(NamedTuple):
    """Output of :func:`meshmatch`.

    Attributes:
      colors: ``[Vt, C]`` final target colours: each vertex copies its matched source colour.
      voted: ``[Vt, C]`` the last Gaussian-weighted vote at the finest level (smoother).
      nnf: ``[Vt]`` matched source vertex (input indexing).
      rotation: ``[Vt]`` rotation step k: target frame → source frame by ``2πk/A``.
      cost: ``[Vt]`` patch distance of the match.
      stats: per-level iterations, times and mean costs, and preprocessing times.
    """

    colors: np.ndarray
    voted: np.ndarray
    nnf: np.ndarray
    rotation: np.ndarray
    cost: np.ndarray
    stats: dict


def _level_pairing(source: Side, target: Side) -> list[int]:
    hs, ht = np.log(np.asarray(source.edge)), np.log(np.asarray(target.edge))
    return [int(np.argmin(np.abs(hs - h))) for h in ht]


def _side_arrays(side: Side, level: int, radii, config, colors, valid, features, dtype):
    """Host (NumPy) :class:`LevelArrays` of one side at one level, and the fans' pre-filter steps."""
    h = side.hierarchy
    v, f = h.vertices[level], h.faces[level]
    # angle 0 half a step off the frame's x-axis (the edge to ring slot 0): no sample geodesic of a
    # regular mesh then runs along an edge through vertices (an ambiguous straightest geodesic)
    reference = np.full(len(v), np.exp(1j * np.pi / config.num_angles))
    fans = geodesic_fans(v, f, radii=radii, num_angles=config.num_angles, edge=side.edge[level],
                         reference=reference, geometry=side.tracers[level])
    nb, sm = side.neighborhoods[level], side.smoothers[level]
    real = np.dtype(dtype)
    cdt = np.complex64 if real == np.float32 else np.complex128
    arr = LevelArrays(
        nb_index=np.asarray(nb.index, np.int32),
        nb_mask=np.asarray(nb.mask, bool),
        nb_log=np.asarray(nb.log, cdt),
        nb_transport=np.asarray(nb.transport, cdt),
        fan_corners=np.asarray(fans.corners, np.int32),
        fan_bary=np.asarray(fans.bary, real),
        sm_index=np.asarray(sm.index, np.int32),
        sm_weight=np.asarray(sm.weight, real),
        features=np.asarray(features[h.vertex_index[level]], real),
        colors=np.asarray(colors, real),
        valid=np.asarray(valid, bool),
    )
    return arr, tuple(int(s) for s in fans.steps)


def _pad_axis(x: np.ndarray, axis: int, size: int, fill=0) -> np.ndarray:
    """``x`` padded with ``fill`` along ``axis`` to ``size`` (unchanged when already that long)."""
    extra = size - x.shape[axis]
    if extra < 0:
        raise ValueError(f"cannot pad axis {axis} of {x.shape} down to {size}")
    if extra == 0:
        return x
    shape = list(x.shape)
    shape[axis] = extra
    return np.concatenate([x, np.full(shape, fill, x.dtype)], axis=axis)


def pad_level_arrays(arr: LevelArrays, *, num_vertices: int, ring: int, smooth_ring: int) -> LevelArrays:
    """Pad one side's :class:`LevelArrays` to ``num_vertices`` rows and ``ring`` / ``smooth_ring``
    neighbour slots (padded-neighbourhood contract: index 0, mask False, weight 0, transport 1;
    padded vertices are not ``valid`` and no real vertex refers to them).

    Levels padded to one shape share one compiled PatchMatch step; padding changes no real
    vertex's result (tested).

    Example:
      >>> a = LevelArrays(*(np.zeros((3, 2), t) for t in (np.int32, bool, np.complex64, np.complex64)),
      ...                 np.zeros((3, 1, 4, 3), np.int32), np.zeros((3, 1, 4, 3), np.float32),
      ...                 np.zeros((3, 2), np.int32), np.full((3, 2), 0.5, np.float32),
      ...                 np.zeros((3, 9), np.float32), np.zeros((3, 3), np.float32), np.ones(3, bool))
      >>> p = pad_level_arrays(a, num_vertices=5, ring=4, smooth_ring=3)
      >>> p.nb_index.shape, p.valid.tolist(), p.nb_transport[0].tolist()
      ((5, 4), [True, True, True, False, False], [0j, 0j, (1+0j), (1+0j)])
    """
    V = num_vertices
    fields = {}
    for name, x in arr._asdict().items():
        fill = 1 if name == "nb_transport" else 0
        x = _pad_axis(np.asarray(x), 0, V, fill)
        if name in ("nb_index", "nb_mask", "nb_log", "nb_transport"):
            x = _pad_axis(x, 1, ring, fill)
        elif name in ("sm_index", "sm_weight"):
            x = _pad_axis(x, 1, smooth_ring, fill)
        fields[name] = x
    return LevelArrays(**fields)


def _search_tables(h: MeshHierarchy, m: int, hops: int):
    """Random-search maps of source level ``m`` with a fixed structure of ``hops`` hops.

    ``up[j]``: each level-m vertex's ancestor at level ``min(m + j + 1, top)``; ``down[i]``:
    ``(children, count)`` from level ``m + i + 1`` to ``m + i``, or the identity of the top level
    where ``m + i + 1`` lies above it (so hops beyond the top repeat the top-level search). The
    fixed structure lets every level share one compiled step.
    """
    top = h.num_levels - 1
    up, down = [], []
    for j in range(hops):
        up.append(ancestors(h, m, min(m + j + 1, top)).astype(np.int32))
    for i in range(hops):
        if m + i + 1 <= top:
            p = h.pooling[m + i]
            down.append((np.asarray(p.children, np.int32), np.asarray(p.children_mask).sum(1).astype(np.int32)))
        else:
            n = len(h.vertices[top])
            down.append((np.arange(n, dtype=np.int32)[:, None], np.ones(n, np.int32)))
    return up, down


def level_groups(sizes, bucket_vertices: int, *, ratio: float = 2.5) -> list[list[int]]:
    """Levels that are padded to one shape and share one compiled PatchMatch step.

    All levels with at most ``bucket_vertices`` vertices form one group (they are cheap: padding
    costs little, each compile saved costs seconds); from the finest level down, a larger level
    joins the group of the level above it when that group's largest size is at most ``ratio``
    times its own (with halving hierarchies: pairs of levels, the smaller padded to the larger: its
    extra work, a few iterations at twice its size, costs less than a compile of the step).

    Args:
      sizes: vertex count per level, finest first.
      bucket_vertices: the small-level bucket bound (0: no small-level bucket).
      ratio: largest padding factor of a larger level.

    Returns:
      Groups of level indices (each list finest first); every level is in exactly one.

    Example:
      >>> level_groups([65536, 32768, 16384, 8192, 4096, 2048, 1024], 4096)
      [[0, 1], [2, 3], [4, 5, 6]]
      >>> level_groups([1000, 500, 250], 0)
      [[0, 1], [2]]
    """
    small = [lv for lv, n in enumerate(sizes) if n <= bucket_vertices]
    groups: list[list[int]] = []
    for lv, n in enumerate(sizes):
        if lv in small:
            continue
        if groups and sizes[groups[-1][0]] <= ratio * n and len(groups[-1]) < 2:
            groups[-1].append(lv)
        else:
            groups.append([lv])
    if small:
        groups.append(small)
    return groups


def _bucket_dims(source: Side, target: Side, pairing, levels, hops: int) -> dict:
    """Common padded sizes of the levels in ``levels`` (target and source rows, ring slots, children)."""
    dims = {"Vt": 0, "Kt": 0, "Kst": 0, "Vs": 0, "Ks": 0, "Kss": 0, "down": [(0, 0)] * hops}
    for level in levels:
        m = pairing[level]
        dims["Vt"] = max(dims["Vt"], len(target.hierarchy.vertices[level]))
        dims["Kt"] = max(dims["Kt"], target.neighborhoods[level].index.shape[1])
        dims["Kst"] = max(dims["Kst"], target.smoothers[level].index.shape[1])
        dims["Vs"] = max(dims["Vs"], len(source.hierarchy.vertices[m]))
        dims["Ks"] = max(dims["Ks"], source.neighborhoods[m].index.shape[1])
        dims["Kss"] = max(dims["Kss"], source.smoothers[m].index.shape[1])
        _, down = _search_tables(source.hierarchy, m, hops)
        dims["down"] = [(max(a, c.shape[0]), max(b, c.shape[1])) for (a, b), (c, _) in zip(dims["down"], down, strict=True)]
    return dims


def _pool_colors(h: MeshHierarchy, colors: np.ndarray) -> list[np.ndarray]:
    out = [np.asarray(colors, np.float64)]
    for p in h.pooling:
        c = out[-1]
        out.append(np.einsum("vm,vmc->vc", p.children_weight, c[p.children]))
    return out


def meshmatch(
    source_vertices: Float[np.ndarray, "Vs 3"],
    source_faces: Int[np.ndarray, "Fs 3"],
    source_colors: Float[np.ndarray, "Vs C"],
    target_vertices: Float[np.ndarray, "Vt 3"],
    target_faces: Int[np.ndarray, "Ft 3"],
    *,
    config: MeshMatchConfig | None = None,
    seed: int = 0,
    correspondences: Int[np.ndarray, "m 2"] | None = None,
    source_mask: np.ndarray | None = None,
    pin: Int[np.ndarray, " Vt"] | None = None,
    progress: bool | Callable[[str], Any] = False,
    prepared: tuple[Side, Side] | None = None,
) -> MeshMatchResult:
    """Transfer per-vertex signals from a source mesh to a target mesh by PatchMatch (MeshMatch).

    .. math:: \\text{NNF}(t) = \\arg\\min_{s, k} D_k(t, s), \\qquad
              c_t = \\frac{\\sum_{q \\in \\{t\\} \\cup N(t)} g_{tq}\\, c^{src}\\bigl(\\exp_{s_q}(e^{i\\theta_q}
              \\log_q t)\\bigr)}{\\sum_q g_{tq}}

    (Chen et al. 2012, §4: E-step / M-step; see the module docstring for ``D``.)

    Args:
      source_vertices, source_faces: the exemplar mesh.
      source_colors: ``[Vs, C]`` per-vertex signal on the source (colours, displacements, ...).
      target_vertices, target_faces: the mesh to synthesise on (same units as the source: the
        texture keeps its world-space scale).
      config: :class:`MeshMatchConfig` (default settings when None).
      seed: PRNG seed of the random initialisation and search.
      correspondences: ``[m, 2]`` (source vertex, target vertex) pairs; adds geodesic affinities.
      source_mask: ``[Vs]`` bool, the source vertices a match may use (default all).
      pin: ``[Vt]`` source vertex each target vertex must match (−1: free) — for painting by
        example, where source and target are the same mesh.
      progress: True for a tqdm bar per level, or a callable receiving one line per level.
      prepared: ``(source_side, target_side)`` from :func:`prepare_side` to reuse preprocessing.

    Returns:
      :class:`MeshMatchResult`.

    Raises:
      InputError: shapes of colours, masks, pins; an empty source mask.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> v, f = icosphere(2)
      >>> v = v * (1 + 0.25 * np.sin(3 * v[:, :1] + 1) * np.cos(2 * v[:, 1:2]))   # no symmetry left
      >>> colors = 0.5 + 0.4 * np.sin(5 * v[:, :3])
      >>> r = meshmatch(v, f, colors, v, f, config=MeshMatchConfig(levels=1, coarse_iterations=25))
      >>> r.colors.shape, bool(np.abs(r.colors - colors).mean() < 0.05)      # self-transfer
      ((162, 3), True)
    """
    config = MeshMatchConfig() if config is None else config
    t_start = time.perf_counter()
    sv, sf = np.asarray(source_vertices, np.float64), np.asarray(source_faces, np.int64)
    tv, tf = np.asarray(target_vertices, np.float64), np.asarray(target_faces, np.int64)
    colors = np.asarray(source_colors, np.float64)
    if colors.ndim == 1:
        colors = colors[:, None]
    if colors.ndim != 2 or len(colors) != len(sv) or not np.all(np.isfinite(colors)):
        raise InputError(f"source_colors must be finite [Vs={len(sv)}, C], got shape {colors.shape}")
    valid0 = np.ones(len(sv), bool) if source_mask is None else np.asarray(source_mask, bool)
    if valid0.shape != (len(sv),):
        raise InputError(f"source_mask must have shape [Vs={len(sv)}], got {valid0.shape}")
    if not valid0.any():
        raise InputError("source_mask selects no source vertex: paint (mask) at least one region")
    pin0 = None if pin is None else np.asarray(pin, np.int64)
    if pin0 is not None and (pin0.shape != (len(tv),) or pin0.max(initial=-1) >= len(sv) or pin0.min(initial=0) < -1):
        raise InputError(f"pin must be [Vt={len(tv)}] source vertices or -1, got shape {pin0.shape}")
    dtype = jnp.float32 if config.dtype == "float32" else jnp.float64

    timings: dict[str, float] = {}
    if prepared is None:
        t0 = time.perf_counter()
        source = prepare_side(sv, sf, config)
        same = sv.shape == tv.shape and sf.shape == tf.shape and np.array_equal(sv, tv) and np.array_equal(sf, tf)
        target = source if same else prepare_side(tv, tf, config, hks_times=source.hks_times)
        timings["prepare_s"] = time.perf_counter() - t0
    else:
        source, target = prepared
    s_feat, t_feat = source.features, target.features
    if correspondences is not None:
        a_s, a_t = correspondence_affinities_for(source, target, correspondences)
        w = math.sqrt(config.affinity_weight)
        s_feat = np.concatenate([s_feat, w * a_s], axis=1)
        t_feat = np.concatenate([t_feat, w * a_t], axis=1)

    pairing = _level_pairing(source, target)
    s_colors = _pool_colors(source.hierarchy, colors)
    C = colors.shape[1]
    R, A = config.num_radii, config.num_angles
    ring_weight = jnp.ones(R, dtype) / R
    key = jax.random.key(seed)

    bar = None
    report = progress if callable(progress) else None
    if progress is True:
        from tqdm.auto import tqdm

        bar = tqdm(total=target.num_levels, desc="meshmatch", unit="level")

    level_stats = []
    nnf = rot = colors_t = None
    fan_s = 0.0
    prev_src_level = None
    hops = config.random_search_levels
    sh = source.hierarchy
    # levels padded to a common shape share one compiled step (see `level_groups`)
    group_dims = {}
    sizes = [len(x) for x in target.hierarchy.vertices]
    for group in level_groups(sizes, config.bucket_vertices) if config.bucket_vertices > 0 else []:
        if len(group) > 1:
            dims = _bucket_dims(source, target, pairing, group, hops)
            group_dims.update({lv: dims for lv in group})
    for level in range(target.num_levels - 1, -1, -1):
        t_level = time.perf_counter()
        m = pairing[level]
        radii = config.radii(target.edge[level])
        valid_m = valid0[sh.vertex_index[m]]
        if not valid_m.any():  # a tiny painted region may vanish at a coarse level
            valid_m = np.ones_like(valid_m)
        t0 = time.perf_counter()
        s_arr, s_steps = _side_arrays(source, m, radii, config, s_colors[m], valid_m, s_feat, dtype)
        Vt = len(target.hierarchy.vertices[level])
        t_arr, t_steps = _side_arrays(target, level, radii, config, np.zeros((Vt, C)), np.ones(Vt, bool),
                                      t_feat, dtype)
        up, down = _search_tables(sh, m, hops)
        valid_index = np.nonzero(valid_m)[0].astype(np.int32)
        num_valid = len(valid_index)
        dims = group_dims.get(level)
        if dims is not None:
            s_arr = pad_level_arrays(s_arr, num_vertices=dims["Vs"], ring=dims["Ks"], smooth_ring=dims["Kss"])
            t_arr = pad_level_arrays(t_arr, num_vertices=dims["Vt"], ring=dims["Kt"], smooth_ring=dims["Kst"])
            up = [_pad_axis(u, 0, dims["Vs"]) for u in up]
            down = [(_pad_axis(_pad_axis(c, 0, n), 1, k), _pad_axis(cnt, 0, n, 1))
                    for (c, cnt), (n, k) in zip(down, dims["down"], strict=True)]
            valid_index = _pad_axis(valid_index, 0, dims["Vs"], valid_index[0])
        Vp = t_arr.nb_index.shape[0]
        t_arr = jax.tree.map(jnp.asarray, t_arr)
        fan_s += time.perf_counter() - t0
        src = _make_src(s_arr, up, down, valid_index, num_valid, ring_weight, steps=s_steps, num_angles=A)
        variance = float(np.var(s_colors[m][valid_m])) + 1e-8
        color_scale = jnp.asarray(config.color_weight / (R * A * C * variance), dtype)
        shape_weight = jnp.asarray(config.shape_weight_at(level), dtype)
        sigma2 = jnp.asarray((config.vote_sigma * target.edge[level]) ** 2, dtype)
        tau2 = jnp.asarray((0.5 * source.edge[m]) ** 2, dtype)
        tvi = target.hierarchy.vertex_index[level]
        if pin0 is None:
            pin_l = np.full(Vt, -1, np.int32)
        else:
            p = pin0[tvi]
            mapped = np.where(p >= 0, source.inverse[m][np.maximum(p, 0)], -1)
            pin_l = np.where(mapped >= 0, mapped, -1).astype(np.int32)
        pin_l = jnp.asarray(_pad_axis(pin_l, 0, Vp, -1))

        if nnf is None:  # coarsest level: random matches among the valid source vertices
            key, sub = jax.random.split(key)
            pick = np.asarray(jax.random.randint(sub, (Vt,), 0, num_valid))
            nnf_h = valid_index[pick]
            rot_h = np.zeros(Vt, np.int32)
            colors_h = np.asarray(s_colors[m][nnf_h])
        else:  # upsample: each vertex starts from its parent's match, moved to this source level
            parent = np.asarray(target.hierarchy.pooling[level].parent)
            coarse = nnf[parent]
            nnf_h = source.inverse[m][sh.vertex_index[prev_src_level][coarse]].astype(np.int32)
            rot_h = rot[parent]
            colors_h = colors_t[parent]
        nnf_j = jnp.asarray(_pad_axis(nnf_h.astype(np.int32), 0, Vp, valid_index[0]))
        rot_j = jnp.asarray(_pad_axis(rot_h.astype(np.int32), 0, Vp))
        colors_j = jnp.asarray(_pad_axis(np.asarray(colors_h), 0, Vp), dtype)
        its, changed = 0, Vt
        cost = None
        coarsest = level == target.num_levels - 1
        budget = config.coarse_iterations if coarsest else config.iterations
        for it in range(budget):
            key, sub = jax.random.split(key)
            # the random start's colours mean nothing: its first E-step matches shape only
            scale = color_scale * 0 if (coarsest and it == 0 and config.shape_weight_at(level) > 0) else color_scale
            nnf_j, rot_j, cost, colors_j, changed = _iterate(
                t_arr, src, nnf_j, rot_j, colors_j, sub, ring_weight, scale, shape_weight, sigma2, tau2,
                pin_l, A=A, steps=t_steps, globals_=config.global_candidates, sweeps=config.sweeps,
                exact=config.exact_candidates,
            )
            its += 1
            changed = int(changed)
            if changed < config.tolerance * Vt:
                break
        nnf = np.asarray(nnf_j)[:Vt]
        rot = np.asarray(rot_j)[:Vt]
        colors_t = np.asarray(colors_j)[:Vt]
        cost_np = np.asarray(cost)[:Vt]
        finite = np.isfinite(cost_np)
        mean_cost = float(cost_np[finite].mean()) if finite.any() else float("inf")
        level_stats.append({
            "level": level, "source_level": m, "vertices": Vt, "padded_vertices": Vp, "iterations": its,
            "changed": changed, "mean_cost": mean_cost, "seconds": time.perf_counter() - t_level,
        })
        line = f"level {level}: {Vt} vertices, {its} iterations, mean cost {mean_cost:.4g}, {changed} changed"
        if bar is not None:
            bar.set_postfix_str(line)
            bar.update(1)
        if report is not None:
            report(line)
        prev_src_level = m
    if bar is not None:
        bar.close()

    m0 = pairing[0]
    nnf_input = source.hierarchy.vertex_index[m0][nnf]
    voted = np.asarray(colors_t, np.float64)
    final = colors[nnf_input]
    timings["fans_s"] = fan_s
    timings["total_s"] = time.perf_counter() - t_start
    return MeshMatchResult(
        colors=final,
        voted=voted,
        nnf=nnf_input,
        rotation=rot,
        cost=cost_np,
        stats={"levels": level_stats, **timings},
    )


def correspondence_affinities_for(source: Side, target: Side, pairs):
    """Affinities of :func:`~jmeshtex.meshmatch.correspondence_affinities` for prepared sides."""
    from ._fans import correspondence_affinities

    hs, ht = source.hierarchy, target.hierarchy
    return correspondence_affinities(hs.vertices[0], hs.faces[0], ht.vertices[0], ht.faces[0], pairs)

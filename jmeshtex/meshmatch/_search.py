"""The jitted PatchMatch step of MeshMatch (Chen et al. 2012 §4): one E-step + M-step at one level.

For every target vertex t the nearest-neighbour field (NNF) holds a source vertex ``s`` and a
rotation ``k`` (target frame → source frame by ``2πk/A``). One iteration (:func:`iterate`) is

- **E-step**, ``sweeps`` times per iteration (each sweep starts from the matches the previous one
  found, so good matches travel ``sweeps`` rings per iteration): candidates are one *propagated*
  match per one-ring neighbour q (q's match moved by p's offset from q, carried into the source
  frame with q's rotation and the target transport: ``e^{iθ_q} log_q(p)``, snapped to the nearest
  vertex of the source star), *random search* through the source hierarchy (hop up j levels from
  the current match, come down through random children) and uniformly random source vertices.
  All of them are pre-scored with a rotation-invariant lower bound of the patch distance (ring
  means and AC norms of the fans, :func:`~jmeshtex.meshmatch.core.fan_distance_bound`, plus the shape
  term: 27 numbers per vertex); only the ``exact_candidates`` best (and, once per iteration, the
  current match) get the exact score, at the best of the ``A`` cyclic rotations of the fans at once
  (cyclic cross-correlation through a real DFT of the angular axis) plus the rotation-invariant
  shape term.
- **M-step**: every target vertex's colour is the Gaussian-weighted vote of the source colours
  its own and its neighbours' matches put at its position (``vote="ring"``), or, with
  ``vote="fan"`` (the paper's footprint), of the source colours every target vertex's match puts at
  each point of its geodesic fan (:func:`_fan_vote`).

Random numbers are hashed per vertex, so padding the vertex axis changes no real vertex.

Patch distance (``w_r`` ring weights, ``φ`` shape features, ``σ²_c`` the source colour variance):

.. math:: D(t, s) = \\min_k\\, \\frac{w_c}{R A C\\, \\sigma_c^2} \\sum_{i,a,c} w_i
          \\bigl(F_t[i, a, c] - F_s[i, (a + k) \\bmod A, c]\\bigr)^2 + w_\\phi \\lVert\\phi_t - \\phi_s\\rVert^2
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._jit import jit_loop
from ._config import Config
from ._prepare import LevelArrays
from ._spectrum import _fan_summaries, fan_spectrum, rotation_distances


class SearchOptions(NamedTuple):
    """The static (compile-time) settings of :func:`iterate`: a new value compiles a new step.

    Attributes:
      num_angles: ``A``, rotations searched.
      prefilter_steps: per ring, smoothing steps of the fans' pre-filter.
      global_candidates: uniformly random source vertices per target vertex and sweep.
      sweeps: propagation sweeps per iteration.
      exact_candidates: candidates per sweep that get the exact rotation search.
      star_candidates: propagation proposes every vertex of the star of each neighbour's match
        (the paper's "whole neighbourhood of NNF(q)") instead of the one nearest the propagated
        offset.
      propagation: ``"parallel"`` (every vertex of a sweep at once, Jacobi) or ``"sequential"``
        (breadth-first wavefronts, Gauss–Seidel; :func:`~jmeshtex.meshmatch.core.scan_order`).
      vote: the M-step, ``"ring"`` (one-ring vote) or ``"fan"`` (fan-footprint vote).
    """

    num_angles: int
    prefilter_steps: tuple[int, ...]
    global_candidates: int
    sweeps: int
    exact_candidates: int
    star_candidates: bool = False
    propagation: str = "parallel"
    vote: str = "ring"

    @classmethod
    def of(cls, config: Config, prefilter_steps) -> SearchOptions:
        """The options of ``config`` with the target level's pre-filter steps."""
        return cls(
            config.num_angles,
            tuple(int(s) for s in prefilter_steps),
            config.experimental.global_candidates,
            config.sweeps,
            config.experimental.exact_candidates,
            config.experimental.star_candidates,
            config.propagation,
            config.vote,
        )


class StepWeights(NamedTuple):
    """The per-level weights of :func:`iterate` (traced: a new value compiles nothing).

    Attributes:
      ring_weight: ``[R]`` ring weights of the fan distance.
      color_scale: ``w_c / (R A C σ_c²)``, the colour term's factor.
      shape_weight: ``w_φ``, the shape term's factor.
      sigma2: variance of the vote's Gaussian over target offsets.
      tau2: variance of the interpolation in the source star.
      fan_weight: ``[R]`` the fan vote's weight of each ring (``vote="fan"``; None otherwise).
    """

    ring_weight: jax.Array
    color_scale: jax.Array
    shape_weight: jax.Array
    sigma2: jax.Array
    tau2: jax.Array
    fan_weight: jax.Array | None = None


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
            current = (1 - lam) * current + lam * jnp.einsum(
                "vk,vkc->vc", arr.sm_weight, _gather(current, arr.sm_index)
            )
        done = max(done, s)
        corners, bary = arr.fan_corners[:, i], arr.fan_bary[:, i]
        rings.append(jnp.einsum("vak,vakc->vac", bary, _gather(current, corners)))
    return jnp.stack(rings, axis=1)


class Source(NamedTuple):
    """Device-side source of one level (:func:`make_source`)."""

    arr: LevelArrays
    pack: jax.Array  # [Vs, 2·RC·M + 1 + D]: re | im | energy | features, one row per vertex
    summary: jax.Array  # [Vs, 2·RC] ring means and AC norms (lower-bound pre-scoring)
    up: tuple  # per hop j: [Vs] ancestor at level min(m + j + 1, top)
    down: tuple  # per hop j: (children [V, M], count [V]) from level m + j + 1 to m + j (identity above top)
    valid_index: jax.Array  # [Nv] valid source vertices (padded with the first one)
    num_valid: jax.Array  # scalar


def _source_pack(re, im, energy, features):
    V = re.shape[0]
    return jnp.concatenate(
        [re.reshape(V, -1), im.reshape(V, -1), energy[:, None], features], axis=1
    )


def _exact_cost(t_re, t_im, t_energy, t_feat, src: Source, cand, A, color_scale, shape_weight):
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
    return _ring_offsets(tgt.nb_index, tgt.nb_log, tgt.nb_transport, rot, A)


def _ring_offsets(nb_index, nb_log, nb_transport, rot, A):
    """:func:`_offsets` for the rows whose one-rings are ``nb_index`` / ``nb_log`` / ``nb_transport``
    ``[B, K]`` (``rot``: ``[V]`` rotations of every target vertex)."""
    angle = (2 * np.pi / A) * rot.astype(nb_log.real.dtype)
    turn = jax.lax.complex(jnp.cos(angle), jnp.sin(angle))
    log_qp = -jnp.conj(nb_transport) * nb_log  # log_q(p) in q's frame
    return _gather(turn, nb_index) * log_qp


def _star(src_arr: LevelArrays, s):
    """Source star of ``s`` [..]: vertices ``[.., 1+K]``, offsets (log) and mask, self first."""
    idx = jnp.concatenate([s[..., None], _gather(src_arr.nb_index, s)], axis=-1)
    log = jnp.concatenate(
        [jnp.zeros(s.shape + (1,), src_arr.nb_log.dtype), _gather(src_arr.nb_log, s)], axis=-1
    )
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


def _fan_vote(tgt: LevelArrays, src_arr: LevelArrays, nnf, rot, A, fan_weight, pin):
    """The fan-footprint vote (Chen et al. 2012 §4, M-step): every real target vertex q votes at
    every point its fan covers. Target fan sample ``(r, a)`` of q lies in a target face at
    barycentric coordinates ``b``; it carries the source colour at source fan sample
    ``(r, (a + rot_q) mod A)`` of ``NNF(q)`` (read linearly in its face), weighted by
    ``fan_weight[r] · b_j`` onto the face's corner ``j``; q's own centre votes its match's colour
    with weight 1. Each vertex's colour is the weighted mean of the votes it receives:

    .. math:: c_p = \\frac{\\sum_q [p = q]\\, C_s(\\mathrm{NNF}(q)) + \\sum_{q, r, a, j}
              [F^t_{q r a j} = p]\\, w_r\\, b^t_{q r a j}\\, F^s_{\\mathrm{NNF}(q), r, a + k_q}}
              {\\sum_q [p = q] + \\sum_{q, r, a, j} [F^t_{q r a j} = p]\\, w_r\\, b^t_{q r a j}}

    Padded target rows (``tgt.valid`` False) vote nothing; pinned vertices keep their pin's colour.
    """
    V = nnf.shape[0]
    real = tgt.valid.astype(src_arr.colors.dtype)  # padded rows vote nothing
    corners = _gather(src_arr.fan_corners, nnf)  # [V, R, A, 3] source fan of each match
    bary = _gather(src_arr.fan_bary, nnf)
    turn = (
        jnp.arange(A, dtype=rot.dtype)[None, :] + rot[:, None]
    ) % A  # target angle a -> source angle a + k
    corners = jnp.take_along_axis(corners, turn[:, None, :, None], axis=2)
    bary = jnp.take_along_axis(bary, turn[:, None, :, None], axis=2)
    vals = jnp.einsum("vrak,vrakc->vrac", bary, _gather(src_arr.colors, corners))  # [V, R, A, C]
    w = (fan_weight[None, :, None, None] * tgt.fan_bary) * real[:, None, None, None]  # [V, R, A, 3]
    seg = tgt.fan_corners.reshape(-1)
    num = jax.ops.segment_sum(
        (w[..., None] * vals[:, :, :, None, :]).reshape(seg.shape[0], -1), seg, num_segments=V
    )
    den = jax.ops.segment_sum(w.reshape(-1), seg, num_segments=V)
    own = _gather(src_arr.colors, nnf)
    out = (own * real[:, None] + num) / (real + den)[:, None].clip(1e-12)
    out = jnp.where(tgt.valid[:, None], out, own)
    return jnp.where((pin >= 0)[:, None], src_arr.colors[jnp.maximum(pin, 0)], out)


def vote_colors(
    tgt: LevelArrays,
    src_arr: LevelArrays,
    nnf,
    rot,
    weights: StepWeights,
    pin,
    *,
    num_angles: int,
    vote: str,
):
    """The M-step of :func:`iterate` alone: the ring vote (``vote="ring"``) or the fan-footprint
    vote (``"fan"``, :func:`_fan_vote`) of matches ``nnf`` / ``rot`` (``[V]``)."""
    if vote == "fan":
        return _fan_vote(tgt, src_arr, nnf, rot, num_angles, weights.fan_weight, pin)
    return _vote(tgt, src_arr, nnf, rot, num_angles, weights.sigma2, weights.tau2, pin)


#: :func:`vote_colors`, jitted (the re-vote after upsampling)
vote_step = jax.jit(vote_colors, static_argnames=("num_angles", "vote"))


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


def _random_candidates(src: Source, nnf, key, globals_: int):
    """Random search: up j levels from the current match and down through random children; then
    uniformly random valid source vertices. ``[H + globals_, V]``."""
    H = len(src.up)
    uniform = _vertex_uniform(key, nnf.shape[0], H * (H + 1) // 2 + globals_)
    cands, n = [], 0
    for j in range(H):
        a = src.up[j][nnf]
        for i in range(j, -1, -1):
            children, count = src.down[i]
            pick = jnp.minimum(
                (uniform[n] * count[a].astype(jnp.float32)).astype(jnp.int32), count[a] - 1
            )
            n += 1
            a = children[a, pick]
        cands.append(a)
    for _ in range(globals_):
        pick = jnp.minimum(
            (uniform[n] * src.num_valid.astype(jnp.float32)).astype(jnp.int32), src.num_valid - 1
        )
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


class _Sweeps(NamedTuple):
    """What every sweep of one iteration reads: the level's arrays, the target's fan spectra (of the
    previous vote's colours, fixed during the sweeps) and both sides' pre-scoring descriptors."""

    tgt: LevelArrays
    src: Source
    t_re: jax.Array
    t_im: jax.Array
    t_energy: jax.Array
    t_desc: jax.Array
    s_desc: jax.Array
    color_scale: jax.Array
    shape_weight: jax.Array
    options: SearchOptions


class _Rows(NamedTuple):
    """The target rows one update touches (all of them, or one wavefront's): their one-ring
    neighbourhoods, current ``(match, cost, rotation)``, descriptors and exact-cost terms."""

    nb_index: jax.Array
    nb_mask: jax.Array
    nb_log: jax.Array
    nb_transport: jax.Array
    cur: jax.Array
    cur_cost: jax.Array
    cur_rot: jax.Array
    desc: jax.Array
    terms: tuple  # (re, im, energy, features) of the exact cost


def _sweeps(tgt: LevelArrays, src: Source, colors, weights: StepWeights, options) -> _Sweeps:
    """The target's fan spectra of ``colors`` and the descriptors of the rotation-invariant bound
    (fan summaries and shape features, scaled by the square roots of their weights)."""
    t_re, t_im, t_energy = fan_spectrum(
        _fan_values(tgt, colors, options.prefilter_steps), weights.ring_weight
    )
    sc, sw = jnp.sqrt(weights.color_scale), jnp.sqrt(weights.shape_weight)
    t_desc = jnp.concatenate(
        [sc * _fan_summaries(t_re, t_im, options.num_angles), sw * tgt.features], axis=1
    )
    s_desc = jnp.concatenate([sc * src.summary, sw * src.arr.features], axis=1)
    return _Sweeps(
        tgt,
        src,
        t_re,
        t_im,
        t_energy,
        t_desc,
        s_desc,
        weights.color_scale,
        weights.shape_weight,
        options,
    )


def _exact(sw: _Sweeps, terms: tuple, cand):
    """Exact patch distance and best rotation of candidates ``cand`` for the rows of ``terms``."""
    A = sw.options.num_angles
    return _exact_cost(*terms, sw.src, cand, A, sw.color_scale, sw.shape_weight)


def _rows(sw: _Sweeps, state, rows) -> _Rows:
    """The :class:`_Rows` of target vertices ``rows`` (None: all of them) in ``state``."""
    tgt = sw.tgt
    nb = (tgt.nb_index, tgt.nb_mask, tgt.nb_log, tgt.nb_transport)
    terms = (sw.t_re, sw.t_im, sw.t_energy, tgt.features)
    if rows is None:
        return _Rows(*nb, *state, sw.t_desc, terms)
    return _Rows(
        *(_gather(x, rows) for x in nb),
        *(_gather(x, rows) for x in (*state, sw.t_desc)),
        tuple(_gather(x, rows) for x in terms),
    )


def _candidates(sw: _Sweeps, r: _Rows, best, best_rot, key):
    """The rows' candidates, ``([B, N], [B, N])`` with their lower bounds (inf: not to use):
    random-search ones and those propagated from the neighbours' matches ``best`` / ``best_rot``
    (all target vertices), the ``exact_candidates`` smallest bounds kept."""
    src, options = sw.src, sw.options
    if options.star_candidates:  # every vertex of each neighbour's matched star
        idx, _, smask = _star(src.arr, _gather(best, r.nb_index))  # [B, K, 1 + Ks]
        prop = idx.reshape(idx.shape[0], -1)
        prop_ok = (r.nb_mask[:, :, None] & smask).reshape(prop.shape)
    else:
        prop = _star_nearest(
            src.arr,
            _gather(best, r.nb_index),
            _ring_offsets(r.nb_index, r.nb_log, r.nb_transport, best_rot, options.num_angles),
        )
        prop_ok = r.nb_mask
    if len(src.up) + options.global_candidates:
        cands = jnp.stack(_random_candidates(src, r.cur, key, options.global_candidates), axis=1)
    else:
        cands = prop[:, :0]
    allowed = jnp.concatenate([jnp.ones(cands.shape, bool), prop_ok], axis=1)
    cands = jnp.concatenate([cands, prop], axis=1)  # [B, N]
    diff = r.desc[:, None, :] - _gather(sw.s_desc, cands)
    bound = jnp.sum(diff * diff, axis=-1)
    bound = jnp.where(
        allowed & (cands != r.cur[:, None]) & _gather(src.arr.valid, cands), bound, jnp.inf
    )
    if cands.shape[1] > options.exact_candidates:
        cands, bound = _smallest(cands, bound, options.exact_candidates)
    return cands, bound


def _improve(sw: _Sweeps, rows, state, key):
    """One sweep's update of target vertices ``rows`` (None: all of them, in parallel): pre-score
    random-search and propagated candidates (from ``state``), exact-score the
    ``exact_candidates`` best, keep improvements. Returns the rows' ``(best, cost, rot)``."""
    best, _, best_rot = state
    r = _rows(sw, state, rows)
    cands, bound = _candidates(sw, r, best, best_rot, key)

    def body(carry, xs):
        b, bc, br = carry
        cand, lb = xs
        c, k = _exact(sw, r.terms, cand)
        better = (c < bc) & jnp.isfinite(lb)  # an infinite bound marks a slot not to use
        return (
            jnp.where(better, cand, b),
            jnp.where(better, c, bc),
            jnp.where(better, k, br),
        ), None

    out, _ = jax.lax.scan(body, (r.cur, r.cur_cost, r.cur_rot), (cands.T, bound.T))
    return out


def _sequential_sweeps(sw: _Sweeps, state, key, order):
    """``sweeps`` Gauss–Seidel sweeps: each runs through the breadth-first wavefronts of ``order``
    (a ``lax.scan`` over its rows; padded slots, index ``V``, write nothing), odd sweeps
    backwards from the far end."""
    if order is None:
        raise InputError(
            "propagation='sequential' needs the breadth-first wavefronts: pass "
            "order=jmeshtex.meshmatch.core.scan_order(...), or use propagation='parallel'"
        )

    def wavefront(state, xs):
        rows, key = xs
        new = _improve(sw, rows, state, key)
        return tuple(x.at[rows].set(y, mode="drop") for x, y in zip(state, new, strict=True)), None

    for sweep_index, sub in enumerate(jax.random.split(key, sw.options.sweeps)):
        rows = order if sweep_index % 2 == 0 else order[::-1, ::-1]
        state, _ = jax.lax.scan(wavefront, state, (rows, jax.random.split(sub, rows.shape[0])))
    return state


@jit_loop(static_argnames=("options",))
def iterate(
    tgt: LevelArrays,
    src: Source,
    nnf,
    rot,
    colors,
    key,
    weights: StepWeights,
    pin,
    order=None,
    *,
    options: SearchOptions,
):
    """One PatchMatch iteration at a level: E-step (``sweeps`` sweeps of re-scoring, random search
    and propagation), M-step (vote). Target vertices with ``tgt.valid`` False are padding (ignored
    in ``changed``).

    The current match is re-scored once; each sweep pre-scores its candidates with the
    rotation-invariant bound of :func:`~jmeshtex.meshmatch.core.fan_distance_bound` (a few numbers per
    vertex) and gives only the ``exact_candidates`` best the full rotation search; a sweep
    propagates from the matches the previous sweep found, so one iteration moves good matches
    ``sweeps`` rings. The sweeps run in a ``lax.scan``: one compiled body whatever their number.

    With ``options.propagation == "sequential"`` (the paper's scan, Gauss–Seidel) each sweep
    instead runs through the breadth-first wavefronts of ``order`` one after the other (a
    ``lax.scan`` over its rows): a wavefront's candidates come from the matches the earlier ones
    found in this sweep, so a good match can travel across the whole mesh in one sweep; odd sweeps
    run the wavefronts in reverse order (the alternating start). Its random numbers are drawn per
    wavefront slot, so unlike the parallel step it is not invariant to padding ``order``.

    Args:
      tgt: the target level's :class:`~jmeshtex.meshmatch.core.LevelArrays` (JAX), ``Vt`` rows.
      src: the source level (:func:`make_source`).
      nnf: ``[Vt]`` int32 current matches; ``rot``: ``[Vt]`` int32 their rotations.
      colors: ``[Vt, C]`` the target's current colours (the previous vote).
      key: PRNG key of this iteration's random search.
      weights: :class:`StepWeights`.
      pin: ``[Vt]`` int32 source vertex a target vertex must match, or -1.
      order: ``[L, B]`` int32 target vertices per breadth-first wavefront, padded with ``Vt``
        (:func:`~jmeshtex.meshmatch.core.scan_order`); only with sequential propagation.
      options: :class:`SearchOptions` (static).

    Returns:
      ``(nnf, rot, cost, colors, changed)``: the new matches, rotations, patch distances ``[Vt]``,
      voted colours ``[Vt, C]`` and the number of real target vertices whose match changed.
    """
    sw = _sweeps(tgt, src, colors, weights, options)
    # the current match is re-scored once (its cost changes with the target's colours, which stay
    # fixed during the sweeps)
    cost0, rot0 = _exact(sw, (sw.t_re, sw.t_im, sw.t_energy, tgt.features), nnf)
    if options.propagation == "sequential":
        state = _sequential_sweeps(sw, (nnf, cost0, rot0), key, order)
    else:

        def sweep(state, key):
            return _improve(sw, None, state, key), None

        state, _ = jax.lax.scan(sweep, (nnf, cost0, rot0), jax.random.split(key, options.sweeps))
    best, best_cost, best_rot = state
    best = jnp.where(pin >= 0, jnp.maximum(pin, 0), best)
    best_rot = jnp.where(pin >= 0, 0, best_rot)
    colors = vote_colors(
        tgt, src.arr, best, best_rot, weights, pin, num_angles=options.num_angles, vote=options.vote
    )
    changed = jnp.sum((best != nnf) & tgt.valid)
    return best, best_rot, jnp.where(pin >= 0, 0.0, best_cost), colors, changed


@functools.partial(jax.jit, static_argnames=("steps", "num_angles"))
def _source_tables(arr: LevelArrays, ring_weight, *, steps, num_angles):
    re, im, energy = fan_spectrum(_fan_values(arr, arr.colors, steps), ring_weight)
    return _source_pack(re, im, energy, arr.features), _fan_summaries(re, im, num_angles)


def make_source(
    arr: LevelArrays, up, down, valid_index, num_valid: int, ring_weight, *, steps, num_angles
) -> Source:
    """Device-side source of one level: fan spectra packed per vertex, summaries, search maps.

    Args:
      arr: the source level's host :class:`~jmeshtex.meshmatch.core.LevelArrays`.
      up, down: random-search maps (:func:`~jmeshtex.meshmatch._prepare.search_tables`).
      valid_index: ``[Nv]`` the valid source vertices (padded with the first one).
      num_valid: how many of them are real.
      ring_weight: ``[R]`` ring weights.
      steps: per ring pre-filter steps of the source fans.
      num_angles: ``A``.
    """
    arr = jax.tree.map(jnp.asarray, arr)
    pack, summary = _source_tables(arr, ring_weight, steps=steps, num_angles=num_angles)
    return Source(
        arr,
        pack,
        summary,
        tuple(jnp.asarray(u, jnp.int32) for u in up),
        tuple((jnp.asarray(c, jnp.int32), jnp.asarray(n, jnp.int32)) for c, n in down),
        jnp.asarray(valid_index, jnp.int32),
        jnp.asarray(num_valid, jnp.int32),
    )

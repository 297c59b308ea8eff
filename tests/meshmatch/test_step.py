"""The jitted PatchMatch step: lower-bound pre-scoring, propagation sweeps, padding, search maps."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex.data import icosphere
from jmeshtex.geometry import mesh_hierarchy, one_rings
from jmeshtex.meshmatch import Config
from jmeshtex.meshmatch._features import ancestors
from jmeshtex.meshmatch._prepare import level_arrays, pad_axis, search_tables
from jmeshtex.meshmatch._search import (
    SearchOptions,
    Source,
    StepWeights,
    _random_candidates,
    _smallest,
    iterate,
    make_source,
)
from jmeshtex.meshmatch.core import (
    fan_distance_bound,
    fan_spectrum,
    level_groups,
    pad_level_arrays,
    prepare_side,
    rotation_distances,
    scan_order,
)


def _bumpy(level=2):
    v, f = icosphere(level)
    r = 1 + 0.25 * np.sin(3 * v[:, 0] + 1) * np.cos(2 * v[:, 1]) + 0.15 * np.sin(4 * v[:, 2] + 0.5)
    return v * r[:, None], f


def test_fan_distance_bound_is_below_every_rotation_and_tight_for_shifts(rng):
    A, R, C = 7, 2, 3
    n = 12
    t = rng.standard_normal((n, R, A, C))
    s = rng.standard_normal((n, R, A, C))
    w = jnp.asarray([0.3, 0.7])
    ts, ss = fan_spectrum(jnp.asarray(t), w), fan_spectrum(jnp.asarray(s), w)
    bound = np.asarray(fan_distance_bound(ts[0], ts[1], ss[0], ss[1], A))
    # slow reference: every cyclic shift, by loops
    exact = np.array(
        [
            [
                sum(
                    w[i] * (t[n, i, a, c] - s[n, i, (a + k) % A, c]) ** 2
                    for i in range(R)
                    for a in range(A)
                    for c in range(C)
                )
                for k in range(A)
            ]
            for n in range(n)
        ]
    ).min(1)
    np.testing.assert_allclose(
        np.asarray(rotation_distances(*ts, *ss, A)).min(1), exact, rtol=1e-10
    )
    assert np.all(bound <= exact + 1e-10)
    # informative, not a trivial 0: exactly the documented bound, per row (ring i, channel c)
    # w_i [A (mean_T - mean_S)^2 + (|T - mean_T| - |S - mean_S|)^2], by loops (holds for every draw,
    # unlike a threshold on the ratio bound / exact, whose distribution reaches below any fixed value)
    formula, wn = np.zeros(n), np.asarray(w)
    for m in range(n):
        for i in range(R):
            for c in range(C):
                tr, sr = t[m, i, :, c], s[m, i, :, c]
                mt, ms = tr.mean(), sr.mean()
                formula[m] += wn[i] * (
                    A * (mt - ms) ** 2 + (np.linalg.norm(tr - mt) - np.linalg.norm(sr - ms)) ** 2
                )
    np.testing.assert_allclose(bound, formula, rtol=1e-10, atol=1e-12)
    # a rolled fan plus a constant per row: the bound is exact
    shifted = np.roll(t, 3, axis=2) + rng.standard_normal((n, R, 1, C))
    sh = fan_spectrum(jnp.asarray(shifted), w)
    np.testing.assert_allclose(
        np.asarray(fan_distance_bound(ts[0], ts[1], sh[0], sh[1], A)),
        np.asarray(rotation_distances(*ts, *sh, A)).min(1),
        rtol=1e-9,
        atol=1e-9,
    )


def _level(cfg, colors, v, f):
    """Source = target = (v, f) at level 0: host arrays, source tables, target colours."""
    side = prepare_side((v, f), cfg)
    radii = cfg.radii(side.edge[0])
    s_arr, steps = level_arrays(
        side, 0, radii, cfg, colors, np.ones(len(v), bool), side.features, np.float64
    )
    t_arr, _ = level_arrays(
        side, 0, radii, cfg, np.zeros_like(colors), np.ones(len(v), bool), side.features, np.float64
    )
    up, down = search_tables(side.hierarchy, 0, cfg.experimental.random_search_levels)
    return side, s_arr, t_arr, steps, up, down


def _step(cfg, t_arr, s_arr, up, down, steps, nnf, colors, key, Vp=None, dims=None, order=None):
    V = len(nnf)
    valid_index = np.arange(s_arr.nb_index.shape[0], dtype=np.int32)
    if dims is not None:
        s_arr = pad_level_arrays(s_arr, **dims)
        t_arr = pad_level_arrays(t_arr, **dims)
        up = [pad_axis(u, 0, dims["num_vertices"]) for u in up]
        down = [
            (pad_axis(c, 0, dims["num_vertices"]), pad_axis(n, 0, dims["num_vertices"], 1))
            for c, n in down
        ]
        valid_index = pad_axis(valid_index, 0, dims["num_vertices"], 0)
    A = cfg.num_angles
    ring_weight = jnp.ones(cfg.num_radii, jnp.float64) / cfg.num_radii
    src = make_source(s_arr, up, down, valid_index, V, ring_weight, steps=steps, num_angles=A)
    Vp = t_arr.nb_index.shape[0]
    scalar = lambda x: jnp.asarray(x, jnp.float64)  # noqa: E731
    weights = StepWeights(
        ring_weight,
        scalar(1.0 / (cfg.num_radii * A * colors.shape[1] * colors.var())),
        scalar(1.0),
        scalar(0.01),
        scalar(0.01),
    )
    return iterate(
        jax.tree.map(jnp.asarray, t_arr),
        src,
        jnp.asarray(pad_axis(nnf, 0, Vp)),
        jnp.zeros(Vp, jnp.int32),
        jnp.asarray(pad_axis(colors, 0, Vp)),
        key,
        weights,
        jnp.full(Vp, -1, jnp.int32),
        None if order is None else jnp.asarray(order),
        options=SearchOptions.of(cfg, steps),
    )


def _ring_distance(faces, V, start):
    rings = one_rings(faces, V)
    dist = np.full(V, -1)
    dist[start] = 0
    frontier = [start]
    d = 0
    while frontier:
        d += 1
        nxt = rings.ring[frontier][rings.mask[frontier]]
        nxt = np.unique(nxt[dist[nxt] < 0])
        dist[nxt] = d
        frontier = list(nxt)
    return dist


@pytest.mark.parametrize("sweeps", [1, 2])
def test_one_iteration_propagates_a_correct_match_sweeps_rings(sweeps, rng, key):
    """Self-match with random colours and one seed vertex matched to itself, everything else to a
    far vertex: one iteration (no random search) must fix exactly the ``sweeps``-ring disc."""
    v, f = _bumpy(2)
    colors = rng.uniform(0, 1, (len(v), 3))
    cfg = Config.from_dict(
        dict(
            levels=1, random_search_levels=0, global_candidates=0, sweeps=sweeps, exact_candidates=2
        )
    )
    _, s_arr, t_arr, steps, up, down = _level(cfg, colors, v, f)
    seed_vertex = 7
    dist = _ring_distance(f, len(v), seed_vertex)
    far = int(np.argmax(dist))
    nnf = np.full(len(v), far, np.int32)
    nnf[seed_vertex] = seed_vertex
    best, rot, cost, _, _ = _step(cfg, t_arr, s_arr, up, down, steps, nnf, colors, key)
    hit = np.asarray(best) == np.arange(len(v))
    assert hit[dist <= sweeps].all()
    assert np.asarray(rot)[dist <= sweeps].tolist() == [0] * int((dist <= sweeps).sum())
    np.testing.assert_allclose(np.asarray(cost)[dist <= sweeps], 0.0, atol=1e-9)
    assert hit[dist == sweeps + 1].mean() < 0.5  # information moved no further


def test_one_sequential_sweep_carries_a_correct_match_across_the_mesh(rng, key):
    """Sequential (Gauss–Seidel) propagation, wavefronts from the seed vertex, every other vertex
    matched at random: one sweep hands the seed's correct match from wavefront to wavefront, so
    every vertex gets it; one parallel sweep fixes the seed's one-ring only (and a few vertices
    whose random neighbours' matches happen to propose them)."""
    v, f = _bumpy(2)
    colors = rng.uniform(0, 1, (len(v), 3))
    cfg = Config.from_dict(
        dict(
            levels=1,
            random_search_levels=0,
            global_candidates=0,
            sweeps=1,
            exact_candidates=2,
            propagation="sequential",
        )
    )
    _, s_arr, t_arr, steps, up, down = _level(cfg, colors, v, f)
    seed_vertex = 7
    V = len(v)
    nnf = ((np.arange(V) + rng.integers(1, V, V)) % V).astype(np.int32)  # every match wrong ...
    nnf[seed_vertex] = seed_vertex  # ... but the seed's
    order = scan_order(t_arr.nb_index, t_arr.nb_mask, start=seed_vertex)
    best, rot, cost, _, _ = _step(cfg, t_arr, s_arr, up, down, steps, nnf, colors, key, order=order)
    assert (np.asarray(best) == np.arange(V)).all()
    np.testing.assert_allclose(np.asarray(cost), 0.0, atol=1e-9)
    parallel = _step(
        cfg.replace(propagation="parallel"), t_arr, s_arr, up, down, steps, nnf, colors, key
    )
    assert (np.asarray(parallel[0]) == np.arange(V)).mean() < 0.2


def test_scan_order_is_breadth_first_wavefronts():
    v, f = _bumpy(2)
    rings = one_rings(f, len(v))
    order = scan_order(rings.ring, rings.mask, start=3)
    V = len(v)
    real = order[order < V]
    assert sorted(real.tolist()) == list(range(V))  # every vertex once, padding = V
    row = np.empty(V, int)
    for r, vs in enumerate(order):
        row[vs[vs < V]] = r
    np.testing.assert_array_equal(row, _ring_distance(f, V, 3))
    # two components: the second follows the first, from its own lowest vertex
    both = scan_order(
        np.concatenate([rings.ring, rings.ring + V]),
        np.concatenate([rings.mask, rings.mask]),
        pad_to=(0, order.shape[1] + 2),
        fill=-1,
    )
    assert both.shape[1] == order.shape[1] + 2 and sorted(both[both >= 0].tolist()) == list(
        range(2 * V)
    )
    assert both[0].tolist()[:1] == [0] and V in both[order.shape[0]].tolist()


def test_padding_leaves_every_real_vertex_unchanged(rng, key):
    v, f = _bumpy(2)
    colors = rng.uniform(0, 1, (len(v), 3))
    cfg = Config(levels=2, min_vertices=40)
    side, s_arr, t_arr, steps, up, down = _level(cfg, colors, v, f)
    assert (
        len(up) == cfg.experimental.random_search_levels
    )  # structure fixed even above the hierarchy's top
    nnf = rng.integers(0, len(v), len(v)).astype(np.int32)
    plain = _step(cfg, t_arr, s_arr, up, down, steps, nnf, colors, key)
    K = t_arr.nb_index.shape[1]
    dims = {"num_vertices": len(v) + 37, "ring": K + 3, "smooth_ring": t_arr.sm_index.shape[1] + 2}
    padded = _step(cfg, t_arr, s_arr, up, down, steps, nnf, colors, key, dims=dims)
    V = len(v)
    np.testing.assert_array_equal(np.asarray(padded[0])[:V], np.asarray(plain[0]))
    np.testing.assert_array_equal(np.asarray(padded[1])[:V], np.asarray(plain[1]))
    np.testing.assert_allclose(np.asarray(padded[2])[:V], np.asarray(plain[2]), rtol=1e-10)
    np.testing.assert_allclose(np.asarray(padded[3])[:V], np.asarray(plain[3]), rtol=1e-10)
    assert int(padded[4]) == int(plain[4])  # padded vertices are not counted as changed
    assert np.all(np.asarray(padded[0]) < V)  # nothing matches a padded source vertex


def test_random_search_candidates_are_descendants_of_the_hop_ancestor(rng, key):
    """Oracle for the hierarchical hop maps: the hop-j candidate of s is a level-m descendant of
    s's ancestor at level min(m + j + 1, top), drawn through the children tables."""
    v, f = _bumpy(3)
    h = mesh_hierarchy(v, f, levels=3)
    for m in (0, 2):  # 2 is the top: every hop repeats the top-level search (identity maps)
        up, down = search_tables(h, m, 4)
        V = len(h.vertices[m])
        src = Source(
            None,
            None,
            None,
            tuple(jnp.asarray(u) for u in up),
            tuple((jnp.asarray(c), jnp.asarray(n)) for c, n in down),
            jnp.arange(V, dtype=jnp.int32),
            jnp.asarray(V, jnp.int32),
        )
        s = jnp.asarray(rng.integers(0, V, 300).astype(np.int32))
        cands = _random_candidates(src, s, key, 2)
        assert len(cands) == 4 + 2
        for j in range(4):
            top = min(m + j + 1, h.num_levels - 1)
            anc = ancestors(h, m, top)
            np.testing.assert_array_equal(anc[np.asarray(cands[j])], anc[np.asarray(s)])
        for c in cands:
            assert 0 <= int(c.min()) and int(c.max()) < V
        if m == 0:  # the deepest hop reaches far: candidates spread over the level
            assert len(np.unique(np.asarray(cands[2]))) > 100


def test_level_groups_share_a_step_and_change_no_result():
    """Padding levels into shared shapes (default) gives the same transfer as no padding at all."""
    from jmeshtex.meshmatch import meshmatch

    assert level_groups([400, 200, 100, 50], 100) == [[0, 1], [2, 3]]
    assert level_groups([400, 150, 100], 0) == [[0], [1, 2]]  # 400 > 2.5 · 150: not paired
    v, f = _bumpy(2)
    colors = 0.5 + 0.4 * np.sin(4 * v[:, :3] + np.array([0.0, 1.0, 2.0]))
    base = dict(levels=3, min_vertices=40, steps=2, coarse_steps=3, hks_eigenpairs=12)
    key = jax.random.key(0)
    padded = meshmatch(
        (v, f), colors, (v, f), key=key, config=Config(**base).replace(bucket_vertices=100)
    )
    plain = meshmatch(
        (v, f), colors, (v, f), key=key, config=Config(**base).replace(bucket_vertices=0)
    )
    stats = padded.stats["levels"]
    assert [s["padded_vertices"] for s in stats] == [max(s["vertices"] for s in stats[:2])] * 2 + [
        162
    ]
    np.testing.assert_array_equal(padded.nnf, plain.nnf)
    np.testing.assert_array_equal(padded.rotation, plain.rotation)
    np.testing.assert_allclose(padded.cost, plain.cost, rtol=1e-5)


def test_smallest_picks_the_lowest_bounds_in_order(rng):
    bound = rng.permutation(40).reshape(5, 8).astype(np.float64)
    bound[2] = np.inf  # nothing allowed: the picks carry infinite bounds (never accepted)
    cands = np.arange(40, dtype=np.int32).reshape(5, 8) + 100
    c, b = _smallest(jnp.asarray(cands), jnp.asarray(bound), 3)
    order = np.argsort(bound, axis=1, kind="stable")[:, :3]
    np.testing.assert_array_equal(np.asarray(b), np.take_along_axis(bound, order, axis=1))
    rows = [0, 1, 3, 4]
    np.testing.assert_array_equal(
        np.asarray(c)[rows], np.take_along_axis(cands, order, axis=1)[rows]
    )

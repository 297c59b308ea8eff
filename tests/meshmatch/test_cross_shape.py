"""MeshMatch between different shapes with ground truth, and correspondences that steer it.

The colours are one smooth field of the direction from the centre, shared by a bumpy sphere and a
bumpier one of another tessellation (the small case of ``benchmarks/meshmatch.py --suite cross``),
so the target's true colours are known.
"""

from __future__ import annotations

import pathlib
import sys

import jax
import numpy as np
import pytest
from scipy.spatial import cKDTree

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "benchmarks"))

from meshmatch import sphere_bumps, sphere_pair  # noqa: E402 (the benchmark script)

from jmeshtex import ConfigError, InputError, Mesh  # noqa: E402
from jmeshtex.data import icosphere  # noqa: E402
from jmeshtex.meshmatch import Config, meshmatch, transfer  # noqa: E402
from jmeshtex.metrics import psnr  # noqa: E402


def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _pair():
    return sphere_pair(3)


#: measured on this pair (642 vertices each): the default (aligned: whole normal + standardised
#: positions) 28.7 dB (key 0), the intrinsic features (Config.intrinsic(): HKS + n·up) 28.5-28.8 dB
#: (keys 0-2; 25.9-26.2 dB with the shape weights (3, 30)), the paper's search (whole-star
#: candidates, every candidate searched exactly) 28.6 dB (keys 0-1), intrinsic shape-only (colour
#: weight 0) 16.9-17.4 dB (keys 0-3), nearest source direction 29.1 dB; the floor sits between.
#: (The aligned features alone, colour weight 0, reach 28.6 dB: the positions place patches.)
FLOOR_DB = 25.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_colours_reach_a_floor_the_shape_only_match_misses(seed):
    """Between different shapes the colours must steer the pose-free match: with colours the
    intrinsic features reach the floor, without them (shape only) they miss it; the default gets
    there too."""
    source, sc, target, truth, u, tu = _pair()
    ceiling = psnr(sc[cKDTree(u).query(tu)[1]], truth)
    key = jax.random.key(seed)
    intrinsic = psnr(
        np.clip(meshmatch(source, sc, target, key=key, config=Config.intrinsic()).colors, 0, 1),
        truth,
    )
    shape_only = psnr(
        meshmatch(source, sc, target, key=key, config=Config.intrinsic(color_weight=0.0)).colors,
        truth,
    )
    assert intrinsic > FLOOR_DB > shape_only
    assert intrinsic < ceiling + 1.0  # sanity: the nearest copy of the source bounds a copy of it
    if seed == 0:
        default = psnr(
            np.clip(meshmatch(source, sc, target, key=key, config=Config()).colors, 0, 1), truth
        )
        assert ceiling + 1.0 > default > FLOOR_DB


def test_correspondences_flip_a_left_right_symmetric_case():
    """An ellipsoid symmetric under x -> -x, red on the source's +x half: two user pairs that map
    the source's +x end to the target's -x end (and back) put the red on the target's -x half.

    With the pose-free features (:meth:`Config.intrinsic`): nothing but the pairs tells the two
    halves apart there (HKS and n·up are mirror-symmetric), so the pairs decide. (The aligned
    default's standardised positions tell +x from -x by themselves:
    ``test_a_shared_pose_resolves_the_mirror_ambiguity``.)"""
    source, target = _ellipsoids()
    sx, tx = source.vertices[:, 0], target.vertices[:, 0]
    s_pos, s_neg = int(np.argmax(sx)), int(np.argmin(sx))
    t_pos, t_neg = int(np.argmax(tx)), int(np.argmin(tx))
    cfg = Config.intrinsic(affinity_weight=3.0)
    side = np.sign(tx)
    for pairs, sign in (
        ([[s_pos, t_pos], [s_neg, t_neg]], 1.0),
        ([[s_pos, t_neg], [s_neg, t_pos]], -1.0),
    ):
        out = transfer(
            source,
            target,
            key=jax.random.key(0),
            config=cfg,
            correspondences=np.array(pairs),
        )
        c = out.mesh.vertex_colors[:, 0]
        # red where the pairs say: the red channel's mean on that half beats the other half's clearly
        assert c[side == sign].mean() - c[side == -sign].mean() > 0.5


def test_scale_mismatch_is_an_error_unless_turned_off():
    v, f = icosphere(2)
    colors = np.tile(0.5 + 0.4 * v[:, :1], (1, 3))
    with pytest.raises(InputError, match="share units"):
        meshmatch((v, f), colors, (100 * v, f), key=jax.random.key(0))
    r = meshmatch(
        (v, f),
        colors,
        (2.5 * v, f),
        key=jax.random.key(0),
        config=Config(levels=1, steps=1, coarse_steps=2, hks_eigenpairs=8, max_scale_ratio=None),
    )
    assert r.colors.shape == (len(v), 3)


def test_y_up_models_match_as_their_z_up_copies():
    """Intrinsic features: ``up="y"`` on a model turned Y-up gives the match ``up="z"`` gives on the
    original, and a wrong up axis changes it."""
    source, sc, target, _, _, _ = _pair()
    turn = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])  # z -> y
    cfg = dict(levels=2, steps=3, coarse_steps=6, hks_eigenpairs=8)

    def match(rotation, up):
        return meshmatch(
            Mesh(source.vertices @ rotation.T, source.faces),
            sc,
            Mesh(target.vertices @ rotation.T, target.faces),
            key=jax.random.key(0),
            config=Config.intrinsic(up=up, **cfg),
        )

    z = match(np.eye(3), "z")
    y = match(turn, "y")
    assert np.mean(z.nnf == y.nnf) > 0.95
    wrong = match(turn, "z")
    assert np.mean(wrong.nnf == z.nnf) < 0.9  # the up axis matters: a wrong one changes the match


def test_the_aligned_default_needs_no_up_axis():
    """The default's features (whole normal, per-axis standardised positions) turn with the pair
    under a signed axis permutation, so a Y-up copy of both meshes matches as the Z-up original;
    the pose they assume is shared: turning only the target changes the match."""
    source, sc, target, _, _, _ = _pair()
    turn = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])  # z -> y
    cfg = Config(levels=2, steps=3, coarse_steps=6, hks_eigenpairs=8)
    z = meshmatch(source, sc, target, key=jax.random.key(0), config=cfg)
    turned_target = Mesh(target.vertices @ turn.T, target.faces)
    y = meshmatch(
        Mesh(source.vertices @ turn.T, source.faces),
        sc,
        turned_target,
        key=jax.random.key(0),
        config=cfg,
    )
    assert np.mean(z.nnf == y.nnf) > 0.95
    off = meshmatch(source, sc, turned_target, key=jax.random.key(0), config=cfg)
    assert np.mean(off.nnf == z.nnf) < 0.5


def _ellipsoids():
    """A source and a target ellipsoid, both symmetric under x -> -x (other tessellations), and
    source colours red on the +x half."""
    v, f = icosphere(3)
    source_v = v * np.array([1.6, 1.0, 0.8])
    q, _ = np.linalg.qr(np.random.default_rng(2).standard_normal((3, 3)))
    tv, tf = icosphere(3)
    tv = _unit(tv @ q.T) * np.array([1.6, 1.0, 0.8])
    red = 0.5 + 0.45 * np.tanh(3 * source_v[:, 0])
    colors = np.stack([red, 1 - red, 0.5 * np.ones_like(red)], axis=1)
    return Mesh(source_v, f, vertex_colors=colors), Mesh(tv, tf)


@pytest.mark.parametrize("seed", [0, 1])
def test_side_axis_resolves_the_mirror_ambiguity(seed):
    """HKS and n·up cannot tell the +x half of a mirror-symmetric ellipsoid from the -x half;
    the n·side feature along x can: the red half lands on +x, for every key (measured, keys 0-3:
    contrast +0.77 each; without ``side``: -0.76, 0.00, -0.76, +0.76)."""
    source, target = _ellipsoids()
    cfg = dict(levels=3, hks_eigenpairs=16)
    out = transfer(
        source, target, key=jax.random.key(seed), config=Config.intrinsic(side="x", **cfg)
    )
    c, side = out.mesh.vertex_colors[:, 0], np.sign(target.vertices[:, 0])
    assert c[side > 0].mean() - c[side < 0].mean() > 0.5


@pytest.mark.parametrize("seed", [0, 1])
def test_a_shared_pose_resolves_the_mirror_ambiguity(seed):
    """The aligned default's standardised positions tell the halves of the mirror-symmetric
    ellipsoid apart without a side axis (where the intrinsic features alone put the red on -x for
    keys 0 and 2, ``test_side_axis_resolves_the_mirror_ambiguity``)."""
    source, target = _ellipsoids()
    out = transfer(
        source, target, key=jax.random.key(seed), config=Config(levels=3, hks_eigenpairs=16)
    )
    c, side = out.mesh.vertex_colors[:, 0], np.sign(target.vertices[:, 0])
    assert c[side > 0].mean() - c[side < 0].mean() > 0.5


def test_side_is_refused_with_the_aligned_default():
    with pytest.raises(ConfigError, match="intrinsic"):
        Config(side="x")
    with pytest.raises(ConfigError, match="aligned=True"):
        Config.intrinsic(position_weight=8.0)
    assert Config.intrinsic(side="x").side_vector() == (1.0, 0.0, 0.0)


def _stretched_pair():
    """The bumpy sphere and the same surface stretched by (1.15, 1, 0.9), another tessellation, and
    the true match of every target vertex (the nearest source vertex of the known map)."""
    source, sc, bumpier, truth, _, tu = sphere_pair(3)
    k = np.array([1.15, 1.0, 0.9])
    target = Mesh(tu * sphere_bumps(tu, 0.15)[:, None] * k, bumpier.faces)
    truth_nnf = cKDTree(source.vertices).query(target.vertices / k)[1]
    return source, sc, target, truth, truth_nnf


def test_truth_survives_the_iterations_only_under_a_weak_shape_term():
    """Where the dB go between non-isometric shapes: started from the true matches, the finest
    level keeps them with colours alone and loses them to the intrinsic shape term (measured, 642 vertices,
    keys 0-1: truth 29.1 dB; shape weight 0: 27.8 dB; shape weight 3: 15.8-16.0 dB)."""
    source, sc, target, truth, gt = _stretched_pair()
    ceiling = psnr(sc[gt], truth)
    out = {}
    for w in (0.0, 3.0):
        cfg = Config.intrinsic(levels=1, coarse_steps=6, shape_weight=w)
        r = meshmatch(source, sc, target, key=jax.random.key(0), config=cfg, initial_nnf=gt)
        out[w] = psnr(np.clip(r.colors, 0, 1), truth)
    assert out[0.0] > ceiling - 2.5
    assert out[3.0] < ceiling - 8.0


def test_a_shared_pose_places_a_stretched_copy():
    """The aligned default's standardised positions undo the stretch the intrinsic shape features
    cannot see (measured, keys 0-1: 28.8 dB, the true matches 29.1 dB, ``Config.intrinsic()``
    13.4-14.4 dB)."""
    source, sc, target, truth, gt = _stretched_pair()
    ceiling = psnr(sc[gt], truth)
    key = jax.random.key(0)
    posed = meshmatch(source, sc, target, key=key, config=Config())
    intrinsic = meshmatch(source, sc, target, key=key, config=Config.intrinsic())
    posed_db = psnr(np.clip(posed.colors, 0, 1), truth)
    assert posed_db > ceiling - 2.0
    assert posed_db > psnr(np.clip(intrinsic.colors, 0, 1), truth) + 8.0


def test_the_papers_search_options_reach_the_floor():
    """Whole-star propagation candidates with the exact rotation search for every candidate (the
    paper's search) reach the floor on the bumpy-sphere pair with the pose-free features (where
    the search, not the positions, places the patches)."""
    source, sc, target, truth, _, _ = _pair()
    cfg = Config.intrinsic(star_candidates=True, exact_candidates=64)
    r = meshmatch(source, sc, target, key=jax.random.key(0), config=cfg)
    assert psnr(np.clip(r.colors, 0, 1), truth) > FLOOR_DB


def test_initial_nnf_is_checked():
    v, f = icosphere(2)
    colors = np.tile(0.5 + 0.4 * v[:, :1], (1, 3))
    with pytest.raises(InputError, match="initial_nnf"):
        meshmatch((v, f), colors, (v, f), key=jax.random.key(0), initial_nnf=np.zeros(3, np.int64))
    with pytest.raises(InputError, match="initial_nnf"):
        meshmatch(
            (v, f), colors, (v, f), key=jax.random.key(0), initial_nnf=np.full(len(v), len(v))
        )

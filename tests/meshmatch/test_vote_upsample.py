"""The fan-footprint vote (``Config(vote="fan")``) and offset upsampling (``Config(upsample="offset")``)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial import cKDTree

from jmeshtex import ConfigError, Mesh
from jmeshtex.data import icosphere
from jmeshtex.meshmatch import Config, _match, meshmatch
from jmeshtex.meshmatch._prepare import level_arrays, pad_axis
from jmeshtex.meshmatch._search import StepWeights, vote_step
from jmeshtex.meshmatch.core import pad_level_arrays, prepare_side
from jmeshtex.metrics import psnr


def _bumpy(level=3):
    v, f = icosphere(level)
    r = 1 + 0.2 * np.sin(3 * v[:, 0] + 1) * np.cos(2 * v[:, 1]) + 0.1 * np.sin(4 * v[:, 2] + 0.5)
    return v * r[:, None], f


def _field(x):
    """A smooth colour field of position (a few periods around the sphere)."""
    return np.stack(
        [
            0.5 + 0.4 * np.sin(3 * x[:, 0]) * np.cos(2 * x[:, 1]),
            0.5 + 0.4 * np.sin(2 * x[:, 2] + 1),
            0.5 + 0.3 * np.cos(2 * x[:, 0] + x[:, 1]),
        ],
        axis=1,
    )


def _arrays(cfg, v, f, colors):
    """Source = target = (v, f), one level: host arrays of both sides."""
    side = prepare_side((v, f), cfg)
    radii = cfg.radii(side.edge[0])
    ones = np.ones(len(v), bool)
    s_arr, _ = level_arrays(side, 0, radii, cfg, colors, ones, side.features, np.float64)
    t_arr, _ = level_arrays(
        side, 0, radii, cfg, np.zeros_like(colors), ones, side.features, np.float64
    )
    return s_arr, t_arr


def _weights(cfg):
    R = cfg.num_radii
    ring = np.exp(-((np.arange(1, R + 1) * cfg.fan_radius / R) ** 2) / (2 * cfg.vote_sigma**2))
    one = jnp.asarray(1.0, jnp.float64)
    return StepWeights(
        jnp.ones(R, jnp.float64) / R,
        one,
        one,
        one,
        jnp.asarray(0.25, jnp.float64),
        fan_weight=jnp.asarray(ring, jnp.float64),
    )


def _vote(cfg, t_arr, s_arr, nnf, rot, pin, vote="fan"):
    return np.asarray(
        vote_step(
            jax.tree.map(jnp.asarray, t_arr),
            jax.tree.map(jnp.asarray, s_arr),
            jnp.asarray(nnf),
            jnp.asarray(rot),
            _weights(cfg),
            jnp.asarray(pin),
            num_angles=cfg.num_angles,
            vote=vote,
        )
    )


def test_fan_vote_reproduces_a_smooth_field_on_a_self_transfer():
    v, f = _bumpy(3)
    colors = _field(v)
    cfg = Config(levels=1, vote="fan")
    s_arr, t_arr = _arrays(cfg, v, f, colors)
    V = len(v)
    ident = np.arange(V, dtype=np.int32)
    out = _vote(cfg, t_arr, s_arr, ident, np.zeros(V, np.int32), np.full(V, -1, np.int32))
    flat = np.broadcast_to(colors.mean(axis=0), colors.shape)
    # the true matches at the true rotation: the vote blurs the field a little (47.9 dB measured),
    # nowhere near the mean colour (14.3 dB)
    assert psnr(out, colors) > 44.0
    assert psnr(out, colors) > psnr(flat, colors) + 25.0
    # a wrong rotation (half a turn) moves every footprint's samples: far worse (26.2 dB measured)
    half = np.full(V, cfg.num_angles // 2, np.int32)
    assert (
        psnr(_vote(cfg, t_arr, s_arr, ident, half, np.full(V, -1, np.int32)), colors)
        < psnr(out, colors) - 10.0
    )
    # pins keep their pin's colour
    pin = np.full(V, -1, np.int32)
    pin[:5] = 7
    pinned = _vote(cfg, t_arr, s_arr, ident, np.zeros(V, np.int32), pin)
    np.testing.assert_allclose(pinned[:5], np.broadcast_to(colors[7], (5, 3)), rtol=0, atol=1e-12)


def test_fan_vote_ignores_padded_rows(rng):
    v, f = _bumpy(2)
    colors = rng.uniform(0, 1, (len(v), 3))
    cfg = Config(levels=1, vote="fan")
    s_arr, t_arr = _arrays(cfg, v, f, colors)
    V = len(v)
    nnf = rng.integers(0, V, V).astype(np.int32)
    rot = rng.integers(0, cfg.num_angles, V).astype(np.int32)
    pin = np.full(V, -1, np.int32)
    pin[3] = 11
    base = _vote(cfg, t_arr, s_arr, nnf, rot, pin)
    Vp, K = V + 37, t_arr.nb_index.shape[1] + 2
    s_pad = pad_level_arrays(
        s_arr, num_vertices=Vp, ring=K, smooth_ring=s_arr.sm_index.shape[1] + 1
    )
    t_pad = pad_level_arrays(
        t_arr, num_vertices=Vp, ring=K, smooth_ring=t_arr.sm_index.shape[1] + 1
    )
    # padded rows point at real source vertices with arbitrary rotations: they must vote nothing
    nnf_p = pad_axis(nnf, 0, Vp, 5)
    rot_p = pad_axis(rot, 0, Vp, 4)
    padded = _vote(cfg, t_pad, s_pad, nnf_p, rot_p, pad_axis(pin, 0, Vp, -1))
    np.testing.assert_allclose(padded[:V], base, rtol=1e-12, atol=1e-12)
    # and the vote is not trivially the own colour: the footprints of the neighbours count
    assert np.abs(base - colors[nnf]).max() > 0.05


def _sphere_pair():
    """Bumpy sphere → its rotated tessellation stretched (1.1, 1, 0.92); truth through the map."""
    v, f = _bumpy(3)
    q, _ = np.linalg.qr(np.random.default_rng(1).standard_normal((3, 3)))
    tv, tf = icosphere(3)
    tu = tv @ q.T
    r = 1 + 0.2 * np.sin(3 * tu[:, 0] + 1) * np.cos(2 * tu[:, 1]) + 0.1 * np.sin(4 * tu[:, 2] + 0.5)
    on_source = tu * r[:, None]
    stretch = np.array([1.1, 1.0, 0.92])
    return (
        Mesh(v, f),
        _field(v),
        Mesh(on_source * stretch, tf),
        _field(on_source),
        lambda x: x / stretch,
    )


def test_offset_upsampling_places_fine_vertices_closer_than_copying(monkeypatch):
    source, sc, target, truth, to_source = _sphere_pair()
    placed = []
    original = _match._offset_upsample

    def recording(src, tgt, level, m, prev_m, nnf_c, rot_c, valid_m, A, cache):
        s, rot = original(src, tgt, level, m, prev_m, nnf_c, rot_c, valid_m, A, cache)
        parent = np.asarray(tgt.hierarchy.pooling[level].parent)
        copy = src.inverse[m][src.hierarchy.vertex_index[prev_m][nnf_c[parent]]]
        xs, goal = src.hierarchy.vertices[m], to_source(tgt.hierarchy.vertices[level])
        placed.append(
            (
                np.median(np.linalg.norm(xs[s] - goal, axis=1)),
                np.median(np.linalg.norm(xs[copy] - goal, axis=1)),
            )
        )
        return s, rot

    monkeypatch.setattr(_match, "_offset_upsample", recording)
    cfg = Config(upsample="offset", min_vertices=160)
    r = meshmatch(source, sc, target, key=jax.random.key(0), config=cfg)
    assert placed, "the offset upsampling never ran"
    offset_err, copy_err = placed[-1]  # the finest level (measured 0.088 against 0.114)
    assert offset_err < 0.9 * copy_err
    # the transfer reaches within 1 dB of the nearest-3D copy through the known map (34.77 dB
    # measured, ceiling 34.93 dB), far above the mean colour (14.3 dB)
    ceiling = psnr(sc[cKDTree(source.vertices).query(to_source(target.vertices))[1]], truth)
    got = psnr(np.clip(r.colors, 0, 1), truth)
    assert got > ceiling - 1.0
    assert got > psnr(np.broadcast_to(sc.mean(axis=0), truth.shape), truth) + 15.0


@pytest.mark.parametrize(
    ("field", "value", "words"),
    [
        ("vote", "disc", "'ring' or 'fan'"),
        ("upsample", "nearest", "'copy' or 'offset'"),
        ("vote", None, "'ring' or 'fan'"),
    ],
)
def test_bad_vote_and_upsample_values_raise(field, value, words):
    with pytest.raises(ConfigError, match=words):
        Config(**{field: value})

"""MeshMatch's bounds on work: the fan radius rule, scale checks, fans that would wrap a mesh."""

from __future__ import annotations

import time

import jax
import numpy as np
import pytest

from jmeshtex import ConfigError, EmptyMeshError, InputError, MeshScaleError
from jmeshtex.data import icosphere, torus
from jmeshtex.meshmatch import Config, meshmatch

_TINY = dict(levels=1, steps=1, coarse_steps=2, hks_eigenpairs=8)


def _source():
    v, f = icosphere(2)
    return (v, f), 0.5 + 0.4 * np.sin(5 * v)


def test_fan_radius_has_a_range():
    assert Config(fan_radius=64).fan_radius == 64
    for bad in (1e9, 64.5, 0.0, -1.0, float("nan"), float("inf"), "4"):
        with pytest.raises(ConfigError, match=r"fan_radius must be a number in \(0, 64\]"):
            Config(fan_radius=bad)
    with pytest.raises(ConfigError, match="fan_radius"):
        Config.from_dict({"fan_radius": 1e9})


def test_a_million_fold_target_with_the_ratio_check_off_is_refused_at_once():
    """Fans of 4 target edges would walk ~1e6 source edges per trace (minutes); refused first."""
    source, colors = _source()
    v, f = torus(12, 6)
    start = time.perf_counter()
    with pytest.raises(InputError, match="rescale one mesh to the other's units"):
        meshmatch(
            source,
            colors,
            (v * 1e6, f),
            key=jax.random.key(0),
            config=Config(max_scale_ratio=None, **_TINY),
        )
    assert time.perf_counter() - start < 5.0


def test_fans_that_would_cross_too_many_edges_of_the_finer_mesh_are_refused_at_once():
    """A fine small source and a coarse target 4x its size (edges 31x longer): the fans wrap the
    source less than 8 times, but each trace would cross ~120 source edges; refused first."""
    v, f = icosphere(4)
    tv, tf = icosphere(1)
    start = time.perf_counter()
    with pytest.raises(InputError, match="would cross .* mean edges of the finer mesh"):
        meshmatch(
            (v, f),
            0.5 + 0.4 * np.sin(5 * v),
            (4.0 * tv, tf),
            key=jax.random.key(0),
            config=Config(max_scale_ratio=None, **_TINY),
        )
    assert time.perf_counter() - start < 5.0


@pytest.mark.parametrize(
    ("scale", "offset", "error"),
    [(1e30, 0.0, MeshScaleError), (1e12, 0.0, MeshScaleError), (1.0, 1e8, MeshScaleError)],
)
def test_extreme_meshes_are_refused_on_either_side(scale, offset, error):
    source, colors = _source()
    v, f = source
    far = (v * scale + offset, f)
    config = Config(max_scale_ratio=None, **_TINY)
    with pytest.raises(error, match="source: "):
        meshmatch(far, colors, source, key=jax.random.key(0), config=config)
    with pytest.raises(error, match="target: "):
        meshmatch(source, colors, far, key=jax.random.key(0), config=config)


def test_an_empty_target_is_a_mesh_error():
    source, colors = _source()
    with pytest.raises(EmptyMeshError):
        meshmatch(source, colors, (np.zeros((0, 3)), np.zeros((0, 3), int)), key=jax.random.key(0))


def test_small_meshes_in_range_still_transfer():
    """No UV unwrapper in MeshMatch: a sphere with 1e-4 edges (a 2 mm scan in metres) runs."""
    (v, f), colors = _source()
    small = (v * 3e-4, f)
    r = meshmatch(small, colors, small, key=jax.random.key(0), config=Config(**_TINY))
    assert np.isfinite(r.colors).all() and r.colors.shape == colors.shape

"""Geodesic fans, pre-filter, rotation search through the angular DFT, shape features."""

from __future__ import annotations

import itertools

import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import ConfigError, InputError
from jmeshtex.data import grid, icosphere
from jmeshtex.meshmatch import Config
from jmeshtex.meshmatch.core import (
    correspondence_affinities,
    fan_descriptor,
    fan_spectrum,
    geodesic_fans,
    rotation_distances,
    sample_fans,
)


def test_fan_samples_lie_on_circles_of_a_flat_grid():
    v, f = grid(10)
    fans = geodesic_fans((v, f), radii=[0.1, 0.2, 0.3], num_angles=8)
    centre = 60  # (0.6, 0.5): every ring stays inside the unit square
    xy = sample_fans(fans, v[:, :2])[centre]  # [R, A, 2]
    d = xy - v[centre, :2]
    np.testing.assert_allclose(
        np.linalg.norm(d, axis=-1), np.array([[0.1], [0.2], [0.3]]) * np.ones((1, 8)), atol=1e-12
    )
    angles = np.angle(d[..., 0] + 1j * d[..., 1])
    step = np.angle(np.exp(1j * np.diff(angles, axis=1)))
    np.testing.assert_allclose(step, 2 * np.pi / 8, atol=1e-12)  # counter-clockwise, evenly spaced
    assert not fans.stopped[centre].any()
    assert fans.stopped[0].any()  # a corner vertex: most directions leave the sheet


@pytest.mark.parametrize("k", [1, 5])
def test_turning_the_reference_by_whole_steps_rolls_the_fan(k, rng):
    v, f = icosphere(2)
    x = jnp.asarray(rng.standard_normal((len(v), 2)))
    A = 8
    ref = np.exp(1j * rng.uniform(0, 2 * np.pi, len(v)))
    a = fan_descriptor((v, f), x, radii=[0.15, 0.3], num_angles=A, reference=ref)
    b = fan_descriptor(
        (v, f), x, radii=[0.15, 0.3], num_angles=A, reference=ref * np.exp(2j * np.pi * k / A)
    )
    np.testing.assert_allclose(np.asarray(b), np.roll(np.asarray(a), -k, axis=2), atol=1e-9)


def test_rotation_distances_match_a_loop(rng):
    A, R, C = 7, 2, 3
    t = rng.standard_normal((4, R, A, C))
    s = rng.standard_normal((4, R, A, C))
    w = np.array([0.3, 0.7])
    d = np.asarray(
        rotation_distances(
            *fan_spectrum(jnp.asarray(t), jnp.asarray(w)),
            *fan_spectrum(jnp.asarray(s), jnp.asarray(w)),
            A,
        )
    )
    ref = np.zeros((4, A))
    for n, k, r, a, c in itertools.product(range(4), range(A), range(R), range(A), range(C)):
        ref[n, k] += w[r] * (t[n, r, a, c] - s[n, r, (a + k) % A, c]) ** 2
    np.testing.assert_allclose(d, ref, rtol=1e-10, atol=1e-10)


def test_rotation_search_finds_the_shift(rng):
    """Fans of a target rotated in its tangent frames by k_p steps are matched at rotation k_p."""
    v, f = icosphere(2)
    x = jnp.asarray(rng.standard_normal((len(v), 3)))
    A = 12
    k = rng.integers(0, A, len(v))
    base = np.exp(1j * rng.uniform(0, 2 * np.pi, len(v)))  # generic: no trace runs along an edge
    src = fan_descriptor((v, f), x, radii=[0.15, 0.3], num_angles=A, reference=base)
    tgt = fan_descriptor(
        (v, f), x, radii=[0.15, 0.3], num_angles=A, reference=base * np.exp(2j * np.pi * k / A)
    )
    w = jnp.ones(2)
    d = rotation_distances(*fan_spectrum(tgt, w), *fan_spectrum(src, w), A)
    np.testing.assert_array_equal(np.asarray(jnp.argmin(d, axis=1)), k)
    assert float(jnp.min(d, axis=1).max()) < 1e-9


def test_affinities_agree_for_identical_meshes_and_differ_elsewhere():
    v, f = icosphere(2)
    pairs = np.array([[0, 0], [20, 20], [90, 90]])
    a, b = correspondence_affinities((v, f), (v, f), pairs)
    np.testing.assert_allclose(a, b, atol=1e-8)
    assert a.shape == (len(v), 3) and np.all((a >= 0) & (a <= 1 / np.sqrt(3) + 1e-12))
    assert np.allclose(a[0, 0], 1 / np.sqrt(3))  # a correspondence point has affinity 1 to itself


def test_bad_inputs_raise_typed_errors():
    v, f = grid(3)
    with pytest.raises(InputError, match="radii"):
        geodesic_fans((v, f), radii=[-1.0])
    with pytest.raises(InputError, match="reference"):
        geodesic_fans((v, f), radii=[0.1], reference=np.zeros(len(v)))
    with pytest.raises(InputError, match="correspondences"):
        correspondence_affinities((v, f), (v, f), np.array([0, 1]))
    with pytest.raises(InputError, match="mesh must be a jmeshtex.Mesh"):
        geodesic_fans(v, radii=[0.1])
    with pytest.raises(ConfigError, match="num_angles"):
        Config(num_angles=1)
    with pytest.raises(ConfigError, match="up"):
        Config(up=(0.0, 0.0, 0.0))
    with pytest.raises(ConfigError, match="constant"):
        Config(color_weight=0.0, shape_weight=0.0)
    with pytest.raises(ConfigError, match="unknown fields \\['iterations'\\]"):
        Config.from_dict({"iterations": 3})  # renamed: steps


def test_host_smoothing_matches_the_jax_smoother(rng):
    """The HKS copy-down smooths hundreds of steps on the host (sparse); same result as `smooth`."""
    from jmeshtex.meshmatch._fans import _smooth_host
    from jmeshtex.meshmatch.core import smooth, smoother

    v, f = icosphere(2)
    x = rng.standard_normal((len(v), 3))
    sm = smoother(f, len(v))
    np.testing.assert_allclose(
        _smooth_host(x, sm, 9), np.asarray(smooth(jnp.asarray(x), sm, 9)), atol=1e-13
    )
    np.testing.assert_array_equal(_smooth_host(x, sm, 0), x)

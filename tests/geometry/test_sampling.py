"""Tests of area-uniform surface sampling and barycentric interpolation."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from jmeshtex import FaceIndexError, InputError, NonTriangleFaceError
from jmeshtex.data import grid, icosphere, single_triangle
from jmeshtex.geometry import barycentric_interpolate, sample_surface

# Statistical tests run with a fresh seed each time; a correct sampler fails one with probability
# 1e-6, a sampler with the wrong distribution fails with p-values far below that (checked below).
ALPHA = 1e-6


def _uneven_mesh():
    """Four triangles whose areas are 1 : 2 : 3 : 4 (and one of zero area)."""
    v = np.array(
        [
            [0.0, 0, 0],
            [1, 0, 0],
            [0, 2, 0],
            [2, 0, 1],
            [0, 3, 1],
            [4, 0, 2],
            [0, 2, 2],
            [0, 0, 1],
            [0, 0, 2],
            [0, 0, 3],
            [1, 1, 3],
            [2, 2, 3],
        ]
    )
    f = np.array([[0, 1, 2], [7, 3, 4], [8, 5, 6], [0, 2, 6], [9, 10, 11]])
    return v, f


def _areas(v, f):
    t = v[f]
    return 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)


def test_faces_are_drawn_in_proportion_to_area(seed):
    v, f = _uneven_mesh()
    area = _areas(v, f)
    assert area[4] == 0.0
    s = sample_surface(v, f, 40_000, key=jax.random.key(seed))
    counts = np.bincount(s.face, minlength=len(f))
    assert counts[4] == 0  # a zero-area face is never drawn
    expected = 40_000 * area[:4] / area.sum()
    assert stats.chisquare(counts[:4], expected).pvalue > ALPHA
    # the test has power: uniform face choice is rejected outright
    assert stats.chisquare(np.full(4, 10_000), expected).pvalue < 1e-100


def test_points_are_uniform_inside_each_face(seed):
    v, f = single_triangle()
    s = sample_surface(v, f, 20_000, key=jax.random.key(seed))
    # each barycentric coordinate of a uniform point in a triangle is Beta(1, 2): CDF 1 − (1 − t)²
    for k in range(3):
        assert stats.kstest(s.bary[:, k], lambda t: 1 - (1 - np.clip(t, 0, 1)) ** 2).pvalue > ALPHA
    # the four midpoint sub-triangles receive a quarter each
    b = s.bary
    quarter = np.where(b[:, 0] > 0.5, 0, np.where(b[:, 1] > 0.5, 1, np.where(b[:, 2] > 0.5, 2, 3)))
    assert stats.chisquare(np.bincount(quarter, minlength=4)).pvalue > ALPHA
    # the naive "normalised uniform weights" sampler is rejected by the same KS test
    rng = np.random.default_rng(seed)
    naive = rng.random((20_000, 3))
    naive /= naive.sum(1, keepdims=True)
    assert stats.kstest(naive[:, 0], lambda t: 1 - (1 - np.clip(t, 0, 1)) ** 2).pvalue < 1e-10


def test_points_lie_on_their_faces_and_on_the_sphere(seed):
    v, f = icosphere(1)
    s = sample_surface(v, f, 500, key=jax.random.key(seed))
    assert s.face.dtype == np.int32 and s.bary.dtype == np.float64
    assert s.bary.min() >= 0.0
    np.testing.assert_allclose(s.bary.sum(1), 1.0, atol=1e-15)
    np.testing.assert_allclose(s.point, np.einsum("nk,nkd->nd", s.bary, v[f[s.face]]), atol=1e-15)
    assert np.all(np.linalg.norm(s.point, axis=1) <= 1.0 + 1e-15)


def test_seed_and_rng_are_deterministic():
    v, f = grid(3)
    a = sample_surface(v, f, 50, key=jax.random.key(7))
    b = sample_surface(v, f, 50, key=jax.random.key(7))
    c = sample_surface(v, f, 50, key=jax.random.key(8))
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a.point, c.point)
    rng = np.random.default_rng(7)
    d = sample_surface(v, f, 50, rng=rng)
    np.testing.assert_array_equal(
        d.point, sample_surface(v, f, 50, rng=np.random.default_rng(7)).point
    )
    e = sample_surface(v, f, 50, rng=rng)  # the generator advanced
    assert not np.array_equal(e.point, d.point)
    assert sample_surface(v, f, 0, key=jax.random.key(1)).point.shape == (0, 3)


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        (dict(), InputError, "exactly one of key"),
        (
            dict(key=jax.random.key(1), rng=np.random.default_rng(1)),
            InputError,
            "exactly one of key",
        ),
        (dict(key=1), InputError, "must be a JAX PRNG key"),
        (dict(rng=1), InputError, "Generator"),
        (dict(key=jax.random.key(1), n=-1), InputError, "non-negative"),
        (dict(key=jax.random.key(1), faces=np.array([[0, 1, 9]])), FaceIndexError, "out of range"),
        (
            dict(key=jax.random.key(1), faces=np.array([[0, 1, 2, 3]])),
            NonTriangleFaceError,
            "triangles",
        ),
        (dict(key=jax.random.key(1), vertices=np.zeros((4, 3))), InputError, "total area"),
    ],
)
@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_sample_surface_rejects_bad_input(kwargs, error, match):
    args = dict(vertices=np.eye(4, 3), faces=np.array([[0, 1, 2]]), n=3)
    for name in ("vertices", "faces", "n"):
        if name in kwargs:
            args[name] = kwargs.pop(name)
    with pytest.raises(error, match=match):
        sample_surface(args["vertices"], args["faces"], args["n"], **kwargs)


# ------------------------------------------------------------------------------------------------
# barycentric interpolation


def test_interpolation_is_exact_for_affine_functions(rng):
    v, f = icosphere(1)
    A, c = rng.standard_normal((3, 4)), rng.standard_normal(4)
    values = v @ A + c
    s = sample_surface(v, f, 200, rng=rng)
    np.testing.assert_allclose(
        barycentric_interpolate(values, f, s.face, s.bary), s.point @ A + c, atol=1e-13
    )
    # at a corner it returns the vertex value; extra value axes and leading sample axes pass through
    vals = rng.standard_normal((len(v), 2, 3)) + 1j * rng.standard_normal((len(v), 2, 3))
    out = barycentric_interpolate(
        vals, f, np.array([[3, 5]]), np.array([[[0, 1.0, 0], [0, 0, 1.0]]])
    )
    assert out.shape == (1, 2, 2, 3) and out.dtype == np.complex128
    np.testing.assert_array_equal(out[0, 0], vals[f[3, 1]])
    np.testing.assert_array_equal(out[0, 1], vals[f[5, 2]])


def test_interpolation_matches_a_loop_reference(rng):
    v, f = grid(3)
    values = rng.standard_normal((len(v), 5))
    face = rng.integers(0, len(f), 30)
    bary = rng.dirichlet([1, 1, 1], 30)
    expected = np.array(
        [sum(bary[i, k] * values[f[face[i], k]] for k in range(3)) for i in range(30)]
    )
    np.testing.assert_allclose(barycentric_interpolate(values, f, face, bary), expected, atol=1e-14)


def test_interpolation_in_jax_jit_grad_and_dtype(rng):
    v, f = grid(2)
    values = jnp.asarray(rng.standard_normal((len(v), 3)), dtype=jnp.float32)
    face = jnp.asarray([0, 3, 5])
    bary = jnp.asarray(rng.dirichlet([1, 1, 1], 3))  # float64 weights, float32 values

    fn = jax.jit(barycentric_interpolate)
    out = fn(values, jnp.asarray(f), face, bary)
    assert isinstance(out, jax.Array) and out.dtype == jnp.float32
    ref = barycentric_interpolate(
        np.asarray(values, np.float64), f, np.asarray(face), np.asarray(bary)
    )
    np.testing.assert_allclose(np.asarray(out), ref, rtol=1e-6, atol=1e-6)
    # the gradient of the sum w.r.t. the values is the total barycentric weight on each vertex
    grad = jax.grad(lambda x: barycentric_interpolate(x, f, face, bary).sum())(values)
    weight = np.zeros(len(v))
    np.add.at(weight, f[np.asarray(face)].ravel(), np.asarray(bary).ravel())
    np.testing.assert_allclose(np.asarray(grad), np.repeat(weight[:, None], 3, 1), rtol=1e-6)
    assert fn._cache_size() == 1
    fn(values + 1, jnp.asarray(f), face, bary)
    assert fn._cache_size() == 1  # no recompilation for the same shapes


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_interpolation_rejects_bad_input():
    v, f = grid(2)
    with pytest.raises(InputError, match="bary must have shape"):
        barycentric_interpolate(v, f, np.array([0, 1]), np.ones((3, 3)) / 3)
    with pytest.raises(InputError, match="face indices"):
        barycentric_interpolate(v, f, np.array([99]), np.ones((1, 3)) / 3)
    with pytest.raises(InputError, match="faces must have shape"):
        barycentric_interpolate(v, f[:, :2], np.array([0]), np.ones((1, 3)) / 3)

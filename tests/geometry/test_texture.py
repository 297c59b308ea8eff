"""Tests of UV lookup and texture sampling: exact small cases, a loop reference, JAX paths."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import InputError
from jmeshtex.geometry import sample_texture, uv_at

# 2×2 texture, row 0 at the top (v = 1):   top row: a=1, b=2; bottom row: c=4, d=8
TEX = np.array([[[1.0], [2.0]], [[4.0], [8.0]]])


def _reference(texture, uv, mode, wrap):
    """Slow per-sample reference written from the convention, not from the implementation."""
    H, W = texture.shape[:2]

    def texel(j, i):
        if wrap == "clamp":
            j, i = min(max(j, 0), H - 1), min(max(i, 0), W - 1)
        else:
            j, i = j % H, i % W
        return texture[j, i]

    out = []
    for u, v in uv:
        if mode == "nearest":
            out.append(texel(int(np.floor((1 - v) * H)), int(np.floor(u * W))))
            continue
        x, y = u * W - 0.5, (1 - v) * H - 0.5
        i, j = int(np.floor(x)), int(np.floor(y))
        a, b = x - i, y - j
        out.append(
            (1 - a) * (1 - b) * texel(j, i)
            + a * (1 - b) * texel(j, i + 1)
            + (1 - a) * b * texel(j + 1, i)
            + a * b * texel(j + 1, i + 1)
        )
    return np.array(out)


@pytest.mark.parametrize(
    "uv, expected",
    [
        ((0.25, 0.75), 1.0),  # texel centres: top-left
        ((0.75, 0.75), 2.0),  # top-right
        ((0.25, 0.25), 4.0),  # bottom-left
        ((0.75, 0.25), 8.0),  # bottom-right
        ((0.5, 0.5), 3.75),  # image centre: mean of the four
        ((0.5, 0.75), 1.5),  # between the top centres
        ((0.25, 0.5), 2.5),  # between the left centres
        ((0.0, 1.0), 1.0),  # image corners clamp to the corner texels
        ((1.0, 0.0), 8.0),
        ((0.5, 1.0), 1.5),  # top edge midpoint: top row only
        ((0.0, 0.5), 2.5),  # left edge midpoint: left column only
        ((-3.0, 7.0), 1.0),  # far outside: clamped
        ((0.375, 0.625), 0.5625 * 1 + 0.1875 * 2 + 0.1875 * 4 + 0.0625 * 8),
    ],
)
def test_bilinear_clamp_on_a_2x2_texture(uv, expected):
    out = sample_texture(TEX, np.array([uv]))
    assert out.shape == (1, 1)
    np.testing.assert_allclose(out[0, 0], expected, atol=1e-15)


@pytest.mark.parametrize(
    "uv, expected",
    [
        ((0.0, 0.5), (1 + 2 + 4 + 8) / 4),  # the left edge sits half way between columns 1 and 0
        ((0.0, 0.75), 1.5),
        ((0.5, 1.0), (1 + 4) / 2 * 0.5 + (2 + 8) / 2 * 0.5),  # top edge: between rows 1 and 0
        ((1.25, 0.75), 1.0),  # tiles: u + 1 is the same point
        ((0.25, -0.75), 4.0),  # v − 1: bottom-left again
    ],
)
def test_bilinear_repeat_on_a_2x2_texture(uv, expected):
    np.testing.assert_allclose(
        sample_texture(TEX, np.array([uv]), wrap="repeat")[0, 0], expected, atol=1e-15
    )


@pytest.mark.parametrize(
    "uv, clamp, repeat",
    [
        ((0.1, 0.9), 1.0, 1.0),
        ((0.9, 0.9), 2.0, 2.0),
        ((0.1, 0.1), 4.0, 4.0),
        ((0.6, 0.4), 8.0, 8.0),
        ((0.5, 0.5), 8.0, 8.0),  # the centre lies on the corner of texel (1, 1)
        ((1.0, 0.0), 8.0, 1.0),  # u = 1 is column 2: clamped to 1, or wrapped to 0 (row 2 → 0)
        ((-0.2, 0.9), 1.0, 2.0),
    ],
)
def test_nearest_on_a_2x2_texture(uv, clamp, repeat):
    assert sample_texture(TEX, np.array([uv]), mode="nearest")[0, 0] == clamp
    assert sample_texture(TEX, np.array([uv]), mode="nearest", wrap="repeat")[0, 0] == repeat


@pytest.mark.parametrize("mode", ["bilinear", "nearest"])
@pytest.mark.parametrize("wrap", ["clamp", "repeat"])
def test_matches_the_loop_reference(rng, mode, wrap):
    texture = rng.random((5, 7, 3))
    uv = rng.uniform(-0.5, 1.5, (300, 2))
    np.testing.assert_allclose(
        sample_texture(texture, uv, mode=mode, wrap=wrap),
        _reference(texture, uv, mode, wrap),
        atol=1e-14,
    )


def test_bilinear_reproduces_linear_ramps_exactly(rng):
    H, W = 6, 9
    j, i = np.meshgrid(np.arange(H), np.arange(W), indexing="ij")
    texture = (0.3 * i - 0.7 * j + 2.0)[..., None]
    u = rng.uniform(0.5 / W, 1 - 0.5 / W, 200)
    v = rng.uniform(0.5 / H, 1 - 0.5 / H, 200)
    x, y = u * W - 0.5, (1 - v) * H - 0.5
    out = sample_texture(texture, np.stack([u, v], 1))[:, 0]
    np.testing.assert_allclose(out, 0.3 * x - 0.7 * y + 2.0, atol=1e-12)


def test_shapes_and_dtypes():
    tex = np.zeros((3, 4, 2, 5), np.float32)
    uv = np.full((6, 7, 2), 0.5)
    assert sample_texture(tex, uv).shape == (6, 7, 2, 5)
    assert sample_texture(tex, uv).dtype == np.float32
    gray = np.arange(12, dtype=np.uint8).reshape(3, 4)
    assert sample_texture(gray, uv, mode="nearest").dtype == np.uint8
    assert sample_texture(gray, uv).dtype == np.float64  # bilinear on integers: uv's dtype
    assert sample_texture(gray, np.array([[0.125, 1 - 1 / 6]]))[0] == 0.0


def test_jax_path_jit_grad_and_no_recompile(rng):
    texture = jnp.asarray(rng.random((4, 5, 3)), dtype=jnp.float32)
    uv = jnp.asarray(rng.uniform(-0.2, 1.2, (50, 2)))
    fn = jax.jit(sample_texture, static_argnames=("mode", "wrap"))
    for mode in ("bilinear", "nearest"):
        for wrap in ("clamp", "repeat"):
            out = fn(texture, uv, mode=mode, wrap=wrap)
            assert isinstance(out, jax.Array) and out.dtype == jnp.float32
            ref = sample_texture(
                np.asarray(texture, np.float64), np.asarray(uv), mode=mode, wrap=wrap
            )
            np.testing.assert_allclose(np.asarray(out), ref, rtol=1e-5, atol=1e-6)
    size = fn._cache_size()
    fn(texture * 2, uv + 0.1, mode="bilinear", wrap="clamp")
    assert fn._cache_size() == size
    # bilinear weights form a partition of unity: d(sum of samples)/d(texture) sums to N per channel
    grad = jax.grad(lambda t: sample_texture(t, uv).sum())(texture)
    np.testing.assert_allclose(np.asarray(grad).sum(axis=(0, 1)), 50.0, rtol=1e-5)
    assert np.asarray(grad).min() >= 0.0


def test_uv_at():
    uv = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], [[0.5, 0.5], [0.5, 1.0], [1.0, 1.0]]])
    face = np.array([0, 1, 1, 0])
    bary = np.array([[1.0, 0, 0], [0, 0, 1.0], [1 / 3, 1 / 3, 1 / 3], [0.2, 0.3, 0.5]])
    np.testing.assert_allclose(
        uv_at(uv, face, bary), [[0.0, 0.0], [1.0, 1.0], [2 / 3, 5 / 6], [0.3, 0.5]], atol=1e-15
    )
    out = uv_at(jnp.asarray(uv, dtype=jnp.float32), jnp.asarray(face), jnp.asarray(bary))
    assert isinstance(out, jax.Array) and out.dtype == jnp.float32
    assert uv_at(uv, face.reshape(2, 2), bary.reshape(2, 2, 3)).shape == (2, 2, 2)


def test_uv_at_then_sample_texture_on_a_mesh(rng):
    """A quad [0,1]² whose UVs equal its xy coordinates reads the texel under each point."""
    from jmeshtex.data import grid
    from jmeshtex.geometry import sample_surface

    v, f = grid(2)
    uv = v[f][..., :2]
    texture = rng.random((4, 4, 3))
    s = sample_surface(v, f, 100, rng=rng)
    np.testing.assert_allclose(
        sample_texture(texture, uv_at(uv, s.face, s.bary), mode="nearest"),
        _reference(texture, s.point[:, :2], "nearest", "clamp"),
        atol=0,
    )


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: sample_texture(TEX, np.array([[0.5, 0.5]]), mode="cubic"), "mode must be one of"),
        (lambda: sample_texture(TEX, np.array([[0.5, 0.5]]), wrap="mirror"), "wrap must be one of"),
        (
            lambda: sample_texture(TEX, np.array([[0.5, 0.5, 0.5]])),
            r"uv must have shape \[..., 2\]",
        ),
        (lambda: sample_texture(np.zeros(4), np.array([[0.5, 0.5]])), "texture must have shape"),
        (lambda: sample_texture(TEX, np.array([[np.nan, 0.5]])), "NaN"),
        (lambda: sample_texture(TEX, np.array([[0, 1]])), "floating point"),
        (lambda: uv_at(np.zeros((2, 3)), np.array([0]), np.ones((1, 3))), r"\[F, 3, 2\]"),
        (lambda: uv_at(np.zeros((2, 3, 2)), np.array([5]), np.ones((1, 3))), "face indices"),
        (
            lambda: uv_at(np.zeros((2, 3, 2)), np.array([0]), np.ones((2, 3))),
            "bary must have shape",
        ),
    ],
)
@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_bad_input_raises(call, match):
    with pytest.raises(InputError, match=match):
        call()


def test_the_renderer_s_lookup_is_the_geometry_lookup_at_level_zero():
    # one bilinear kernel: render.sample_mipmapped without a mip level equals geometry's, clamped
    from jmeshtex import render

    rng = np.random.default_rng(3)
    texture = rng.random((7, 5, 3))
    uv = rng.uniform(0.0, 0.999, (200, 2))
    np.testing.assert_allclose(
        np.asarray(render.sample_mipmapped(texture, uv)), sample_texture(texture, uv), atol=1e-15
    )


def test_bilinear_taps_take_one_image_size_per_point():
    from jmeshtex.geometry import bilinear_blend, bilinear_taps

    u, v = np.array([0.5, 0.5]), np.array([0.5, 0.5])
    (r0, r1, c0, c1), (a, b) = bilinear_taps(u, v, np.array([2, 4]), np.array([2, 4]))
    # x = u·W − 0.5 = 0.5 and 1.5: texels (0, 1) of the 2-wide image, (1, 2) of the 4-wide one
    assert [r0.tolist(), r1.tolist(), c0.tolist(), c1.tolist()] == [[0, 1], [1, 2]] * 2
    assert a.tolist() == b.tolist() == [0.5, 0.5]
    assert bilinear_blend(0.0, 1.0, 2.0, 3.0, 0.25, 0.0) == 0.25

"""Texel convolution and grouped pooling: the flat-image oracle (lax.conv / reduce_window), loop
references for bilinear taps, padding, batching, dtypes and gradients."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jmeshtex import InputError
from jmeshtex.ops import (
    PoolGroups,
    TexelNeighborhood,
    grouped_pool,
    image_pool_groups,
    image_texel_neighborhood,
    texel_conv,
)

_conv = jax.jit(texel_conv)
_pool = jax.jit(grouped_pool, static_argnames=("mode",))


def _lax_conv(img, kernel, bias):
    """The 2D CNN layer texel_conv must reproduce: HWIO kernel, SAME zero padding."""
    y = jax.lax.conv_general_dilated(
        img[None], kernel, (1, 1), "SAME", dimension_numbers=("NHWC", "HWIO", "NHWC")
    )
    return y[0] + bias


def _random_taps(rng, N, J=4):
    index = rng.integers(0, N, size=(N, 9, J)).astype(np.int32)
    weight = rng.random((N, 9, J))
    weight /= weight.sum(-1, keepdims=True)
    weight[rng.random((N, 9)) < 0.1] = 0  # some taps fall off the surface
    return TexelNeighborhood(index, weight, np.ones(N, bool))


def _conv_ref(x, taps, kernel, bias):
    N, D = x.shape[0], kernel.shape[-1]
    out = np.zeros((N, D))
    for n in range(N):
        for t in range(9):
            dy, dx = divmod(t, 3)
            s = sum(
                taps.weight[n, t, j] * x[taps.index[n, t, j]] for j in range(taps.index.shape[2])
            )
            out[n] += s @ kernel[dy, dx]
        out[n] = (out[n] + bias) * taps.texel_mask[n]
    return out


# ----------------------------------------------------------------------------- the image oracle


def test_equals_lax_conv_exactly_on_integers(rng):
    H, W, C, D = 5, 7, 3, 4
    img = rng.integers(-8, 9, size=(H, W, C)).astype(np.float64)
    kernel = rng.integers(-8, 9, size=(3, 3, C, D)).astype(np.float64)
    bias = rng.integers(-8, 9, size=D).astype(np.float64)
    taps = image_texel_neighborhood(H, W)
    got = _conv(jnp.asarray(img.reshape(H * W, C)), taps, jnp.asarray(kernel), jnp.asarray(bias))
    want = _lax_conv(jnp.asarray(img), jnp.asarray(kernel), jnp.asarray(bias))
    np.testing.assert_array_equal(got.reshape(H, W, D), want)  # integers: every sum order is exact


@pytest.mark.parametrize("dtype, tol", [(jnp.float64, 1e-13), (jnp.float32, 1e-5)])
def test_equals_lax_conv_random(dtype, tol, rng):
    H, W, C, D = 6, 5, 4, 3
    img = jnp.asarray(rng.standard_normal((H, W, C)), dtype)
    kernel = jnp.asarray(rng.standard_normal((3, 3, C, D)), dtype)
    bias = jnp.asarray(rng.standard_normal(D), dtype)
    got = _conv(img.reshape(H * W, C), image_texel_neighborhood(H, W), kernel, bias)
    assert got.dtype == dtype
    # only the summation order differs from XLA's convolution
    np.testing.assert_allclose(
        got.reshape(H, W, D), _lax_conv(img, kernel, bias), rtol=tol, atol=tol
    )


def test_offset_and_row_direction_convention():
    H, W = 3, 4
    rows, cols = np.divmod(np.arange(H * W), W)
    x = jnp.asarray(np.stack([rows, cols], 1).astype(np.float64))  # channel 0 = row, 1 = column
    taps = image_texel_neighborhood(H, W)
    # offset (dx, dy) = (0, +1) is kernel[2, 1]: the texel one row *down* (row index + 1)
    k = jnp.zeros((3, 3, 2, 2)).at[2, 1].set(jnp.eye(2))
    y = np.asarray(_conv(x, taps, k, jnp.zeros(2)))
    inside = rows < H - 1
    np.testing.assert_array_equal(y[inside], np.stack([rows + 1, cols], 1)[inside])
    np.testing.assert_array_equal(y[~inside], 0)  # zero padding below the last row
    # offset (dx, dy) = (+1, 0) is kernel[1, 2]: the texel one column to the right
    k = jnp.zeros((3, 3, 2, 2)).at[1, 2].set(jnp.eye(2))
    y = np.asarray(_conv(x, taps, k, jnp.zeros(2)))
    inside = cols < W - 1
    np.testing.assert_array_equal(y[inside], np.stack([rows, cols + 1], 1)[inside])


def test_pooling_equals_reduce_window(rng):
    H, W, C = 6, 8, 3
    img = rng.standard_normal((H, W, C))
    groups = image_pool_groups(H, W)
    x = jnp.asarray(img.reshape(H * W, C))
    avg = (
        jax.lax.reduce_window(jnp.asarray(img), 0.0, jax.lax.add, (2, 2, 1), (2, 2, 1), "VALID") / 4
    )
    mx = jax.lax.reduce_window(
        jnp.asarray(img), -jnp.inf, jax.lax.max, (2, 2, 1), (2, 2, 1), "VALID"
    )
    np.testing.assert_allclose(_pool(x, groups).reshape(H // 2, W // 2, C), avg, rtol=1e-14)
    np.testing.assert_array_equal(_pool(x, groups, mode="max").reshape(H // 2, W // 2, C), mx)
    # odd sizes: border blocks keep only their real members
    g = image_pool_groups(3, 3)
    assert g.mask.sum(1).tolist() == [4, 2, 2, 1]
    x9 = jnp.arange(9.0)[:, None]
    assert _pool(x9, g).ravel().tolist() == [2.0, 3.5, 6.5, 8.0]


# ----------------------------------------------------------------------------- loop references


def test_bilinear_taps_against_loop_reference(rng):
    N, C, D = 13, 3, 2
    taps = _random_taps(rng, N)
    taps = taps._replace(texel_mask=rng.random(N) < 0.8)
    x, kernel, bias = (
        rng.standard_normal((N, C)),
        rng.standard_normal((3, 3, C, D)),
        rng.standard_normal(D),
    )
    got = _conv(jnp.asarray(x), taps, jnp.asarray(kernel), jnp.asarray(bias))
    np.testing.assert_allclose(got, _conv_ref(x, taps, kernel, bias), rtol=1e-12, atol=1e-14)


def test_pool_against_loop_reference(rng):
    N, G, S, C = 20, 6, 5, 3
    index = rng.integers(0, N, (G, S)).astype(np.int32)
    mask = rng.random((G, S)) < 0.7
    mask[2] = False  # an empty group
    index[~mask] = 0
    x = rng.standard_normal((N, C))
    mean, mx = np.zeros((G, C)), np.zeros((G, C))
    for g in range(G):
        members = [x[index[g, s]] for s in range(S) if mask[g, s]]
        if members:
            mean[g], mx[g] = np.mean(members, 0), np.max(members, 0)
    groups = PoolGroups(index, mask)
    # a mean of O(1) values summed in another order differs by a few ulps of the summands, not of the
    # (possibly cancelling, near-zero) result: bound the error absolutely
    np.testing.assert_allclose(_pool(jnp.asarray(x), groups), mean, rtol=1e-14, atol=1e-14)
    np.testing.assert_array_equal(_pool(jnp.asarray(x), groups, mode="max"), mx)


# ----------------------------------------------------------------------------- padding / jit / vmap


def test_padding_invariance(rng):
    N, C, D = 11, 3, 2
    taps = _random_taps(rng, N)
    x, kernel, bias = (
        rng.standard_normal((N, C)),
        rng.standard_normal((3, 3, C, D)),
        rng.standard_normal(D),
    )
    ref = np.asarray(_conv(jnp.asarray(x), taps, jnp.asarray(kernel), jnp.asarray(bias)))
    # 4 padded texels (garbage features, mask False) and 2 padded slots per tap (index 0, weight 0)
    P = 4
    index = np.pad(taps.index, ((0, P), (0, 0), (0, 2)))
    weight = np.pad(taps.weight, ((0, P), (0, 0), (0, 2)))
    padded = TexelNeighborhood(index, weight, np.arange(N + P) < N)
    x_pad = np.concatenate([x, 1e6 * rng.standard_normal((P, C))])
    got = np.asarray(_conv(jnp.asarray(x_pad), padded, jnp.asarray(kernel), jnp.asarray(bias)))
    np.testing.assert_allclose(got[:N], ref, rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(got[N:], 0)
    groups = PoolGroups(rng.integers(0, N, (4, 3)).astype(np.int32), np.ones((4, 3), bool))
    gpad = PoolGroups(np.pad(groups.index, ((0, 2), (0, 2))), np.pad(groups.mask, ((0, 2), (0, 2))))
    for mode in ("mean", "max"):
        want = np.asarray(_pool(jnp.asarray(x), groups, mode=mode))
        got = np.asarray(_pool(jnp.asarray(x_pad), gpad, mode=mode))
        np.testing.assert_allclose(got[:4], want, rtol=1e-14)
        np.testing.assert_array_equal(got[4:], 0)


def test_jit_eager_and_single_compilation(rng):
    taps = image_texel_neighborhood(4, 4)
    groups = image_pool_groups(4, 4)
    x = jnp.asarray(rng.standard_normal((16, 3)))
    kernel, bias = jnp.asarray(rng.standard_normal((3, 3, 3, 2))), jnp.zeros(2)
    traces = []

    def fn(x, taps, kernel, bias, groups):
        traces.append(1)
        y = texel_conv(x, taps, kernel, bias)
        return y, grouped_pool(y, groups), grouped_pool(y, groups, mode="max")

    jitted = jax.jit(fn)
    for got, want in zip(
        jitted(x, taps, kernel, bias, groups), fn(x, taps, kernel, bias, groups), strict=True
    ):
        np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-15)
    jitted(x + 1, taps, kernel * 2, bias, groups)
    assert len(traces) == 2  # eager once, compiled once


def test_vmap_over_two_padded_textures(rng):
    sizes = [(3, 4), (4, 5)]
    N = max(h * w for h, w in sizes)
    kernel, bias = (
        jnp.asarray(rng.standard_normal((3, 3, 2, 3))),
        jnp.asarray(rng.standard_normal(3)),
    )
    imgs = [rng.standard_normal((h, w, 2)) for h, w in sizes]

    def pad_taps(t):
        n = t.index.shape[0]
        return TexelNeighborhood(
            np.pad(t.index, ((0, N - n), (0, 0), (0, 0))),
            np.pad(t.weight, ((0, N - n), (0, 0), (0, 0))),
            np.pad(t.texel_mask, (0, N - n)),
        )

    taps = jax.tree.map(
        lambda *a: jnp.stack(a), *[pad_taps(image_texel_neighborhood(h, w)) for h, w in sizes]
    )
    xs = jnp.stack(
        [
            jnp.pad(jnp.asarray(i.reshape(-1, 2)), ((0, N - i.shape[0] * i.shape[1]), (0, 0)))
            for i in imgs
        ]
    )
    out = jax.jit(jax.vmap(texel_conv, in_axes=(0, 0, None, None)))(xs, taps, kernel, bias)
    for b, ((h, w), img) in enumerate(zip(sizes, imgs, strict=True)):
        want = _lax_conv(jnp.asarray(img), kernel, bias).reshape(h * w, 3)
        np.testing.assert_allclose(out[b, : h * w], want, rtol=1e-12, atol=1e-13)
        np.testing.assert_array_equal(out[b, h * w :], 0)


# ----------------------------------------------------------------------------- dtypes / grads


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_dtype_follows_input(dtype, rng):
    x = jnp.asarray(rng.standard_normal((16, 3)), dtype)
    taps, groups = image_texel_neighborhood(4, 4), image_pool_groups(4, 4)
    y = _conv(
        x, taps, jnp.ones((3, 3, 3, 2), jnp.float32), jnp.zeros(2, jnp.float32)
    )  # params cast
    assert y.dtype == dtype
    assert _pool(y, groups).dtype == dtype and _pool(y, groups, mode="max").dtype == dtype


def test_gradients(rng):
    N = 9
    taps = _random_taps(rng, N)
    groups = PoolGroups(rng.integers(0, N, (4, 3)).astype(np.int32), rng.random((4, 3)) < 0.8)
    args = (
        jnp.asarray(rng.standard_normal((N, 2))),
        jnp.asarray(rng.standard_normal((3, 3, 2, 3))),
        jnp.asarray(rng.standard_normal(3)),
    )

    # max pooling has a kink where two members of a group tie: per-texel offsets 10 apart keep every
    # seed's features far from one (a random draw can put two within the finite-difference step)
    offset = jnp.asarray(10.0 * rng.permutation(N))[:, None]

    @jax.jit
    def f(x, kernel, bias):
        y = texel_conv(x, taps, kernel, bias)
        return y, grouped_pool(y, groups), grouped_pool(y + offset, groups, mode="max")

    check_grads(f, args, order=1, modes=["fwd", "rev"])
    # exactly-zero features and an all-empty group: finite values and gradients
    empty = PoolGroups(np.zeros((2, 3), np.int32), np.zeros((2, 3), bool))
    g = jax.jit(
        jax.grad(
            lambda x: (
                jnp.sum(grouped_pool(texel_conv(x, taps, args[1], args[2]), empty, mode="max"))
                + jnp.sum(grouped_pool(x, groups, mode="max"))
            )
        )
    )(jnp.zeros((N, 2)))
    assert np.isfinite(np.asarray(g)).all()


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_bad_input_raises_typed_errors():
    taps = image_texel_neighborhood(2, 2)
    x = jnp.ones((4, 3))
    with pytest.raises(InputError, match="HWIO"):
        texel_conv(x, taps, jnp.ones((3, 3, 2, 1)), jnp.ones(1))
    with pytest.raises(InputError, match="N = 4"):
        texel_conv(jnp.ones((5, 3)), taps, jnp.ones((3, 3, 3, 1)), jnp.ones(1))
    with pytest.raises(InputError, match=r"\[N, 9, J\]"):
        texel_conv(x, taps._replace(index=taps.index[:, :4]), jnp.ones((3, 3, 3, 1)), jnp.ones(1))
    with pytest.raises(InputError, match="mode"):
        grouped_pool(x, image_pool_groups(2, 2), mode="median")
    with pytest.raises(InputError, match=">= 1"):
        image_texel_neighborhood(0, 3)

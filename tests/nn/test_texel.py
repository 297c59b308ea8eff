"""TexelConv: on the taps of a flat image it is flax.linen.Conv(3×3, SAME) with the same variables."""

from __future__ import annotations

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from jmeshtex.nn import TexelConv
from jmeshtex.ops import image_texel_neighborhood, texel_conv


def test_drop_in_for_flax_conv(rng):
    H, W, C, D = 5, 6, 3, 4
    img = jnp.asarray(rng.standard_normal((H, W, C)))
    taps = image_texel_neighborhood(H, W)
    layer = TexelConv(D)
    x = img.reshape(H * W, C)
    variables = jax.jit(layer.init)(jax.random.key(0), x, taps)
    assert variables["params"]["kernel"].shape == (3, 3, C, D)
    variables = jax.tree.map(
        lambda a: a + jnp.asarray(rng.standard_normal(a.shape), a.dtype), variables
    )
    conv = nn.Conv(D, (3, 3), padding="SAME", dtype=jnp.float64)  # casts the float32 parameters
    want = jax.jit(conv.apply)(variables, img[None])[0]  # the same parameter names and layout
    got = jax.jit(layer.apply)(variables, x, taps)
    assert got.dtype == jnp.float64  # follows the input, not the float32 parameters
    np.testing.assert_allclose(got.reshape(H, W, D), want, rtol=1e-12, atol=1e-12)
    p = variables["params"]
    np.testing.assert_allclose(
        got, jax.jit(texel_conv)(x, taps, p["kernel"], p["bias"]), rtol=1e-13, atol=1e-14
    )


def test_without_bias(rng):
    taps = image_texel_neighborhood(3, 3)
    x = jnp.asarray(rng.standard_normal((9, 2)), jnp.float32)
    layer = TexelConv(3, use_bias=False)
    variables = jax.jit(layer.init)(jax.random.key(0), x, taps)
    assert set(variables["params"]) == {"kernel"}
    y = jax.jit(layer.apply)(variables, x, taps)
    np.testing.assert_allclose(
        y, jax.jit(texel_conv)(x, taps, variables["params"]["kernel"], jnp.zeros(3)), rtol=1e-6
    )
    assert y.dtype == jnp.float32

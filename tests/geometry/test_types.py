"""The padding contract of `pad_to` for every pytree it knows, and `to_jax` dtypes."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import ops
from jmeshtex.data import icosahedron
from jmeshtex.geometry import face_neighborhood, one_ring_neighborhood, pad_to, to_jax


def test_texel_conv_is_unchanged_by_padded_texels_and_slots(rng):
    n, c, d = 6, 3, 2
    taps = ops.TexelNeighborhood(
        index=rng.integers(0, n, (n, 9, 4)).astype(np.int32),
        weight=rng.random((n, 9, 4)),
        texel_mask=np.ones(n, bool),
    )
    x = rng.standard_normal((n, c))
    kernel, bias = rng.standard_normal((3, 3, c, d)), rng.standard_normal(d)
    y = ops.texel_conv(jnp.asarray(x), taps, jnp.asarray(kernel), jnp.asarray(bias))
    padded = pad_to(taps, {"N": n + 3, "J": 6})
    assert padded.index.shape == (n + 3, 9, 6) and not padded.texel_mask[n:].any()
    assert (padded.weight[:, :, 4:] == 0).all() and (padded.weight[n:] == 0).all()
    xp = np.concatenate([x, 1e3 * rng.standard_normal((3, c))])  # garbage in padded texels
    yp = ops.texel_conv(jnp.asarray(xp), padded, jnp.asarray(kernel), jnp.asarray(bias))
    np.testing.assert_allclose(np.asarray(yp)[:n], np.asarray(y), rtol=1e-12, atol=1e-12)


def test_pad_values_follow_the_contract():
    v, f = icosahedron()
    nb = pad_to(one_ring_neighborhood(v, f), {"V": 14, "K": 8})
    assert nb.index.shape == (14, 8)
    assert not nb.mask[:, 5:].any() and not nb.vertex_mask[12:].any()
    assert (
        (nb.transport[:, 5:] == 1).all()
        and (nb.log[:, 5:] == 0).all()
        and (nb.weight[:, 5:] == 0).all()
    )
    fn = pad_to(face_neighborhood(f), {"F": 22, "M": 7})
    assert (
        fn.faces.shape == (22, 3)
        and not fn.face_mask[20:].any()
        and not fn.vertex_faces_mask[:, 5:].any()
    )
    with pytest.raises(ValueError, match="cannot shrink"):
        pad_to(nb, {"K": 2})


@pytest.mark.parametrize(
    "real, cplx", [(jnp.float32, jnp.complex64), (jnp.float64, jnp.complex128)]
)
def test_to_jax_dtypes(real, cplx):
    v, f = icosahedron()
    nb = to_jax(one_ring_neighborhood(v, f), real)
    assert nb.log.dtype == cplx and nb.weight.dtype == real and nb.index.dtype == jnp.int32
    assert nb.mask.dtype == jnp.bool_

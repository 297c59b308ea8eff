"""Flax field-convolution modules: apply == op, embeddings; a chain of the nn layers (field conv,
FRN, VN, field conv with embedding) is gauge-equivariant, padding-invariant and jits once."""

from __future__ import annotations

import functools

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import ConfigError, InputError
from jmeshtex.geometry import pad_to
from jmeshtex.nn import FRN, FieldConv, FieldConvEmb, VNNonlinearity
from jmeshtex.ops import FieldConvParams, field_conv
from tests._random_fields import crandn, random_nbhd, rel_err

V, K, C, E = 6, 4, 3, 2


def filled(shapes, seed=0):
    """Random values (complex where complex) in a variables structure obtained with eval_shape."""
    rng = np.random.default_rng(seed)

    def fill(s):
        is_complex = jnp.issubdtype(s.dtype, jnp.complexfloating)
        v = rng.standard_normal(s.shape) + (1j * rng.standard_normal(s.shape) if is_complex else 0)
        return jnp.asarray(0.5 * v, s.dtype)

    return jax.tree.map(fill, shapes)


class Chain(nn.Module):
    """Field conv -> FRN -> VN -> field conv whose filters see an embedding: each piece is
    gauge-equivariant, so the chain must be."""

    features: int
    hdim: int = 3
    param_dtype: object = jnp.complex128

    @nn.compact
    def __call__(self, x, nbhd, embedding):
        conv = dict(hdim=self.hdim, param_dtype=self.param_dtype)
        h = FieldConv(self.features, name="conv_0", **conv)(x, nbhd)
        h = FRN(name="norm")(h, area=nbhd.area, vertex_mask=nbhd.vertex_mask)
        h = VNNonlinearity(param_dtype=self.param_dtype, name="act")(h)
        return FieldConvEmb(self.features, name="conv_1", **conv)(h, nbhd, embedding)


@functools.cache
def block_variables(features, dtype=jnp.complex128):
    m = Chain(features, param_dtype=dtype)
    x, nb = jnp.zeros((V, C), dtype), random_nbhd(np.random.default_rng(0), V, K)
    return filled(jax.eval_shape(m.init, jax.random.key(0), x, nb, jnp.zeros((V, E))))


def test_field_conv_modules_apply_the_op(rng):
    nb = random_nbhd(rng, V, K)
    x = jnp.asarray(crandn(rng, V, C), jnp.complex128)
    emb = rng.standard_normal((V, E))
    plain, with_emb = FieldConv(5, hdim=3, activation="relu"), FieldConvEmb(5, hdim=3)
    v1 = filled(jax.eval_shape(plain.init, jax.random.key(0), x, nb))
    v2 = filled(jax.eval_shape(with_emb.init, jax.random.key(0), x, nb, emb), seed=1)
    t = np.array([0.3, -1.2])  # a global embedding is broadcast to every vertex

    @jax.jit
    def run(v1, v2, x, emb):
        p1, p2 = (FieldConvParams(**v["params"]) for v in (v1, v2))
        return (
            plain.apply(v1, x, nb),
            field_conv(x, nb, p1, activation="relu"),
            with_emb.apply(v2, x, nb, emb),
            field_conv(x, nb, p2, embedding=emb),
            with_emb.apply(v2, x, nb, t),
            field_conv(x, nb, p2, embedding=jnp.tile(t, (V, 1))),
        )

    out = run(v1, v2, x, emb)
    for got, want in zip(out[::2], out[1::2], strict=False):
        assert rel_err(got, want) < 1e-13


def test_field_conv_options_apply_the_op(rng):
    """Two-hidden-layer filters, a per-channel embedding and the reference's untransported argument
    (the options the FLDM denoiser's blocks use) reach :func:`field_conv` unchanged; the parameters
    are the FieldConvParams fields, and a channel embedding the module was not built for is an error."""
    nb = random_nbhd(rng, V, K)
    x = jnp.asarray(crandn(rng, V, C), jnp.complex128)
    e = jnp.asarray(rng.standard_normal((V, C)))
    for argument in ("transported", "untransported"):
        m = FieldConv(
            5,
            hdim=3,
            filter_layers=2,
            channel_embedding=True,
            argument=argument,
            param_dtype=jnp.complex128,
        )
        v = filled(jax.eval_shape(m.init, jax.random.key(0), x, nb, e))
        assert sorted(v["params"]) == [
            "channel_weight",
            "filter_bias",
            "filter_weight",
            "hidden_bias",
            "hidden_weight",
            "mix",
        ]
        assert v["params"]["hidden_weight"].shape == (3, 3) and v["params"][
            "channel_weight"
        ].shape == (3,)
        want = field_conv(
            x, nb, FieldConvParams(**v["params"]), channel_embedding=e, argument=argument
        )
        assert rel_err(m.apply(v, x, nb, e), want) < 1e-13
        assert rel_err(m.apply(v, x, nb, 2 * e), want) > 1e-3  # the embedding reaches the filters
    one = FieldConv(5, hdim=3, param_dtype=jnp.complex128)
    v1 = filled(jax.eval_shape(one.init, jax.random.key(0), x, nb))
    assert sorted(v1["params"]) == ["filter_bias", "filter_weight", "mix"]
    with pytest.raises(InputError, match="channel_weight"):
        one.apply(v1, x, nb, e)
    with pytest.raises(ConfigError, match="hidden_layers"):
        FieldConv(5, filter_layers=3).init(jax.random.key(0), x, nb)


def test_block_is_gauge_equivariant(rng):
    nb = random_nbhd(rng, V, K)
    m = Chain(C)
    v = block_variables(C)
    x, emb = crandn(rng, V, C), rng.standard_normal((V, E))
    alpha = rng.uniform(-np.pi, np.pi, V)
    rot = np.exp(-1j * alpha)
    nb2 = nb._replace(
        log=nb.log * rot[:, None],
        transport=nb.transport * np.exp(1j * (alpha[nb.index] - alpha[:, None])),
    )
    f = jax.jit(m.apply)
    assert rel_err(f(v, x * rot[:, None], nb2, emb), f(v, x, nb, emb) * rot[:, None]) < 1e-12


def test_block_padding_invariance(rng):
    nb = random_nbhd(rng, V, K)
    m = Chain(C)
    v = block_variables(C)
    x, emb = crandn(rng, V, C), rng.standard_normal((V, E))
    y = jax.jit(m.apply)(v, x, nb, emb)
    padded = pad_to(nb, {"V": V + 2, "K": K + 1})  # padded vertices: vertex_mask False, area 0
    x_pad = np.concatenate([x, 1e3 * crandn(rng, 2, C)])
    emb_pad = np.concatenate([emb, 1e3 * rng.standard_normal((2, E))])
    y_pad = jax.jit(m.apply)(v, x_pad, padded, emb_pad)
    assert rel_err(y_pad[:V], y) < 1e-12


def test_block_init_and_jit_without_recompiling(rng):
    nb = random_nbhd(rng, V, K)
    m = Chain(4, hdim=2, param_dtype=jnp.complex64)
    x = jnp.asarray(crandn(rng, V, C), jnp.complex64)
    v = jax.jit(m.init)(jax.random.key(0), x, nb, jnp.zeros(1))
    assert v["params"]["conv_0"]["mix"].dtype == jnp.complex64
    assert v["params"]["conv_1"]["filter_weight"].shape == (2 + 1, 2)  # log map (2) + embedding (1)
    traces = []

    def apply(v, x, t):
        traces.append(1)
        return m.apply(v, x, nb, t)

    f = jax.jit(apply)
    y1 = f(v, x, jnp.array([0.1]))
    y2 = f(v, x * 2, jnp.array([0.7]))
    assert len(traces) == 1 and y1.dtype == jnp.complex64
    assert np.all(np.isfinite(np.asarray(y2)))

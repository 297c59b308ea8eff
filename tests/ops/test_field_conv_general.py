"""Field convolution, general path: two-hidden-layer filters, per-channel embedding, and the
untransported (reference-code / printed eq. 34) filter argument, against a slow loop reference."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jmeshtex import ConfigError, InputError
from jmeshtex.geometry import pad_to
from jmeshtex.ops import _field_conv_fast as fc_fast
from jmeshtex.ops import _field_conv_general as fc_module
from jmeshtex.ops import field_conv, init_field_conv
from tests._random_fields import (
    crandn,
    field_conv_params,
    gauge_transform,
    random_nbhd,
    rel_err,
    silu,
)

V, K, C, D, H = 7, 5, 3, 2, 4

# ----------------------------------------------------------------------------- helpers


# ----------------------------------------------------------------------------- tests


def general_params(seed, *, hidden=True, channel=True, dtype=jnp.complex128):
    rng = np.random.default_rng(seed)
    base = field_conv_params(seed, e=1, c=C, d=D, h=H, dtype=dtype)
    real = np.float64 if dtype == jnp.complex128 else np.float32
    extra = {}
    if channel:
        extra["channel_weight"] = rng.standard_normal(H).astype(real)
    if hidden:
        extra["hidden_weight"] = (rng.standard_normal((H, H)) / np.sqrt(H)).astype(real)
        extra["hidden_bias"] = (0.3 * rng.standard_normal(H)).astype(real)
    return base._replace(**extra)


def loop_reference(x, nb, params, emb, chan, *, activation="silu", untransported=False, delta=1e-4):
    """One (vertex, slot, channel) at a time: φ = act(act([a_r, a_i, e_p, e_pc] A + b) W₂ + b₂)."""
    act = silu if activation == "silu" else (lambda t: np.maximum(t, 0))
    x = np.asarray(x, complex)
    a_w, b, mix = (np.asarray(t) for t in params[:3])
    cw = None if params.channel_weight is None else np.asarray(params.channel_weight)
    y = np.zeros((x.shape[0], mix.shape[2]), complex)
    for p in range(x.shape[0]):
        wsum = sum(nb.weight[p, k] for k in range(nb.index.shape[1]) if nb.mask[p, k])
        for k in range(nb.index.shape[1]):
            if not nb.mask[p, k]:
                continue
            q, rho, w = nb.index[p, k], nb.transport[p, k], nb.weight[p, k] / wsum
            for ch in range(x.shape[1]):
                u = rho * x[q, ch]
                direction = x[q, ch] if untransported else u
                a = nb.log[p, k] * np.conj(direction / np.sqrt(abs(direction) ** 2 + delta**2))
                pre = np.concatenate([[a.real, a.imag], emb[p]]) @ a_w + b
                if cw is not None:
                    pre = pre + chan[p, ch] * cw
                phi = act(pre)
                if params.hidden_weight is not None:
                    phi = act(
                        phi @ np.asarray(params.hidden_weight) + np.asarray(params.hidden_bias)
                    )
                y[p] += w * u * (phi @ mix[ch])
    return y


@pytest.fixture
def case(rng):
    nb = random_nbhd(rng, V, K)
    return nb, crandn(rng, V, C), rng.standard_normal((V, 1)), rng.standard_normal((V, C))


@pytest.mark.parametrize("activation", ["silu", "relu"])
@pytest.mark.parametrize("hidden, channel", [(True, True), (True, False), (False, True)])
def test_general_path_matches_loop_reference(case, activation, hidden, channel):
    nb, x, emb, chan = case
    params = general_params(1, hidden=hidden, channel=channel)
    y = field_conv(
        jnp.asarray(x),
        nb,
        params,
        embedding=emb,
        channel_embedding=chan if channel else None,
        activation=activation,
    )
    ref = loop_reference(x, nb, params, emb, chan, activation=activation)
    assert rel_err(y, ref) < 1e-12


def test_a_zero_channel_embedding_changes_nothing(case):
    nb, x, emb, _ = case
    params = general_params(2, hidden=False, channel=True)
    fast = field_conv(jnp.asarray(x), nb, params._replace(channel_weight=None), embedding=emb)
    general = field_conv(
        jnp.asarray(x), nb, params, embedding=emb, channel_embedding=np.zeros((V, C))
    )
    assert rel_err(general, fast) < 1e-13


@pytest.mark.parametrize("argument", ["transported", "untransported"])
def test_blocks_cover_every_vertex(case, argument, monkeypatch):
    # two hidden layers and a channel embedding: the transported argument runs the fused path, the
    # untransported one the general path; 7 vertices in blocks of 3 (the last one overlapping or
    # padded) give the values and gradients of one block
    nb, x, emb, chan = case
    params = general_params(3)

    def loss(x, params):
        y = field_conv(x, nb, params, embedding=emb, channel_embedding=chan, argument=argument)
        return jnp.sum(jnp.abs(y) ** 2), y

    whole = jax.value_and_grad(loss, argnums=(0, 1), has_aux=True)(jnp.asarray(x), params)
    monkeypatch.setattr(fc_module, "GENERAL_BLOCK", 3)
    monkeypatch.setattr(fc_module, "GENERAL_SINGLE", 0)
    monkeypatch.setattr(fc_fast, "BLOCK", 3)
    monkeypatch.setattr(fc_fast, "TANGENT_BLOCK", 3)
    blocked = jax.value_and_grad(loss, argnums=(0, 1), has_aux=True)(jnp.asarray(x), params)
    for a, b in zip(jax.tree.leaves(blocked), jax.tree.leaves(whole), strict=True):
        assert rel_err(a, b) < 1e-12


def test_gauge_equivariance_and_the_untransported_negative_control(case, rng):
    nb, x, emb, chan = case
    params = general_params(4)
    alpha = rng.uniform(-np.pi, np.pi, V)
    xt, nbt = gauge_transform(x, nb, alpha)
    rot = np.exp(-1j * alpha)[:, None]
    errors = {}
    for argument in ("transported", "untransported"):
        y = field_conv(
            jnp.asarray(x), nb, params, embedding=emb, channel_embedding=chan, argument=argument
        )
        yt = field_conv(
            jnp.asarray(xt), nbt, params, embedding=emb, channel_embedding=chan, argument=argument
        )
        errors[argument] = rel_err(yt, np.asarray(y) * rot)
    assert errors["transported"] < 1e-12
    assert errors["untransported"] > 1e-2, errors
    # the untransported form is the loop reference's printed-eq.-34 argument
    y = field_conv(
        jnp.asarray(x), nb, params, embedding=emb, channel_embedding=chan, argument="untransported"
    )
    assert rel_err(y, loop_reference(x, nb, params, emb, chan, untransported=True)) < 1e-12


def test_padding_invariance_of_the_general_path(case, rng):
    nb, x, emb, chan = case
    params = general_params(5)
    y = field_conv(jnp.asarray(x), nb, params, embedding=emb, channel_embedding=chan)
    nbp = pad_to(nb, {"V": V + 3, "K": K + 2})
    xp = np.concatenate([x, 9 + crandn(rng, 3, C)])
    yp = field_conv(
        jnp.asarray(xp),
        nbp,
        params,
        embedding=np.concatenate([emb, np.ones((3, 1))]),
        channel_embedding=np.concatenate([chan, np.ones((3, C))]),
    )
    np.testing.assert_allclose(yp[:V], y, rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize("hidden", [True, False], ids=["two-layer", "one-layer-channel"])
def test_gradients_finite_at_zero_and_correct(case, hidden):
    nb, x, emb, chan = case
    params = general_params(6, hidden=hidden)
    modes = (
        ("rev", "fwd") if hidden else ("rev",)
    )  # the one-layer fast path has a hand-written VJP only

    def f(x, chan):
        return field_conv(x, nb, params, embedding=emb, channel_embedding=chan)

    zero = jnp.zeros((V, C), jnp.complex128)
    g = jax.grad(lambda z: jnp.sum(jnp.abs(f(z, chan)) ** 2 + jnp.real(f(z, chan)).sum()))(zero)
    assert bool(jnp.all(jnp.isfinite(g)))
    # JAX's float64 default (1e-5): central differences (eps 1e-4) err by eps^2 f'''/6, and f'''
    # grows as |x|^-3 through the argument x/|x|; random features put some |x| near 0.05
    check_grads(f, (jnp.asarray(x), jnp.asarray(chan)), order=1, modes=modes, atol=1e-5, rtol=1e-5)
    check_grads(
        lambda p: field_conv(jnp.asarray(x), nb, p, embedding=emb, channel_embedding=chan),
        (params,),
        order=1,
        modes=("rev",),
        atol=1e-6,
        rtol=1e-6,
    )


def test_init_options_keep_the_one_layer_parameters_and_have_the_documented_shapes():
    key = jax.random.key(0)
    one = init_field_conv(key, 3, 5, hdim=4, embedding_features=2, dtype=jnp.complex128)
    two = init_field_conv(
        key, 3, 5, hdim=4, embedding_features=2, hidden_layers=2, dtype=jnp.complex128
    )
    for name in ("filter_weight", "filter_bias", "mix"):
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name))
    assert (
        one.hidden_weight is None
        and two.hidden_weight.shape == (4, 4)
        and two.hidden_bias.shape == (4,)
    )
    chan = init_field_conv(key, 3, 5, hdim=4, channel_embedding=True)
    assert chan.channel_weight.shape == (4,) and chan.hidden_weight is None
    with pytest.raises(ConfigError, match="hidden_layers"):
        init_field_conv(key, 3, 5, hidden_layers=3)


def test_general_path_bad_inputs_raise_typed_errors(case):
    nb, x, emb, chan = case
    params = general_params(7)
    # parameters that lack a part the channel embedding or the hidden layer needs
    for broken, match in (
        (params._replace(channel_weight=None), "channel_embedding needs"),
        (params._replace(hidden_bias=None), "hidden_weight and hidden_bias"),
    ):
        with pytest.raises(InputError, match=match):
            field_conv(jnp.asarray(x), nb, broken, embedding=emb, channel_embedding=chan)
    with pytest.raises(InputError, match="channel_weight but channel_embedding=None"):
        field_conv(jnp.asarray(x), nb, params, embedding=emb)
    with pytest.raises(ConfigError, match="argument must be"):
        field_conv(
            jnp.asarray(x), nb, params, embedding=emb, channel_embedding=chan, argument="printed"
        )

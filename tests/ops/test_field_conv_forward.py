"""Every JAX transformation through field_conv's fast path (one and two hidden filter layers), in
any order: jvp, linearize, jvp(jit(f)), jit(jvp), jacfwd, jacrev, hessian, and vmap of each; the
fast and general implementations give equal values and derivatives."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jmeshtex import VertexNeighborhood, to_jax
from jmeshtex.ops import _field_conv_fast, _field_conv_general, field_conv, init_field_conv

V, K, C, D, H = 5, 3, 2, 3, 4


def _setup(seed=0, layers=1):
    """A tiny k-NN-like neighbourhood (self slot, one padded slot), float64 / complex128; filters
    with ``layers`` hidden layers."""
    rng = np.random.default_rng(seed)
    index = rng.integers(0, V, (V, K))
    index[:, 0] = np.arange(V)
    mask = np.ones((V, K), bool)
    mask[1, 2] = False
    log = rng.uniform(0.2, 1.0, (V, K)) * np.exp(1j * rng.uniform(-np.pi, np.pi, (V, K)))
    log[:, 0] = 0
    transport = np.exp(1j * rng.uniform(-np.pi, np.pi, (V, K)))
    transport[:, 0] = 1
    log[~mask], transport[~mask], index[~mask] = 0, 1, 0
    nbhd = to_jax(
        VertexNeighborhood(
            index=index.astype(np.int32),
            mask=mask,
            log=log,
            transport=transport,
            weight=np.where(mask, rng.uniform(0.5, 1.5, (V, K)), 0.0),
            area=np.ones(V),
            vertex_mask=np.ones(V, bool),
        )
    )
    x = jnp.asarray(rng.standard_normal((V, C)) + 1j * rng.standard_normal((V, C)))
    params = init_field_conv(
        jax.random.key(seed), C, D, hdim=H, hidden_layers=layers, dtype=jnp.complex128
    )
    if layers == 2:  # the init's zero second-layer offsets put a ReLU's kink exactly at every
        # slot whose first-layer responses are all 0, where finite differences are one-sided
        params = params._replace(hidden_bias=jnp.asarray(0.3 * rng.standard_normal(H)))
    return x, nbhd, params


@pytest.mark.parametrize(
    "activation, layers",
    [("silu", 1), ("relu", 2)],  # each activation and each depth (the ReLU at its kinks: 2 layers)
    ids=["silu-one-hidden", "relu-two-hidden"],  # the other two pairs: 60 CPU-s, no new path
)
def test_check_grads_forward_and_reverse_to_second_order(activation, layers):
    x, nbhd, params = _setup(layers=layers)

    def f(x, params):
        return field_conv(x, nbhd, params, activation=activation)

    check_grads(f, (x, params), order=2, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6)


def test_check_grads_with_a_channel_embedding():
    x, nbhd, _ = _setup()
    params = init_field_conv(
        jax.random.key(1), C, D, hdim=H, channel_embedding=True, dtype=jnp.complex128
    )
    emb = jnp.asarray(np.random.default_rng(2).standard_normal((V, C)))

    def f(x, params, emb):
        return field_conv(x, nbhd, params, channel_embedding=emb)

    check_grads(f, (x, params, emb), order=2, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6)


def test_jacfwd_equals_jacrev_under_jit():
    x, nbhd, params = _setup()

    def f(xr):  # a real function of a real input: jacfwd and jacrev both apply
        y = field_conv(jax.lax.complex(xr[:, :C], xr[:, C:]), nbhd, params)
        return jnp.concatenate([y.real, y.imag], axis=1)

    xr = jnp.concatenate([x.real, x.imag], axis=1)
    fwd = jax.jit(jax.jacfwd(f))(xr)
    rev = jax.jit(jax.jacrev(f))(xr)
    np.testing.assert_allclose(fwd, rev, rtol=1e-10, atol=1e-12)
    assert np.abs(fwd).max() > 0


def test_jvp_values_equal_the_fast_path():
    x, nbhd, params = _setup()

    def f(x):
        return field_conv(x, nbhd, params)

    y, _ = jax.jit(lambda x, t: jax.jvp(f, (x,), (t,)))(x, x)
    np.testing.assert_allclose(y, jax.jit(f)(x), rtol=1e-12, atol=1e-14)


def _real_loss(nbhd, params):
    def loss(xr):  # a real scalar of a real input: every mode applies
        y = field_conv(jax.lax.complex(xr[:, :C], xr[:, C:]), nbhd, params)
        return jnp.sum(jnp.abs(y) ** 2 * jnp.arange(1.0, D + 1.0))

    return loss


@pytest.mark.parametrize("layers", [1, 2], ids=["one-hidden", "two-hidden"])
def test_every_transformation_in_any_order(layers):
    x, nbhd, params = _setup(layers=layers)
    xr = jnp.concatenate([x.real, x.imag], axis=1)
    t = jnp.cos(jnp.arange(xr.size, dtype=xr.dtype)).reshape(xr.shape)
    loss = _real_loss(nbhd, params)
    grad = jax.grad(loss)(xr)
    hess = jax.hessian(loss)(xr)  # jacfwd of jacrev
    hvp = jnp.einsum("ijkl,kl->ij", hess, t)
    jvp_value = jnp.sum(grad * t)
    tangents = {
        "jvp": jax.jvp(loss, (xr,), (t,))[1],
        "linearize": jax.linearize(loss, xr)[1](t),
        "jvp(jit)": jax.jvp(jax.jit(loss), (xr,), (t,))[1],
        "jit(jvp)": jax.jit(lambda a, b: jax.jvp(loss, (a,), (b,))[1])(xr, t),
        "linearize(jit)": jax.linearize(jax.jit(loss), xr)[1](t),
    }
    for name, value in tangents.items():
        np.testing.assert_allclose(value, jvp_value, rtol=1e-10, err_msg=name)
    grads = {
        "jacfwd": jax.jacfwd(loss)(xr),
        "jacrev(jit)": jax.jacrev(jax.jit(loss))(xr),
        "grad(jit)": jax.jit(jax.grad(loss))(xr),
    }
    for name, value in grads.items():
        np.testing.assert_allclose(value, grad, rtol=1e-10, atol=1e-12, err_msg=name)
    hessians = {  # forward over reverse, reverse over forward, reverse over reverse
        "jvp(grad)": jax.jvp(jax.grad(loss), (xr,), (t,))[1],
        "grad(jvp)": jax.grad(lambda a: jax.jvp(loss, (a,), (t,))[1])(xr),
        "jacrev(jacrev)": jnp.einsum("ijkl,kl->ij", jax.jacrev(jax.jacrev(loss))(xr), t),
    }
    for name, value in hessians.items():
        np.testing.assert_allclose(value, hvp, rtol=1e-9, atol=1e-11, err_msg=name)
    assert np.abs(np.asarray(hvp)).max() > 1e-3


@pytest.mark.parametrize("layers", [1, 2], ids=["one-hidden", "two-hidden"])
def test_vmap_of_every_transformation(layers):
    x, nbhd, params = _setup(layers=layers)
    xr = jnp.concatenate([x.real, x.imag], axis=1)
    batch = jnp.stack([xr, 2 * xr + 0.1])
    loss = _real_loss(nbhd, params)
    for name, fn in {
        "jvp": lambda a: jax.jvp(loss, (a,), (a,))[1],
        "linearize": lambda a: jax.linearize(loss, a)[1](a),
        "jvp(jit)": lambda a: jax.jvp(jax.jit(loss), (a,), (a,))[1],
        "grad": jax.grad(loss),
        "jacfwd": jax.jacfwd(loss),
        "jacrev": jax.jacrev(loss),
        "hessian": jax.hessian(loss),
    }.items():
        got = jax.jit(jax.vmap(fn))(batch)
        for i in range(2):
            np.testing.assert_allclose(got[i], fn(batch[i]), rtol=1e-10, atol=1e-12, err_msg=name)


@pytest.mark.parametrize("layers", [1, 2], ids=["one-hidden", "two-hidden"])
@pytest.mark.parametrize("activation", ["silu", "relu"])
def test_the_fast_and_general_implementations_are_equal(activation, layers, monkeypatch):
    # the same transported convolution (one or two hidden filter layers) through both
    # implementations: values, forward-mode and reverse-mode derivatives in every argument, the
    # second layer's weights included (blocked: 5 vertices, blocks of 2)
    monkeypatch.setattr(_field_conv_fast, "BLOCK", 2)
    monkeypatch.setattr(_field_conv_fast, "TANGENT_BLOCK", 2)
    monkeypatch.setattr(_field_conv_general, "GENERAL_BLOCK", 2)
    monkeypatch.setattr(_field_conv_general, "GENERAL_SINGLE", 0)
    x, nbhd, params = _setup(3)
    from jmeshtex.ops._field_conv_terms import slot_geometry

    index, slots = slot_geometry(nbhd, jnp.float64)
    a_w = params.filter_weight
    bias = jnp.broadcast_to(params.filter_bias, (V, H))
    hidden = None
    if layers == 2:
        rng = np.random.default_rng(8)
        hidden = (rng.standard_normal((H, H)) / np.sqrt(H), 0.3 * rng.standard_normal(H))
        hidden = tuple(jnp.asarray(a) for a in hidden)

    def fast(x, slots, a_w, bias, hidden, mix):
        return _field_conv_fast.conv_fast(x, index, slots, a_w, bias, mix, 1e-4, activation, hidden)

    def general(x, slots, a_w, bias, hidden, mix):
        return _field_conv_general.conv_general(
            x, index, slots, a_w, bias, mix, None, hidden,
            delta=1e-4, activation=activation, transported=True,
        )  # fmt: skip

    args = (x, slots, a_w, bias, hidden, params.mix)
    tangents = jax.tree.map(
        lambda a: jnp.cos(jnp.arange(a.size).reshape(a.shape)).astype(a.dtype), args
    )
    s = jnp.sin(jnp.arange(V * D, dtype=jnp.float64).reshape(V, D))
    cot = jax.lax.complex(s, -0.5 * s)
    for fn_pair in ((fast, general),):
        y_f, dy_f = jax.jvp(fn_pair[0], args, tangents)
        y_g, dy_g = jax.jvp(fn_pair[1], args, tangents)
        np.testing.assert_allclose(y_f, y_g, rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(dy_f, dy_g, rtol=1e-11, atol=1e-12)
        g_f = jax.vjp(fn_pair[0], *args)[1](cot)
        g_g = jax.vjp(fn_pair[1], *args)[1](cot)
        for a, b in zip(jax.tree.leaves(g_f), jax.tree.leaves(g_g), strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-12)
    assert np.abs(np.asarray(dy_f)).max() > 0 and np.abs(np.asarray(y_f)).max() > 0


@pytest.mark.parametrize("layers", [1, 2], ids=["one-hidden", "two-hidden"])
@pytest.mark.parametrize("per_channel", [False, True])
@pytest.mark.parametrize("activation", ["silu", "relu"])
def test_fixed_neighbourhood_derivatives_equal_the_plain_formula(
    activation, per_channel, layers, monkeypatch
):
    # the neighbourhood held fixed (its tangent a symbolic zero, as in training): the fast path's
    # tangent (the transpose of its hand-written blocked VJP) and its reverse mode (that VJP) must
    # equal the plain whole-mesh formula's derivatives in x, the filter rows, the offsets ([V, H],
    # or per channel [V, H, C]) and the second layer's (W₂, b₂)
    monkeypatch.setattr(_field_conv_fast, "BLOCK", 2)
    monkeypatch.setattr(_field_conv_fast, "TANGENT_BLOCK", 2)
    x, nbhd, params = _setup(4)
    from jmeshtex.ops._field_conv_terms import slot_geometry

    index, slots = slot_geometry(nbhd, jnp.float64)
    rng = np.random.default_rng(5)
    shape = (V, H, C) if per_channel else (V, H)
    bias = jnp.asarray(rng.standard_normal(shape))
    a_w = params.filter_weight
    hidden = None
    if layers == 2:
        hidden = (rng.standard_normal((H, H)) / np.sqrt(H), 0.3 * rng.standard_normal(H))
        hidden = tuple(jnp.asarray(a) for a in hidden)

    def fast(x, a_w, bias, hidden, mix):
        return _field_conv_fast.conv_fast(x, index, slots, a_w, bias, mix, 1e-4, activation, hidden)

    def plain(x, a_w, bias, hidden, mix):
        return _plain(x, index, slots, a_w, bias, mix, activation, hidden)

    args = (x, a_w, bias, hidden, params.mix)
    tangents = jax.tree.map(
        lambda a: jnp.cos(jnp.arange(a.size).reshape(a.shape)).astype(a.dtype), args
    )
    s = jnp.sin(jnp.arange(V * D, dtype=jnp.float64).reshape(V, D))
    cot = jax.lax.complex(s, -0.5 * s)
    y_f, dy_f = jax.jvp(fast, args, tangents)
    y_g, dy_g = jax.jvp(plain, args, tangents)
    np.testing.assert_allclose(y_f, y_g, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(dy_f, dy_g, rtol=1e-11, atol=1e-12)
    g_f = jax.vjp(fast, *args)[1](cot)
    g_g = jax.vjp(plain, *args)[1](cot)
    for a, b in zip(jax.tree.leaves(g_f), jax.tree.leaves(g_g), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-12)
        assert np.abs(np.asarray(a)).max() > 0


def _plain(x, index, slots, a_w, bias, mix, activation, hidden=None):
    """The transported convolution as the plain whole-mesh formula (an oracle)."""
    from jmeshtex.ops._field_conv_terms import (
        as_complex,
        filtered_sums_plain,
        gather_terms,
        mix_halves,
    )

    zr, zi, ar, ai = gather_terms(x.real, x.imag, index, slots, 1e-4, blocked=False)
    s_r, s_i = filtered_sums_plain(zr, zi, ar, ai, a_w, bias, activation, hidden)
    m_r, m_i = mix_halves(mix)
    v = x.shape[0]
    return as_complex(s_r.reshape(v, -1) @ m_r + s_i.reshape(v, -1) @ m_i)


def test_no_private_jax_import():
    import pathlib

    import jmeshtex

    root = pathlib.Path(jmeshtex.__file__).parent
    offenders = [str(p) for p in root.rglob("*.py") if "jax._src" in p.read_text()]
    assert offenders == []

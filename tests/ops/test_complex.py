"""Complex tangent-feature layers: hand cases, slow loop references, rotation / permutation
equivariance, masks and padding, batching, jit, dtypes, zero features, gradients, optax helper."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from jax.test_util import check_grads

from jmeshtex import ConfigError, InputError
from jmeshtex.ops import (
    ComplexAttentionParams,
    FRNParams,
    VNParams,
    VNTransformerParams,
    complex_attention,
    complex_layer_norm,
    complex_linear,
    conjugate_complex_grads,
    filter_response_norm,
    init_complex_attention,
    vn_nonlinearity,
    vn_transformer_block,
)
from tests._random_fields import crandn, rel_err, silu

S, C, HEADS = 5, 4, 2  # set size, channels, attention heads used throughout


# ----------------------------------------------------------------------------- slow references


def ref_linear(x, w):
    x, w = np.asarray(x), np.asarray(w)
    y = np.zeros(x.shape[:-1] + (w.shape[1],), complex)
    for idx in np.ndindex(*x.shape[:-1]):
        for d in range(w.shape[1]):
            y[idx + (d,)] = sum(x[idx + (c,)] * w[c, d] for c in range(w.shape[0]))
    return y


def ref_vn(x, p, delta=1e-6):
    q = np.asarray(x) if p.weight is None else ref_linear(x, p.weight)
    k = ref_linear(x, p.direction)
    y = np.empty_like(q)
    for idx in np.ndindex(*q.shape):
        dot = (q[idx] * np.conj(k[idx])).real
        y[idx] = q[idx] + silu(-dot) / (abs(k[idx]) ** 2 + delta) * k[idx]
    return y


def ref_frn(x, p, area, mask, delta=1e-6):
    x, scale, eps = np.asarray(x), np.asarray(p.scale), np.asarray(p.eps)
    y = np.empty_like(x)
    for c in range(x.shape[1]):
        num = sum(area[v] * abs(x[v, c]) ** 2 for v in range(len(x)) if mask[v])
        den = sum(area[v] for v in range(len(x)) if mask[v])
        y[:, c] = x[:, c] * scale[c] / np.sqrt(num / den + delta + abs(eps[c]))
    return y


def ref_layer_norm(x, scale, delta=1e-6):
    x = np.asarray(x)
    y = np.empty_like(x)
    for idx in np.ndindex(*x.shape[:-1]):
        ms = np.mean([abs(v) ** 2 for v in x[idx]])
        y[idx] = np.asarray(scale) * x[idx] / np.sqrt(ms + delta)
    return y


def ref_attention(x, p, mask=None):
    x = np.asarray(x)
    mask = np.ones(x.shape[:-1], bool) if mask is None else np.asarray(mask)
    c, nh, e = p.query.shape
    f = p.value.shape[2]
    q, k, v = (
        ref_linear(x, np.asarray(w).reshape(c, -1)).reshape(x.shape[:-1] + (nh, -1))
        for w in (p.query, p.key, p.value)
    )
    out = np.zeros(x.shape[:-1] + (nh, f), complex)
    for b in np.ndindex(*x.shape[:-2]):
        for h in range(nh):
            for s in range(x.shape[-2]):
                valid = [t for t in range(x.shape[-2]) if mask[b + (t,)]]
                if not valid:
                    continue
                logits = np.array(
                    [
                        np.sum(q[b + (s, h)] * np.conj(k[b + (t, h)])).real / np.sqrt(e)
                        for t in valid
                    ]
                )
                a = np.exp(logits - logits.max())
                a /= a.sum()
                out[b + (s, h)] = sum(ai * v[b + (t, h)] for ai, t in zip(a, valid, strict=False))
    return ref_linear(out.reshape(x.shape[:-1] + (nh * f,)), np.asarray(p.out).reshape(nh * f, -1))


def ref_block(x, p, mask=None, delta=1e-6):
    u = np.asarray(x) + ref_attention(ref_layer_norm(x, p.attention_norm, delta), p.attention, mask)
    hidden = ref_vn(ref_layer_norm(u, p.mlp_norm, delta), p.mlp_in, delta)
    return u + ref_vn(hidden, p.mlp_out, delta)


# ----------------------------------------------------------------------------- the ops under test


@functools.cache
def _params(name, dtype, seed=0):
    """Parameters as NumPy arrays (no JAX compilation: the init_* functions have their own doctests)."""
    rng = np.random.default_rng(seed)
    real = np.float64 if dtype == jnp.complex128 else np.float32

    def w(*shape):  # complex LeCun-normal-like weights
        return (crandn(rng, *shape) / np.sqrt(2 * shape[0])).astype(dtype)

    def vn(c, d, dense=True):
        return VNParams(weight=w(c, d) if dense else None, direction=w(c, d))

    def attention():
        return ComplexAttentionParams(
            w(C, HEADS, 2), w(C, HEADS, 2), w(C, HEADS, 2), w(HEADS, 2, C)
        )

    scale = np.linspace(0.5, 2.0, C).astype(real)
    return {
        "linear": lambda: w(C, 3),
        "vn": lambda: vn(C, C, dense=False),
        "vn_dense": lambda: vn(C, 3),
        "frn": lambda: FRNParams(
            scale=np.arange(1, C + 1).astype(real), eps=np.full(C, -1e-3, real)
        ),
        "layer_norm": lambda: scale,
        "attention": attention,
        "block": lambda: VNTransformerParams(
            scale, attention(), scale[::-1].copy(), vn(C, 6), vn(6, C)
        ),
    }[name]()


AREA = np.array([0.5, 1.0, 2.0, 1.5, 0.7])
MASK = np.array([True, True, True, False, True])

OPS = {  # name -> (op(x, params), reference(x, params)); x is [2, S, C] for set ops, [S, C] per vertex
    "linear": (complex_linear, ref_linear),
    "vn": (vn_nonlinearity, ref_vn),
    "vn_dense": (vn_nonlinearity, ref_vn),
    "frn": (
        lambda x, p: filter_response_norm(x, p, area=AREA, vertex_mask=MASK),
        lambda x, p: ref_frn(x, p, AREA, MASK),
    ),
    "layer_norm": (complex_layer_norm, ref_layer_norm),
    "attention": (
        lambda x, p: complex_attention(x, p, mask=np.stack([MASK, ~MASK | MASK])),
        lambda x, p: ref_attention(x, p, np.stack([MASK, ~MASK | MASK])),
    ),
    "block": (
        lambda x, p: vn_transformer_block(x, p, mask=np.stack([MASK, ~MASK | MASK])),
        lambda x, p: ref_block(x, p, np.stack([MASK, ~MASK | MASK])),
    ),
}
JITTED = {name: jax.jit(op) for name, (op, _) in OPS.items()}


def _x(rng, name, dtype=jnp.complex128):
    shape = (S, C) if name == "frn" else (2, S, C)
    return jnp.asarray(crandn(rng, *shape), dtype)


# ----------------------------------------------------------------------------- generic checks


@pytest.mark.parametrize("name", OPS)
def test_matches_loop_reference(rng, name):
    p = _params(name, jnp.complex128)
    x = _x(rng, name)
    assert rel_err(JITTED[name](x, p), OPS[name][1](x, p)) < 1e-12


@pytest.mark.parametrize("name", ["linear", "vn", "frn", "layer_norm", "attention"])
def test_jit_matches_eager_without_recompiling(rng, name):
    # (the block is a composition of these; its jitted path is checked against the loop reference)
    p = _params(name, jnp.complex64)
    op = OPS[name][0]
    traces = []

    def fn(x, p):
        traces.append(1)
        return op(x, p)

    jitted = jax.jit(fn)
    x1, x2 = _x(rng, name, jnp.complex64), _x(rng, name, jnp.complex64)
    np.testing.assert_allclose(jitted(x1, p), op(x1, p), rtol=2e-5, atol=2e-5)
    jitted(x2, p)
    assert len(traces) == 1


@pytest.mark.parametrize("name", OPS)
@pytest.mark.parametrize("dtype", [jnp.complex64, jnp.complex128])
def test_dtype_follows_input(rng, name, dtype):
    # parameters of the other precision are cast to the input's; eval_shape traces without compiling
    low = {jnp.dtype("complex128"): jnp.complex64, jnp.dtype("float64"): jnp.float32}
    cast = (lambda d: low[d]) if dtype == jnp.complex128 else (lambda d: d)
    params = jax.tree.map(
        lambda a: jax.ShapeDtypeStruct(a.shape, cast(a.dtype)), _params(name, jnp.complex128)
    )
    assert jax.eval_shape(OPS[name][0], _x(rng, name, dtype), params).dtype == dtype


@pytest.mark.parametrize("name", OPS)
def test_rotation_equivariance(rng, name):
    # a common rotation of all channels of a vertex (for set ops: of a whole set)
    p = _params(name, jnp.complex128)
    x = _x(rng, name)
    alpha = rng.uniform(-np.pi, np.pi, x.shape[0])
    rot = np.exp(1j * alpha).reshape((-1,) + (1,) * (x.ndim - 1))
    y = JITTED[name](x, p)
    assert rel_err(JITTED[name](x * rot, p), y * rot) < 1e-12


@pytest.mark.parametrize("name", OPS)
def test_check_grads_at_random_and_at_zero_features(rng, name):
    # complex input checked through its real and imaginary parts; at exactly x = 0 the values and
    # gradients must be finite (jax_debug_nans raises on any NaN) and still match finite differences
    p = _params(name, jnp.complex128)
    op = OPS[name][0]

    def f(xr, xi):
        y = op(jax.lax.complex(xr, xi), p)
        return jnp.concatenate([y.real.ravel(), y.imag.ravel()])

    f = jax.jit(f)
    x = np.asarray(_x(rng, name))
    # near 0 the ops vary on the scale sqrt(δ) ~ 1e-3 (δ = 1e-6), and at random points a VN direction
    # k may be small: finite differences use small steps (truncation ~eps², round-off ~1e-16/eps).
    # The block chains two layer norms (gain up to 1/sqrt(δ) each) and VN layers, which shrinks that
    # scale below 1e-10: at 0 only its finiteness is checked (the gradient is ~1e7 there, but finite).
    for point, eps, at_zero in ((x, 1e-6, False), (np.zeros_like(x), 1e-8, True)):
        assert np.all(np.isfinite(np.asarray(f(point.real, point.imag))))
        if at_zero and name == "block":
            grads = jax.jit(jax.grad(lambda a, b: jnp.sum(jnp.sin(f(a, b))), argnums=(0, 1)))(
                point.real, point.imag
            )
            assert all(np.all(np.isfinite(np.asarray(g))) for g in grads)
            continue
        check_grads(
            f, (point.real, point.imag), order=1, modes=("rev",), atol=1e-5, rtol=1e-5, eps=eps
        )


def test_parameter_gradients_finite_at_zero_features():
    x0 = jnp.zeros((2, S, C), jnp.complex128)

    def loss(p):
        out = vn_transformer_block(x0, p, mask=np.stack([MASK, MASK]))
        out = out + filter_response_norm(x0[0], _params("frn", jnp.complex128), area=AREA)[None]
        return jnp.sum(out.real * 0.7 + out.imag * 1.3)

    for g in jax.tree.leaves(jax.jit(jax.grad(loss))(_params("block", jnp.complex128))):
        assert np.all(np.isfinite(np.asarray(g)))


# ----------------------------------------------------------------------------- hand cases


def test_complex_linear_hand_case():
    x = jnp.array([[1 + 1j, 2.0, -1j]])
    w = jnp.array([[1.0, 1j], [0.5j, 0.0], [2.0, 1.0]])
    np.testing.assert_allclose(
        complex_linear(x, w), [[(1 + 1j) + 1j - 2j, (1 + 1j) * 1j - 1j]], rtol=1e-15
    )


def test_vn_is_vector_neuron_relu_far_from_zero():
    # q = x, k = x U with U = -1 (k opposite to q): <q, k> = -|x|^2 << 0, so y ≈ q - <q,k>/|k|^2 k = 0;
    # exactly, SiLU(900) = 900 (to 1e-390) and y = x (1 - 900 / (900 + δ))
    p = VNParams(weight=None, direction=-jnp.eye(1, dtype=jnp.complex128))
    x = jnp.array([[30 * np.exp(0.4j)]])
    y = vn_nonlinearity(
        x, p, delta=1e-6
    )  # ~3e-8; the subtraction q - q(1 - 1e-9) costs ~1e-15 absolute
    np.testing.assert_allclose(y, x * (1 - 900 / (900 + 1e-6)), rtol=0, atol=1e-13)
    # k aligned with q: <q, k> >> 0 and y ≈ q
    p = VNParams(weight=None, direction=jnp.eye(1, dtype=jnp.complex128))
    np.testing.assert_allclose(vn_nonlinearity(x, p), x, rtol=1e-12)
    # k orthogonal to q: <q, k> = 0, SiLU(0) = 0, y = q exactly
    p = VNParams(weight=None, direction=1j * jnp.eye(1, dtype=jnp.complex128))
    np.testing.assert_allclose(vn_nonlinearity(x, p), x, rtol=1e-15)


def test_frn_hand_case_and_padding_invariance(rng):
    x = jnp.array([[3 + 4j], [0j], [1e6 + 0j]])
    p = FRNParams(scale=jnp.array([2.0]), eps=jnp.array([-0.25]))  # |eps| is used
    y = filter_response_norm(
        x, p, area=jnp.array([1.0, 3.0, 5.0]), vertex_mask=jnp.array([True, True, False]), delta=0.5
    )
    # nu^2 = (1*25 + 3*0) / 4 = 6.25, factor = 2 / sqrt(6.25 + 0.5 + 0.25) = 2 / sqrt(7)
    np.testing.assert_allclose(y[:2], [[(3 + 4j) * 2 / np.sqrt(7)], [0]], rtol=1e-15)
    # padding with pad_to-style zero-area, masked vertices leaves the real vertices unchanged
    x = crandn(rng, S, C)
    p = _params("frn", jnp.complex128)
    y = filter_response_norm(x, p, area=AREA, vertex_mask=MASK)
    x_pad = np.concatenate([x, 1e4 * crandn(rng, 3, C)])
    y_pad = filter_response_norm(
        x_pad,
        p,
        area=np.concatenate([AREA, np.zeros(3)]),
        vertex_mask=np.concatenate([MASK, np.zeros(3, bool)]),
    )
    assert rel_err(y_pad[:S], y) < 1e-14


def test_frn_vmap_over_padded_batch(rng):
    p = _params("frn", jnp.complex128)
    sizes = (3, S)
    xs = [crandn(rng, n, C) for n in sizes]
    areas = [rng.uniform(0.5, 2.0, n) for n in sizes]
    pad = lambda a, n: np.concatenate([a, np.zeros((S - n,) + a.shape[1:], a.dtype)])  # noqa: E731
    xb = np.stack([pad(x, n) for x, n in zip(xs, sizes, strict=False)])
    ab = np.stack([pad(a, n) for a, n in zip(areas, sizes, strict=False)])
    mb = np.stack([np.arange(S) < n for n in sizes])
    yb = jax.jit(jax.vmap(lambda x, a, m: filter_response_norm(x, p, area=a, vertex_mask=m)))(
        xb, ab, mb
    )
    for i, (x, a) in enumerate(zip(xs, areas, strict=False)):
        assert rel_err(yb[i, : len(x)], filter_response_norm(x, p, area=a)) < 1e-14


def test_layer_norm_hand_case():
    y = complex_layer_norm(jnp.array([[3 + 4j, 0j]]), jnp.array([1.0, 1.0]), delta=1e-300)
    np.testing.assert_allclose(y, [[(3 + 4j) / np.sqrt(12.5), 0]], rtol=1e-14)


# ----------------------------------------------------------------------------- attention and block


@pytest.mark.parametrize("name", ["attention", "block"])
def test_permutation_equivariance_and_masked_padding(rng, name):
    p = _params(name, jnp.complex128)
    f = JITTED[name]  # masks the fourth element of the first set
    x = np.asarray(_x(rng, name))
    perm = rng.permutation(S)
    x_perm = x.copy()
    x_perm[1] = x[1, perm]  # permute the unmasked set
    assert rel_err(f(x_perm, p)[1], f(x, p)[1, perm]) < 1e-12
    # three garbage elements appended to each set behind a False mask change nothing
    op = complex_attention if name == "attention" else vn_transformer_block
    g = jax.jit(lambda x, p, m: op(x, p, mask=m))
    mask = np.stack([MASK, np.ones(S, bool)])
    x_pad = np.concatenate([x, 1e3 * crandn(rng, 2, 3, C)], axis=1)
    mask_pad = np.concatenate([mask, np.zeros((2, 3), bool)], axis=1)
    assert rel_err(g(x_pad, p, mask_pad)[:, :S], f(x, p)) < 1e-12
    # a fully masked set gives exactly zero attention output
    if name == "attention":
        np.testing.assert_array_equal(np.asarray(g(x, p, np.zeros((2, S), bool))), 0)


def test_attention_vmap_matches_loop(rng):
    p = _params("attention", jnp.complex128)
    xb = crandn(rng, 3, 2, S, C)
    yb = jax.jit(jax.vmap(lambda x: complex_attention(x, p)))(xb)
    for i in range(3):
        assert rel_err(yb[i], ref_attention(xb[i], p)) < 1e-12


# ----------------------------------------------------------------------------- errors


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_bad_inputs_raise_typed_errors():
    x = jnp.ones((2, C), jnp.complex64)
    attention = _params("attention", jnp.complex64)
    with pytest.raises(InputError, match="complex"):
        complex_linear(jnp.ones((2, C)), jnp.ones((C, 2), jnp.complex64))
    with pytest.raises(InputError, match="channels"):
        complex_linear(x, jnp.ones((C + 1, 2), jnp.complex64))
    with pytest.raises(ConfigError, match="delta"):
        vn_nonlinearity(x, _params("vn", jnp.complex64), delta=0.0)
    with pytest.raises(InputError, match="weight=None"):
        vn_nonlinearity(x, VNParams(None, jnp.ones((C, 3), jnp.complex64)))
    with pytest.raises(InputError, match="area"):
        filter_response_norm(x, _params("frn", jnp.complex64), area=jnp.ones(3))
    with pytest.raises(InputError, match="mask"):
        complex_attention(x[None], attention, mask=jnp.ones((1, 3), bool))
    with pytest.raises(ConfigError, match="divisible"):
        init_complex_attention(jax.random.key(0), 5, num_heads=2)
    with pytest.raises(InputError, match="value"):
        p = attention
        complex_attention(x[None], ComplexAttentionParams(p.query, p.key, p.value[:, :1], p.out))


# ----------------------------------------------------------------------------- optax


def test_conjugated_gradient_is_steepest_ascent():
    # L(w) = |w - t|^2 has steepest ascent dL/da + i dL/db = 2 (w - t)
    t = 1.5 - 0.5j
    g = jax.grad(lambda w: jnp.abs(w - t) ** 2)(jnp.array(0.2 + 0.1j))
    np.testing.assert_allclose(conjugate_complex_grads(g), 2 * ((0.2 + 0.1j) - t), rtol=1e-14)
    tree = {"w": g, "b": jnp.array(3.0), "n": None}
    out = conjugate_complex_grads(tree)
    assert out["b"] == 3.0 and out["n"] is None


def test_adam_step_on_complex_least_squares_decreases_loss(rng):
    a = jnp.asarray(crandn(rng, 12, 4))
    b = jnp.asarray(crandn(rng, 12))
    loss = jax.jit(lambda w: jnp.sum(jnp.abs(a @ w - b) ** 2))
    w0 = jnp.zeros(4, jnp.complex128)
    opt = optax.adam(0.05)
    # optax divides complex moments by real ones: not allowed under this suite's strict promotion
    with jax.numpy_dtype_promotion("standard"):
        state = opt.init(w0)
        updates, _ = opt.update(conjugate_complex_grads(jax.grad(loss)(w0)), state, w0)
        assert loss(optax.apply_updates(w0, updates)) < loss(w0)
        # and many steps converge to the least-squares solution
        w, state = w0, opt.init(w0)
        step = jax.jit(lambda w, s: opt.update(conjugate_complex_grads(jax.grad(loss)(w)), s, w))
        for _ in range(400):
            updates, state = step(w, state)
            w = optax.apply_updates(w, updates)
    w_star = np.linalg.lstsq(np.asarray(a), np.asarray(b), rcond=None)[0]
    assert np.linalg.norm(np.asarray(w) - w_star) < 1e-2

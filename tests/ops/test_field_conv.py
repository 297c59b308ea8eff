"""Field convolution: hand cases, a slow loop reference, exact gauge equivariance (and the printed
eq. 34 as a negative control), padding, batching, jit, dtypes, zero features and gradients."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jmeshtex import ConfigError, InputError
from jmeshtex.data import grid
from jmeshtex.geometry import VertexNeighborhood, pad_to, to_jax
from jmeshtex.ops import (
    FieldConvParams,
    _field_conv_fast,
    _field_conv_terms,
    field_conv,
    field_conv_filter_sums,
    field_conv_mix,
    field_conv_responses,
    field_conv_terms,
)
from jmeshtex.ops._field_conv_stages import _filtered_sums
from tests._random_fields import (
    crandn,
    field_conv_params,
    gauge_transform,
    random_nbhd,
    rel_err,
    silu,
)

_conv = jax.jit(field_conv, static_argnames=("delta", "activation"))
# one shape for most tests (V vertices, K slots, C -> D channels, H responses, E embedding): the
# jitted op then compiles once per dtype / activation instead of once per test
V, K, C, D, H, E = 6, 4, 2, 3, 3, 1


@functools.cache
def make_params(seed, e=E, c=C, d=D, h=H, dtype=jnp.complex128):
    """Parameters distributed like init_field_conv (which has its own doctest): no compilation."""
    return field_conv_params(seed, e=e, c=c, d=d, h=h, dtype=dtype)


def grid_nbhd(n):
    """The 3×3 stencil on the flat n×n grid of `jmeshtex.data.grid` (parallel diagonals): k-NN with a self
    slot; log = planar offset, transport = 1, weight = barycentric vertex area."""
    verts, faces = grid(n, diagonals="uniform")
    v = len(verts)
    e0, e1 = verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]]
    fa = 0.5 * np.linalg.norm(np.cross(e0, e1), axis=1)
    area = np.zeros(v)
    np.add.at(area, faces.ravel(), np.repeat(fa / 3, 3))
    pos = verts[:, 0] + 1j * verts[:, 1]
    step = np.min(np.abs(pos[1:] - pos[0]))
    ij = np.round(np.stack([pos.real, pos.imag], 1) / step).astype(int)
    lookup = {tuple(t): i for i, t in enumerate(ij)}
    offsets = [(0, 0)] + [(a, b) for a in (-1, 0, 1) for b in (-1, 0, 1) if (a, b) != (0, 0)]
    index = np.array(
        [[lookup.get((i + a, j + b), -1) for a, b in offsets] for i, j in ij]
    )  # host set-up only
    mask = index >= 0
    index = np.where(mask, index, 0)
    log = np.where(mask, pos[index] - pos[:, None], 0)
    return VertexNeighborhood(
        index=index.astype(np.int32),
        mask=mask,
        log=log,
        transport=np.ones(index.shape, complex),
        weight=np.where(mask, area[index], 0.0),
        area=area,
        vertex_mask=np.ones(v, bool),
    )


def loop_reference(x, nb, params, emb=None, delta=1e-4, printed_eq34=False, activation="silu"):
    """Slow NumPy field convolution, one (vertex, slot, channel) at a time.

    ``printed_eq34`` pairs log_p(q) with x̂_q in q's own frame (no transport inside the filter).
    """
    x = np.asarray(x, complex)
    a_w, b, mix = (np.asarray(t) for t in params[:3])
    v, c = x.shape
    y = np.zeros((v, mix.shape[2]), complex)
    for p in range(v):
        wsum = sum(nb.weight[p, k] for k in range(nb.index.shape[1]) if nb.mask[p, k])
        for k in range(nb.index.shape[1]):
            if not nb.mask[p, k]:
                continue
            q, rho, w = nb.index[p, k], nb.transport[p, k], nb.weight[p, k] / wsum
            for ch in range(c):
                u = rho * x[q, ch]
                direction = x[q, ch] if printed_eq34 else u
                a = nb.log[p, k] * np.conj(direction / np.sqrt(abs(direction) ** 2 + delta**2))
                inp = np.concatenate([[a.real, a.imag], [] if emb is None else emb[p]])
                pre = inp @ a_w + b
                phi = silu(pre) if activation == "silu" else np.maximum(pre, 0)
                y[p] += w * u * (phi @ mix[ch])
    return y


# ----------------------------------------------------------------------------- exact cases


def test_hand_case_single_transported_neighbour():
    # vertex 0 sees vertex 1 one unit east; 1's frame is turned so that ρ = i; x_1 = 1 in 1's frame.
    # u = i, û ≈ i, a = 1 · conj(i) = -i  =>  φ = SiLU(Im a) = SiLU(-1), y_0 = u φ.
    nb = VertexNeighborhood(
        index=np.array([[1], [0]], np.int32),
        mask=np.array([[True], [False]]),
        log=np.array([[1.0 + 0j], [0j]]),
        transport=np.array([[1j], [1 + 0j]]),
        weight=np.array([[2.0], [0.0]]),
        area=np.ones(2),
        vertex_mask=np.ones(2, bool),
    )
    params = FieldConvParams(np.array([[0.0], [1.0]]), np.zeros(1), np.ones((1, 1, 1), complex))
    y = _conv(jnp.array([[0j], [1 + 0j]]), nb, params, delta=1e-9)
    np.testing.assert_allclose(np.asarray(y), [[1j * silu(-1.0)], [0]], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("activation", ["silu", "relu"])
def test_matches_loop_reference(rng, activation):
    nb = random_nbhd(rng, V, K)
    x = crandn(rng, V, C)
    x[2, 1] = 0  # one exact zero feature
    emb = rng.standard_normal((V, E))
    params = make_params(1)
    got = _conv(jnp.asarray(x), nb, params, embedding=emb, activation=activation)
    assert rel_err(got, loop_reference(x, nb, params, emb, activation=activation)) < 1e-12


@pytest.mark.parametrize("activation", ["silu", "relu"])
def test_public_stages_compose_to_field_conv(rng, activation):
    """terms -> filter sums -> mix is field_conv, and the filter sums are Σ_k z φ with the responses."""
    nb = random_nbhd(rng, V, K)
    x = jnp.asarray(crandn(rng, V, C))
    emb = rng.standard_normal((V, E))
    params = make_params(3)
    terms = field_conv_terms(x, nb)
    sums = field_conv_filter_sums(terms, params, embedding=emb, activation=activation)
    y = field_conv_mix(sums, params)
    assert rel_err(y, _conv(x, nb, params, embedding=emb, activation=activation)) < 1e-12
    phi = field_conv_responses(
        terms.arg_real, terms.arg_imag, params, embedding=emb, activation=activation
    )
    assert phi.shape == (V, K, H, C)
    np.testing.assert_allclose(
        sums[0], jnp.einsum("vkc,vkhc->vhc", terms.z_real, phi), rtol=1e-12, atol=1e-14
    )
    np.testing.assert_allclose(
        sums[1], jnp.einsum("vkc,vkhc->vhc", terms.z_imag, phi), rtol=1e-12, atol=1e-14
    )


def test_matches_loop_reference_without_embedding(rng):
    nb = random_nbhd(rng, V, K, self_slot=False)  # a one-ring-like neighbourhood: no self slot
    x = crandn(rng, V, C)
    params = make_params(12, e=0)
    assert rel_err(_conv(jnp.asarray(x), nb, params), loop_reference(x, nb, params)) < 1e-12


def test_flat_grid_constant_field_gives_constant_interior_output():
    # on the flat grid every vertex away from the boundary sees the same stencil with the same areas,
    # so a constant field (transport 1) must give the same output at all of them
    nb = grid_nbhd(6)
    params = make_params(2, e=0)
    x = jnp.tile(jnp.array([[1 + 2j, -0.5j]]), (len(nb.area), 1))
    y = np.asarray(_conv(x, nb, params))
    interior = nb.mask[nb.index].all(axis=(1, 2))  # the whole stencil is interior
    assert interior.sum() == 9
    np.testing.assert_allclose(
        y[interior], np.broadcast_to(y[interior][0], y[interior].shape), rtol=1e-12
    )
    assert rel_err(y, loop_reference(np.asarray(x), nb, params)) < 1e-12


# ----------------------------------------------------------------------------- equivariance


def _gauge_error(fn, x, nb, alpha, emb):
    y = fn(x, nb, emb)
    x2, nb2 = gauge_transform(x, nb, alpha)
    y2 = fn(x2, nb2, emb)
    return rel_err(y2, y * np.exp(-1j * alpha)[:, None])


@pytest.mark.parametrize("activation", ["silu", "relu"])
def test_gauge_equivariance_exact(rng, activation):
    nb = random_nbhd(rng, V, K)
    x, emb = crandn(rng, V, C), rng.standard_normal((V, E))
    alpha = rng.uniform(-np.pi, np.pi, V)
    params = make_params(3)

    def fn(a, n, e):
        return np.asarray(_conv(jnp.asarray(a), n, params, embedding=e, activation=activation))

    assert _gauge_error(fn, x, nb, alpha, emb) < 1e-12


def test_printed_eq34_argument_is_not_gauge_equivariant(rng):
    # negative control: the same harness flags the printed argument log_p(q)·conj(x̂_q), x̂_q in q's frame
    nb = random_nbhd(rng, V, K)
    x, emb = crandn(rng, V, C), rng.standard_normal((V, E))
    alpha = rng.uniform(-np.pi, np.pi, V)
    params = make_params(4)
    gathering = _gauge_error(lambda a, n, e: loop_reference(a, n, params, e), x, nb, alpha, emb)
    printed = _gauge_error(
        lambda a, n, e: loop_reference(a, n, params, e, printed_eq34=True), x, nb, alpha, emb
    )
    assert gathering < 1e-12
    assert printed > 1e-2


# ----------------------------------------------------------------------------- padding, batching, jit


def test_filter_responses_are_silu_to_float32_accuracy():
    # the evaluation path's SiLU, q (1 + tanh q) with q = p / 2 folded into the weights, against a
    # float64 SiLU: absolute error at float32 level over [-30, 30] (jax.nn.silu's own: 1.9e-6)
    p = np.linspace(-30.0, 30.0, 600_001)
    ar = jnp.asarray(p, jnp.float32).reshape(1, 1, -1)  # one vertex, one slot, C = len(p)
    a_w, bias = jnp.array([[1.0], [0.0]], jnp.float32), jnp.zeros((1, 1), jnp.float32)
    got = np.asarray(
        _field_conv_terms.responses(ar, jnp.zeros_like(ar), a_w, bias, "silu"), np.float64
    ).ravel()
    want = p / (1.0 + np.exp(-p))
    assert np.max(np.abs(got - want)) < 4e-6
    relu = np.asarray(
        _field_conv_terms.responses(ar, jnp.zeros_like(ar), a_w, bias, "relu"), np.float64
    ).ravel()
    np.testing.assert_array_equal(relu, np.maximum(np.asarray(ar, np.float64).ravel(), 0))


@pytest.mark.parametrize("activation", ["silu", "relu"])
def test_vertex_blocks_match_loop_reference_and_reverse_mode_path(rng, monkeypatch, activation):
    # evaluation runs in vertex blocks (the last one overlapping the one before); reverse mode's
    # primal too. Blocks of 4 on 11 vertices: three blocks, padded slots, and under vmap.
    monkeypatch.setattr(_field_conv_fast, "BLOCK", 4)
    v = 11
    nbs = [random_nbhd(rng, v, K) for _ in range(2)]
    xs, embs = [crandn(rng, v, C) for _ in nbs], [rng.standard_normal((v, E)) for _ in nbs]
    params = make_params(3)
    conv = jax.jit(functools.partial(field_conv, activation=activation))
    for nb, x, emb in zip(nbs, xs, embs, strict=True):
        want = loop_reference(x, nb, params, emb, activation=activation)
        assert rel_err(conv(jnp.asarray(x), nb, params, embedding=emb), want) < 1e-12
        # the reverse-mode path's primal: the output of jax.vjp
        y, _ = jax.vjp(
            lambda a, nb=nb, emb=emb: field_conv(
                a, nb, params, embedding=emb, activation=activation
            ),
            jnp.asarray(x),
        )
        assert rel_err(y, want) < 1e-12
    batch = jax.tree.map(lambda *a: np.stack(a), *nbs)
    yb = jax.jit(
        jax.vmap(lambda a, n, e: field_conv(a, n, params, embedding=e, activation=activation))
    )(jnp.asarray(np.stack(xs)), batch, np.stack(embs))
    for i, (nb, x, emb) in enumerate(zip(nbs, xs, embs, strict=True)):
        assert rel_err(yb[i], loop_reference(x, nb, params, emb, activation=activation)) < 1e-12


def test_padding_invariance(rng):
    nb = random_nbhd(rng, V, K)
    params = make_params(5)
    x, emb = crandn(rng, V, C), rng.standard_normal((V, E))
    y = _conv(jnp.asarray(x), nb, params, embedding=emb)
    padded = pad_to(nb, {"V": V + 3, "K": K + 3})
    x_pad = np.concatenate([x, 1e3 * crandn(rng, 3, C)])  # garbage on padded vertices
    emb_pad = np.concatenate([emb, 1e3 * rng.standard_normal((3, E))])
    y_pad = _conv(jnp.asarray(x_pad), padded, params, embedding=emb_pad)
    assert rel_err(y_pad[:V], y) < 1e-13
    # a padded vertex has no valid slot: its output is 0
    np.testing.assert_array_equal(np.asarray(y_pad[V:]), 0)


def test_vmap_over_padded_batch(rng):
    nbs = [random_nbhd(rng, V - 2, K - 1), random_nbhd(rng, V, K)]
    xs = [crandn(rng, V - 2, C), crandn(rng, V, C)]
    embs = [rng.standard_normal((V - 2, E)), rng.standard_normal((V, E))]
    params = make_params(6)
    batch = jax.tree.map(lambda *a: np.stack(a), *[pad_to(n, {"V": V, "K": K}) for n in nbs])
    xb = np.stack([np.concatenate([xs[0], np.zeros((2, C))]), xs[1]])
    eb = np.stack([np.concatenate([embs[0], np.zeros((2, E))]), embs[1]])
    yb = jax.jit(jax.vmap(lambda a, n, e: field_conv(a, n, params, embedding=e)))(
        jnp.asarray(xb), batch, eb
    )
    for i, (n, a, e) in enumerate(zip(nbs, xs, embs, strict=False)):
        assert rel_err(yb[i, : len(a)], _conv(jnp.asarray(a), n, params, embedding=e)) < 1e-13

    # and the parameter gradient of the batched loss is the sum of the per-mesh gradients
    def batched(p):
        y = jax.vmap(lambda a, n, e: field_conv(a, n, p, embedding=e))(jnp.asarray(xb), batch, eb)
        return jnp.sum(jnp.abs(y[0, : V - 2]) ** 2) + jnp.sum(jnp.abs(y[1]) ** 2)

    def separate(p):
        return sum(
            jnp.sum(jnp.abs(field_conv(a, n, p, embedding=e)) ** 2)
            for n, a, e in zip(nbs, xs, embs, strict=True)
        )

    for g, r in zip(
        jax.tree.leaves(jax.jit(jax.grad(batched))(params)),
        jax.tree.leaves(jax.jit(jax.grad(separate))(params)),
        strict=True,
    ):
        np.testing.assert_allclose(g, r, rtol=1e-12, atol=1e-12)


def test_jit_matches_eager_without_recompiling(rng):
    # tiny shapes: the eager reference call compiles every primitive separately
    nb = to_jax(random_nbhd(rng, 3, 2), jnp.float32)
    p = make_params(7, e=0, c=1, d=2, h=2, dtype=jnp.complex64)
    x1, x2 = (jnp.asarray(crandn(rng, 3, 1), jnp.complex64) for _ in range(2))
    traces = []

    def fn(a, n):
        traces.append(1)
        return field_conv(a, n, p)

    jitted = jax.jit(fn)
    np.testing.assert_allclose(jitted(x1, nb), field_conv(x1, nb, p), rtol=1e-5, atol=1e-6)
    jitted(x2, nb)
    assert len(traces) == 1  # traced once for both calls (the eager call does not go through fn)


@pytest.mark.parametrize("real", [jnp.float32, jnp.float64])
def test_dtype_follows_input(rng, real):
    cplx = jnp.complex64 if real == jnp.float32 else jnp.complex128
    nb = to_jax(random_nbhd(rng, V, K), real)
    p = make_params(8, dtype=jnp.complex64)  # complex64 / float32 parameters
    y = _conv(jnp.asarray(crandn(rng, V, C), cplx), nb, p, embedding=jnp.ones((V, E), jnp.float32))
    assert y.dtype == cplx


# ----------------------------------------------------------------------------- zero features, gradients


def test_zero_features_finite_values_and_gradients(rng):
    nb = random_nbhd(rng, V, K)
    params = make_params(9)
    emb = rng.standard_normal((V, E))
    x0 = jnp.zeros((V, C), jnp.complex128)
    np.testing.assert_array_equal(np.asarray(_conv(x0, nb, params, embedding=emb)), 0)

    def loss(x, p):
        y = field_conv(x, nb, p, embedding=emb)
        return jnp.sum(y.real * 0.3 - y.imag * 1.7)

    gx, gp = jax.jit(jax.grad(loss, argnums=(0, 1)))(x0, params)
    for g in jax.tree.leaves((gx, gp)):
        assert np.all(np.isfinite(np.asarray(g)))
    assert np.abs(np.asarray(gx)).max() > 0  # the output does depend on x at 0


def _real_view(nb, activation):
    """field_conv as a function of real arrays only (check_grads perturbs real and imaginary parts)."""

    def f(xr, xi, a_w, a_b, mr, mi, e):
        params = FieldConvParams(a_w, a_b, jax.lax.complex(mr, mi))
        y = field_conv(jax.lax.complex(xr, xi), nb, params, embedding=e, activation=activation)
        return jnp.concatenate([y.real, y.imag])

    return f


def _grad_args(rng):
    p = make_params(10, c=2, d=2, h=3)
    x, emb = crandn(rng, 4, 2), rng.standard_normal((4, 1))
    return (x.real, x.imag, p.filter_weight, p.filter_bias, p.mix.real, p.mix.imag, emb)


@pytest.mark.parametrize("activation", ["silu", "relu"])
def test_check_grads_real_and_imaginary_parts(rng, activation):
    # forward and reverse mode of the jitted op, every argument (x, filter, mix, embedding)
    f = _real_view(random_nbhd(rng, 4, 3), activation)
    # small step: ReLU filters have kinks, which a step of 1e-6 reaches with probability ~1e-4
    check_grads(
        jax.jit(f), _grad_args(rng), order=1, modes=("fwd", "rev"), atol=1e-5, rtol=1e-5, eps=1e-6
    )


def test_fused_filter_sums_differentiate_as_the_plain_formula_to_second_order(rng):
    # the fused filter-sum stage (custom_jvp) against plain autodiff of the straightforward sums:
    # first order (VJP) and second order (reverse over reverse). SiLU: the ReLU path shares the code
    # and has no second-order terms; its first order is covered by check_grads above.
    activation = "silu"
    args = [rng.standard_normal((3, 2, 2)) for _ in range(4)] + [
        rng.standard_normal((2, 3)),
        rng.standard_normal((3, 3)),
    ]
    w = rng.standard_normal((3, 2, 3, 2))

    def loss(core):
        return lambda *a: jnp.sum(w * jnp.stack(core(*a, activation), axis=1))

    def second(core):  # d/d(args) of <v, grad loss>
        v = [np.cos(np.arange(a.size).reshape(a.shape)) for a in args]
        return jax.grad(
            lambda *a: sum(
                jnp.sum(g * t)
                for g, t in zip(jax.grad(loss(core), argnums=range(6))(*a), v, strict=False)
            ),
            argnums=range(6),
        )

    for order in (lambda core: jax.grad(loss(core), argnums=range(6)), second):
        got = jax.jit(order(_filtered_sums))(*args)
        want = jax.jit(order(_field_conv_terms.filtered_sums_plain))(*args)
        for g, r in zip(got, want, strict=False):
            np.testing.assert_allclose(g, r, rtol=1e-12, atol=1e-12)


# ----------------------------------------------------------------------------- errors


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_bad_inputs_raise_typed_errors(rng):
    nb = random_nbhd(rng, 4, 3)
    p = make_params(11, c=2, d=2, h=3, dtype=jnp.complex64)
    x = jnp.asarray(crandn(rng, 4, 2), jnp.complex64)
    with pytest.raises(InputError, match="complex"):
        field_conv(x.real, nb, p, embedding=jnp.ones((4, 1)))
    with pytest.raises(ConfigError, match="activation"):
        field_conv(x, nb, p, embedding=jnp.ones((4, 1)), activation="tanh")
    with pytest.raises(InputError, match="embedding=None"):
        field_conv(x, nb, p)
    with pytest.raises(InputError, match="embedding must have shape"):
        field_conv(x, nb, p, embedding=jnp.ones((4, 2)))
    with pytest.raises(InputError, match="vertices"):
        field_conv(x[:3], nb, p, embedding=jnp.ones((3, 1)))
    with pytest.raises(InputError, match="mix"):
        field_conv(jnp.ones((4, 5), jnp.complex64), nb, p, embedding=jnp.ones((4, 1)))
    with pytest.raises(ConfigError, match="delta"):
        field_conv(x, nb, p, embedding=jnp.ones((4, 1)), delta=0.0)


# ----------------------------------------------------------------------------- reverse mode against autodiff


def plain_formula(x, nb, params, emb=None, chan=None, activation="silu", delta=1e-4):
    """The fast path's formula in plain jnp, everything materialised (the autodiff oracle)."""
    w = jnp.where(jnp.asarray(nb.mask), jnp.asarray(nb.weight), 0.0)
    w = w / jnp.sum(w, axis=1, keepdims=True)
    u = jnp.asarray(nb.transport)[..., None] * x[jnp.asarray(nb.index)]  # [V, K, C]
    norm = jnp.sqrt(u.real**2 + u.imag**2 + delta**2).astype(u.dtype)
    a = jnp.asarray(nb.log)[..., None] * jnp.conj(u) / norm
    a_w = params.filter_weight
    pre = (
        a.real[..., None] * a_w[0] + a.imag[..., None] * a_w[1] + params.filter_bias
    )  # [V, K, C, H]
    if emb is not None:
        pre = pre + (emb @ a_w[2:])[:, None, None, :]
    if chan is not None:
        pre = pre + chan[:, None, :, None] * params.channel_weight
    phi = jax.nn.silu(pre) if activation == "silu" else jnp.maximum(pre, 0)
    return jnp.einsum(
        "vkc,vkch,chd->vd", w[..., None].astype(u.dtype) * u, phi.astype(u.dtype), params.mix
    )


@pytest.mark.parametrize("activation", ["silu", "relu"])
@pytest.mark.parametrize("channel", [False, True], ids=["embedding", "channel-embedding"])
def test_reverse_mode_matches_autodiff_of_the_plain_formula(rng, monkeypatch, activation, channel):
    # the blocked tangent, transposed (blocks of 4 on 11 vertices: the last block padded) against
    # jax.grad of the materialised formula, for x, every parameter and both embeddings, in float64
    monkeypatch.setattr(_field_conv_fast, "TANGENT_BLOCK", 4)
    v = 11
    nb = random_nbhd(rng, v, K)
    params = make_params(21)
    if channel:
        params = params._replace(channel_weight=rng.standard_normal(H) / 2)
    x, emb, chan = (
        jnp.asarray(crandn(rng, v, C)),
        jnp.asarray(rng.standard_normal((v, E))),
        jnp.asarray(rng.standard_normal((v, C))),
    )
    cot = jnp.asarray(crandn(rng, v, D))

    def loss(fn):
        def f(x, p, emb, chan):
            y = fn(x, p, emb, chan if channel else None)
            return jnp.sum(y.real * cot.real + y.imag * cot.imag)

        return jax.jit(jax.value_and_grad(f, argnums=(0, 1, 2, 3)))

    got = loss(
        lambda x, p, e, c: field_conv(
            x, nb, p, embedding=e, channel_embedding=c, activation=activation
        )
    )(x, params, emb, chan)
    want = loss(lambda x, p, e, c: plain_formula(x, nb, p, e, c, activation=activation))(
        x, params, emb, chan
    )
    leaves = jax.tree.leaves(want)
    assert (
        len(jax.tree.leaves(got)) == len(leaves) == (8 if channel else 7)
    )  # value, x, params, both embeddings
    for g, r in zip(jax.tree.leaves(got), leaves, strict=True):
        np.testing.assert_allclose(g, r, rtol=1e-10, atol=1e-12)
    assert (
        np.abs(np.asarray(got[1][0])).max() > 0
        and np.abs(np.asarray(got[1][1].filter_weight)).max() > 0
    )


def test_gradient_with_respect_to_the_neighbourhood_geometry(rng, monkeypatch):
    # the log maps, transports and weights get tangents too (blocks of 4 on 9 vertices)
    monkeypatch.setattr(_field_conv_fast, "TANGENT_BLOCK", 4)
    v = 9
    nb = random_nbhd(rng, v, K)
    params = make_params(22)
    x, emb, cot = (
        jnp.asarray(crandn(rng, v, C)),
        jnp.asarray(rng.standard_normal((v, E))),
        jnp.asarray(crandn(rng, v, D)),
    )

    def loss(fn):
        def f(log, transport, weight, x):
            y = fn(x, nb._replace(log=log, transport=transport, weight=weight))
            return jnp.sum(y.real * cot.real + y.imag * cot.imag)

        return jax.jit(jax.grad(f, argnums=(0, 1, 2, 3)))

    args = tuple(jnp.asarray(a) for a in (nb.log, nb.transport, nb.weight)) + (x,)
    got = loss(lambda x, n: field_conv(x, n, params, embedding=emb))(*args)
    want = loss(lambda x, n: plain_formula(x, n, params, emb))(*args)
    for g, r in zip(got, want, strict=True):
        np.testing.assert_allclose(g, r, rtol=1e-10, atol=1e-12)
    assert all(np.abs(np.asarray(g)).max() > 0 for g in got)


def test_nested_reverse_mode_matches_the_plain_formula(rng):
    # reverse over the transposed blocked tangent: a Hessian-vector product in x
    nb, params = random_nbhd(rng, V, K), make_params(23)
    emb, x, t = (
        rng.standard_normal((V, E)),
        jnp.asarray(crandn(rng, V, C)),
        jnp.asarray(crandn(rng, V, C)),
    )

    def hvp(fn):
        loss = lambda x: jnp.sum(jnp.abs(fn(x)) ** 2)  # noqa: E731
        return jax.jit(jax.grad(lambda x: jnp.sum((jax.grad(loss)(x) * jnp.conj(t)).real)))

    got = hvp(lambda x: field_conv(x, nb, params, embedding=emb))(x)
    want = hvp(lambda x: plain_formula(x, nb, params, jnp.asarray(emb)))(x)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-13)
    assert np.abs(np.asarray(want)).max() > 1e-3

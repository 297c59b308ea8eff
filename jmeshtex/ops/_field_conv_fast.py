"""The transported-argument field convolution (one or two hidden filter layers): a fused blocked
forward, and a ``custom_jvp`` whose tangent is plain JAX, linear in the tangents.

Forward: per block of :data:`BLOCK` vertices in one loop, gather → terms → fused filter sums →
mix, so a block's ``[B, K, C]`` terms and ``[B, H, C]`` sums stay in cache; with one hidden layer
no response is written to memory, with two the second layer's matrix product over the block's
first-layer responses is (:func:`~._field_conv_terms.filtered_sums_fused`).

Derivatives: the forward's fused reduction cannot be transposed by JAX, so it sits behind a
``jax.custom_jvp`` whose tangent is linear in the tangents and written in plain JAX, so every
transformation follows from JAX's own rules, in any order and under ``jax.jit``: ``jvp``,
``linearize``, ``jacfwd``, ``vmap``, reverse mode (``grad``, ``vjp``, ``jacrev``) as JAX's
transpose of the tangent, higher orders by re-entering the same rule (its primal output calls the
rule's own function). Inputs without a tangent arrive as symbolic zeros and cost nothing.

Which tangent: with the neighbourhood held fixed (the usual case), ``jax.linear_transpose`` of a
hand-written blocked VJP (:func:`blocked_vjp`), so reverse mode, JAX's transpose of that transpose,
runs the hand-written VJP itself (each block's responses recomputed and written once in cache, no
``V·K·H·C`` array stored); forward mode runs its transpose. For the output's tangent the mix is
folded into that VJP's blocks (each block forms its own ``∂S = ∂y Mᵀ``) and each block scatter-adds
its neighbours' feature cotangents, so no ``[V, 2·H·C]`` or ``[V, K, C]`` cotangent is written.
With a tangent on the neighbourhood's geometry, the forward-mode derivative of the plain formula
(:func:`sums_tangent_plain`, block by block under ``jax.checkpoint``). Reverse mode keeps the
forward's ``V·2·H·C`` filtered sums (transposed once) for the mix's gradient.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from jax.custom_derivatives import SymbolicZero

from ._field_conv_terms import (
    as_complex,
    bias3,
    filtered_sums_fused,
    filtered_sums_plain,
    from_blocks,
    gather_terms,
    mix_halves,
    mix_matrix,
    terms,
    to_blocks,
)

#: vertices per block of the forward; 256, 512 and 1024 are within 2% at 30K vertices
BLOCK = 512
#: vertices per block of the tangent: a block's ``[B, K, H, C]`` responses and derivatives in cache
TANGENT_BLOCK = 32


def conv_fast(x, index, slots, a_w, bias, mix, delta: float, activation: str, hidden=None):
    """``[V, D]`` complex outputs of the fast path (arguments after :func:`field_conv`'s checks).

    ``index [V, K]``, ``slots`` the five ``[V, K]`` real slot arrays, ``a_w [2, H]`` the filter rows
    acting on the argument, ``bias`` the pre-activation offsets ``[V, H]`` (or per channel
    ``[V, H, C]``), ``mix [C, H, D]``, ``hidden`` None or the second filter layer ``(W₂, b₂)``.
    """
    return as_complex(_conv(x, index, slots, a_w, bias, hidden, mix, delta, activation))


def blocked_forward(x, index, slots, a_w, bias, hidden, mix, delta, activation, *, keep_sums: bool):
    """Blocked forward: ``[V, 2D]`` real outputs (real block, imaginary block) and, with ``keep_sums``,
    the filtered sums ``[V, 2·H·C]`` (real part's ``(h, c)`` block, then the imaginary part's)."""
    v, d = x.shape[0], mix.shape[2]
    m_r, m_i = mix_halves(mix)
    xr, xi = x.real, x.imag

    def block(idx, sl, b):
        zr, zi, ar, ai = gather_terms(xr, xi, idx, sl, delta, blocked=True)
        s_r, s_i = filtered_sums_fused(zr, zi, ar, ai, a_w, b, activation, hidden)
        n = s_r.shape[0]
        s_r, s_i = s_r.reshape(n, -1), s_i.reshape(n, -1)
        y = s_r @ m_r + s_i @ m_i
        return (y, jnp.concatenate([s_r, s_i], axis=1)) if keep_sums else (y,)

    if v <= BLOCK:
        out = block(index, slots, bias)
    else:

        def body(i, out):
            start = jnp.minimum(i * BLOCK, v - BLOCK)  # the last block overlaps the one before it
            part = block(
                *jax.tree.map(
                    lambda a: jax.lax.dynamic_slice_in_dim(a, start, BLOCK, axis=0),
                    (index, slots, bias),
                )
            )
            return tuple(
                jax.lax.dynamic_update_slice_in_dim(o, q, start, axis=0)
                for o, q in zip(out, part, strict=True)
            )

        shapes = [(v, 2 * d)] + ([(v, 2 * mix.shape[0] * mix.shape[1])] if keep_sums else [])
        out = jax.lax.fori_loop(
            0, -(-v // BLOCK), body, tuple(jnp.zeros(t, xr.dtype) for t in shapes)
        )
    return out if keep_sums else out[0]


@functools.partial(jax.custom_jvp, nondiff_argnums=(7, 8))
def _conv(x, index, slots, a_w, bias, hidden, mix, delta, activation):
    return blocked_forward(
        x, index, slots, a_w, bias, hidden, mix, delta, activation, keep_sums=False
    )


@functools.partial(jax.custom_jvp, nondiff_argnums=(7, 8))
def _conv_and_sums(x, index, slots, a_w, bias, hidden, mix, delta, activation):
    return blocked_forward(
        x, index, slots, a_w, bias, hidden, mix, delta, activation, keep_sums=True
    )


def _mix_tangent(sums, dmix):
    """``S Ṁ`` (``[V, 2D]`` real), from the sums transposed once behind a barrier: reverse mode
    then forms ``∂M = Sᵀ ∂y`` from ``[2·H·C, V]`` rows, which XLA's CPU multiplies faster than
    the same product contracted over ``S``'s leading axis (docs/design_notes.md, "Field
    convolution")."""
    sums_t = jax.lax.optimization_barrier(sums.T)
    return jax.lax.dot_general(sums_t, mix_matrix(dmix), (((0,), (0,)), ((), ())))


def _out_tangent(primals, sums, tangents, delta, activation):
    """``(ẏ, Ṡ)``: ``Ṡ`` from :func:`sums_tangent`, ``ẏ = Ṡ M + S Ṁ`` (both ``[V, ·]`` real)."""
    x, index, slots, a_w, bias, hidden, mix = primals
    dx, _, dslots, da_w, dbias, dhidden, dmix = tangents
    ds = sums_tangent(
        x, index, slots, a_w, bias, hidden, dx, dslots, da_w, dbias, dhidden, delta, activation
    )
    dy = None
    if ds is not None:
        dy = ds @ mix_matrix(mix)
    if not isinstance(dmix, SymbolicZero):
        term = _mix_tangent(sums, dmix)
        dy = term if dy is None else dy + term
    if ds is None:
        ds = jnp.zeros_like(sums)
    return dy, ds


def _y_tangent(primals, sums, tangents, delta, activation):
    """``ẏ`` alone (``[V, 2D]`` real, or None if zero): with the neighbourhood held fixed, the
    transpose of :func:`blocked_vjp` with the mix folded into its blocks (reverse mode runs that
    VJP, each block forming its own ``∂S = ∂y Mᵀ``); otherwise ``Ṡ M``, ``Ṡ`` from
    :func:`sums_tangent_plain`. Plus ``S Ṁ``."""
    x, index, slots, a_w, bias, hidden, mix = primals
    dx, _, dslots, da_w, dbias, dhidden, dmix = tangents
    if not _all_zero(dslots):
        ds = sums_tangent_plain(
            x, index, slots, a_w, bias, hidden, dx, dslots, da_w, dbias, dhidden, delta, activation
        )
        dy = None if ds is None else ds @ mix_matrix(mix)
    else:
        dy = _transposed_vjp(
            x, index, slots, a_w, bias, hidden, dx, da_w, dbias, dhidden, delta, activation, mix
        )
    if not isinstance(dmix, SymbolicZero):
        term = _mix_tangent(sums, dmix)
        dy = term if dy is None else dy + term
    return dy


def _conv_jvp(delta, activation, primals, tangents):
    y, sums = _conv_and_sums(*primals, delta, activation)
    return y, _y_tangent(primals, sums, tangents, delta, activation)


def _conv_and_sums_jvp(delta, activation, primals, tangents):
    y, sums = _conv_and_sums(*primals, delta, activation)  # higher orders re-enter this rule
    return (y, sums), _out_tangent(primals, sums, tangents, delta, activation)


_conv.defjvp(_conv_jvp, symbolic_zeros=True)
_conv_and_sums.defjvp(_conv_and_sums_jvp, symbolic_zeros=True)


def sums_tangent(
    x, index, slots, a_w, bias, hidden, dx, dslots, da_w, dbias, dhidden, delta, activation
):
    """The filtered sums' tangent ``Ṡ [V, 2·H·C]``, linear in ``(ẋ, slots', Ȧ, ḃ)`` and the second
    layer's ``(Ẇ₂, ḃ₂)``; None if all zero.

    Without a slot tangent (the neighbourhood held fixed, the usual case), ``Ṡ`` is the transpose of
    :func:`blocked_vjp`, taken by ``jax.linear_transpose``: reverse mode transposes it back, so it
    runs the hand-written blocked VJP. With a slot tangent, :func:`sums_tangent_plain`.
    """
    if not _all_zero(dslots):
        return sums_tangent_plain(
            x, index, slots, a_w, bias, hidden, dx, dslots, da_w, dbias, dhidden, delta, activation
        )
    return _transposed_vjp(
        x, index, slots, a_w, bias, hidden, dx, da_w, dbias, dhidden, delta, activation, None
    )


def _transposed_vjp(
    x, index, slots, a_w, bias, hidden, dx, da_w, dbias, dhidden, delta, activation, mix
):
    """``jax.linear_transpose`` of :func:`blocked_vjp` applied to the live tangents: ``Ṡ`` (``mix``
    None) or ``Ṡ M`` (``[V, 2D]``); None if every tangent is a symbolic zero."""
    named = {"x": dx, "a_w": da_w, "bias": dbias, "hidden": dhidden}
    live = {k: _instantiate(t) for k, t in named.items() if not _all_zero(t)}
    if not live:
        return None
    if "x" in live:
        live["x"] = (live["x"].real, live["x"].imag)
    width = 2 * (a_w.shape[1] * x.shape[1] if mix is None else mix.shape[2])
    want = tuple(live)

    def vjp(g):
        return blocked_vjp(x, index, slots, a_w, bias, hidden, g, delta, activation, want, mix)

    transpose = jax.linear_transpose(vjp, jax.ShapeDtypeStruct((x.shape[0], width), x.real.dtype))
    (out,) = transpose(live)
    return out


def blocked_vjp(x, index, slots, a_w, bias, hidden, g, delta, activation, want, mix=None):
    """The VJP of the filtered sums (``mix`` None; ``g = ∂L/∂S [V, 2·H·C]``) or of the outputs
    through them (``g = ∂L/∂y [V, 2D]``, each block forming ``∂S = g Mᵀ``), for fixed slots and
    mix, block by block: a dict of cotangents for the names in ``want``: ``"x"`` (real and imaginary
    ``[V, C]``, scatter-added over each block's neighbours in the loop), ``"a_w"`` ``[2, H]``,
    ``"bias"`` (the offsets' shape), ``"hidden"`` ``(W₂ [H, H], b₂ [H])``.

    Per block of :data:`TANGENT_BLOCK` vertices under ``jax.checkpoint``: :func:`block_vjp`, which
    recomputes the block's responses from the gathered features.
    """
    v, c, h = x.shape[0], x.shape[1], a_w.shape[1]
    block = min(v, TANGENT_BLOCK)
    n_blocks = -(-v // block)
    xr, xi = x.real, x.imag
    m = None if mix is None else mix_matrix(mix)  # [2HC, 2D]

    def body(acc, pv):
        xqr = jnp.take(xr, pv["index"], axis=0, mode="clip")
        xqi = jnp.take(xi, pv["index"], axis=0, mode="clip")
        # g Mᵀ against M's rows as stored (a transposed copy of M: 15 % slower value-and-grad)
        g_s = pv["g"] if m is None else jax.lax.dot_general(pv["g"], m, (((1,), (1,)), ((), ())))
        out = block_vjp(
            xqr, xqi, pv["slots"], a_w, pv["bias"], hidden, g_s.reshape(-1, 2, h, c), delta,
            activation, want,
        )  # fmt: skip
        acc = dict(acc)
        if "x" in out:  # the gather's transpose, per block
            acc["x"] = tuple(
                a.at[pv["index"]].add(d, mode="clip")
                for a, d in zip(acc["x"], out.pop("x"), strict=True)
            )
        for k in ("a_w", "hidden"):
            if k in out:
                acc[k] = jax.tree.map(jnp.add, acc[k], out.pop(k))
        return acc, out

    acc = {}
    if "x" in want:
        acc["x"] = (jnp.zeros_like(xr), jnp.zeros_like(xi))
    if "a_w" in want:
        acc["a_w"] = jnp.zeros_like(a_w)
    if "hidden" in want:
        acc["hidden"] = jax.tree.map(jnp.zeros_like, hidden)
    per_vertex = {"index": index, "slots": slots, "bias": bias, "g": g}
    acc, per_block = jax.lax.scan(
        jax.checkpoint(body, prevent_cse=False), acc, to_blocks(per_vertex, n_blocks, block)
    )
    return dict(acc, **from_blocks(per_block, v))


def block_vjp(xqr, xqi, slots, a_w, bias, hidden, g, delta, activation, want):
    """Hand-written VJP of one block's filtered sums for fixed slots (see :func:`blocked_vjp`).

    With ``p₁ = a_r A_0 + a_i A_1 + b``, ``φ₁ = act(p₁)``, (two layers) ``p₂ = φ₁ W₂ + b₂``,
    ``φ = act(p₂)`` (one layer: ``φ = φ₁``), ``G_s = ∂L/∂S_s``: ``g₂ = (G_r z_r + G_i z_i) act'(p₂)``
    and ``∂z_s = Σ_h G_s φ``; ``g₁ = (W₂ g₂) act'(p₁)``, ``∂W₂ = Σ_{b,k,c} φ₁ g₂ᵀ`` (one GEMM per
    block), ``∂b₂ = Σ g₂``; ``∂a_j = Σ_h g₁ A_j``, ``∂b = Σ_{k(,c)} g₁``, ``∂A_j = Σ_{b,k,c} g₁ a_j``;
    then the chain through ``a = log · conj(u) / |u|_δ``, ``z = ŵ u`` and ``u = ρ x_q``.

    Linear in ``g`` and plain ``jnp``, so JAX transposes it (the forward-mode tangent) and
    differentiates it in the primal inputs (higher orders). The sums over ``h`` are unrolled into
    ``[B, K, C]`` terms; each stage (the slot terms, each layer's responses and derivatives, the
    second layer's pre-activations, each layer's ``g``, ``∂z``) is written once per block
    (``[H, B, K, C]``, in cache) behind an optimisation barrier, so that XLA evaluates every
    response and activation derivative once instead of again inside each fusion that reads it. The
    second activation and the outer layer's ``g`` are evaluated on whole ``[H, B, K, C]`` stacks
    rather than per ``h`` (measured: docs/design_notes.md, "Field convolution").
    """
    w, tr, ti, lr, li = (a[..., None] for a in slots)
    ur = tr * xqr - ti * xqi
    ui = tr * xqi + ti * xqr
    inv = jax.lax.rsqrt(ur * ur + ui * ui + jnp.asarray(delta * delta, xqr.dtype))
    num_r, num_i = lr * ur + li * ui, li * ur - lr * ui
    _, (ur, ui, inv, num_r, num_i, ar, ai, zr, zi) = _written(
        [ur, ui, inv, num_r, num_i, num_r * inv, num_i * inv, w * ur, w * ui]
    )
    b3 = bias3(bias)  # [B, H, C] or [B, H, 1]
    g_r, g_i = g[:, 0], g[:, 1]  # [B, H, C]
    n_h = a_w.shape[1]
    p1 = [ar * a_w[0, j] + ai * a_w[1, j] + b3[:, None, j, :] for j in range(n_h)]
    (phi1_st, phi1), (dphi1_st, dphi1) = _responses(p1, activation)
    phi, dphi_st = phi1, dphi1_st
    if hidden is not None:
        hw, hb = hidden
        p2_st, _ = _written(
            [sum(phi1[i] * hw[i, j] for i in range(n_h)) + hb[j] for j in range(n_h)]
        )
        # the second activation on the whole written stack, in one fusion per output
        phi2_st, dphi_st = jax.lax.optimization_barrier(act_and_grad(p2_st, activation))
        phi = [phi2_st[j] for j in range(n_h)]
    # g = (G_r z_r + G_i z_i) act'(p), broadcast over h in one fusion ([H, B, K, C])
    g_rh, g_ih = (jnp.moveaxis(t, 1, 0)[:, :, None, :] for t in (g_r, g_i))
    g_st = jax.lax.optimization_barrier((g_rh * zr + g_ih * zi) * dphi_st)
    gs = [g_st[j] for j in range(n_h)]
    _, (dzr, dzi) = _written(  # read by both halves of the features' cotangent
        [sum(t[:, None, j, :] * phi[j] for j in range(n_h)) for t in (g_r, g_i)]
    )
    out = {}
    if hidden is not None:
        g2_st, g2 = g_st, gs
        g_st, gs = _written(
            [sum(g2[j] * hw[i, j] for j in range(n_h)) * dphi1[i] for i in range(n_h)]
        )
        if "hidden" in want:
            f1, g2_flat = phi1_st.reshape(n_h, -1), g2_st.reshape(n_h, -1)
            out["hidden"] = (f1 @ g2_flat.T, jnp.sum(g2_flat, axis=1))
    dar = sum(gs[j] * a_w[0, j] for j in range(n_h))
    dai = sum(gs[j] * a_w[1, j] for j in range(n_h))
    if "x" in want:
        common = (num_r * dar + num_i * dai) * inv * inv * inv  # ∂|u|_δ⁻¹ terms
        dur = w * dzr + inv * (lr * dar + li * dai) - ur * common
        dui = w * dzi + inv * (li * dar - lr * dai) - ui * common
        out["x"] = (tr * dur + ti * dui, tr * dui - ti * dur)
    if "a_w" in want:  # g₁ [H, B, K, C] against a: sums over (b, k), then over c
        out["a_w"] = jnp.stack([jnp.sum(jnp.sum(g_st * a, axis=(1, 2)), axis=1) for a in (ar, ai)])
    if "bias" in want:
        if bias.ndim == 3 and bias.shape[2] > 1:  # per-channel offsets: no sum over c
            out["bias"] = jnp.sum(g_st, axis=2).transpose(1, 0, 2)
        else:
            red = jnp.sum(g_st, axis=(2, 3)).T  # [B, H]
            out["bias"] = red[:, :, None] if bias.ndim == 3 else red
    return out


def _written(arrays):
    """``arrays`` (equal shapes) stacked and written behind an optimisation barrier: the stack and
    its rows (XLA fuses no producer into a reader across it)."""
    stacked = jax.lax.optimization_barrier(jnp.stack(arrays))
    return stacked, [stacked[i] for i in range(stacked.shape[0])]


def _responses(pre, activation: str):
    """``act`` and ``act'`` of the pre-activations ``pre`` (a list over ``h``), each :func:`_written`."""
    values, slopes = zip(*(act_and_grad(p, activation) for p in pre), strict=True)
    return _written(list(values)), _written(list(slopes))


def act_and_grad(p, activation: str):
    """:func:`~._field_conv_terms.act` and its derivative, in differentiable ``jnp``."""
    if activation == "silu":
        q = p * jnp.asarray(0.5, p.dtype)
        t = jnp.tanh(q)
        half = jnp.asarray(0.5, p.dtype)
        return q + q * t, half + half * t + q * half * (1 - t * t)
    return jnp.maximum(p, 0), (p > 0).astype(p.dtype)


def sums_tangent_plain(
    x, index, slots, a_w, bias, hidden, dx, dslots, da_w, dbias, dhidden, delta, activation
):
    """:func:`sums_tangent` as the forward-mode derivative of the plain block formula (any tangent,
    the slots' included).

    Per block of :data:`TANGENT_BLOCK` vertices under ``jax.checkpoint``: the block gathers its
    neighbours' features from ``x`` and takes the forward-mode derivative of the plain block
    formula with respect to the inputs that have a tangent (symbolic zeros are left out).
    """
    named = {"x": dx, "slots": dslots, "a_w": da_w, "bias": dbias, "hidden": dhidden}
    live = {k: _instantiate(t) for k, t in named.items() if not _all_zero(t)}
    if not live:
        return None
    v = x.shape[0]
    block = min(v, TANGENT_BLOCK)
    n_blocks = -(-v // block)
    per_vertex = {"index": index, "slots": slots, "bias": bias}
    if "x" in live:  # the tangents' gather: linear, outside the loop (one scatter when transposed)
        live["x"] = tuple(jnp.take(part, index, axis=0, mode="clip") for part in (dx.real, dx.imag))
    tangent_rows = {k: t for k, t in live.items() if k not in ("a_w", "hidden")}
    blocks = to_blocks((per_vertex, tangent_rows), n_blocks, block)
    xr, xi = x.real, x.imag

    def body(args):
        pv, dt = args
        xqr = jnp.take(xr, pv["index"], axis=0, mode="clip")
        xqi = jnp.take(xi, pv["index"], axis=0, mode="clip")
        dt = dict(dt, **{k: live[k] for k in ("a_w", "hidden") if k in live})
        values = {
            "x": (xqr, xqi),
            "slots": pv["slots"],
            "a_w": a_w,
            "bias": pv["bias"],
            "hidden": hidden,
        }

        def sums(*diff):
            args = dict(values, **dict(zip(dt, diff, strict=True)))
            zr, zi, ar, ai = terms(*args["x"], args["slots"], delta, blocked=False)
            s_r, s_i = filtered_sums_plain(
                zr, zi, ar, ai, args["a_w"], args["bias"], activation, args["hidden"]
            )
            b = s_r.shape[0]
            return jnp.concatenate([s_r.reshape(b, -1), s_i.reshape(b, -1)], axis=1)

        primal_in = tuple(values[k] for k in dt)
        return jax.jvp(sums, primal_in, tuple(dt.values()))[1]

    ds = jax.lax.map(jax.checkpoint(body, prevent_cse=False), blocks)
    return from_blocks(ds, v)


def _all_zero(t) -> bool:
    return all(isinstance(leaf, SymbolicZero) for leaf in jax.tree.leaves(t))


def _instantiate(t):
    """Symbolic zeros among live tangents (one slot array of five) as arrays of zeros."""
    return jax.tree.map(
        lambda leaf: jnp.zeros(leaf.shape, leaf.dtype) if isinstance(leaf, SymbolicZero) else leaf,
        t,
    )

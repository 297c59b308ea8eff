"""The transported-argument field convolution (one or two hidden filter layers): a fused blocked
forward, and a ``custom_jvp`` whose tangent is plain JAX, linear in the tangents.

Forward: per block of :data:`BLOCK` vertices in one loop, gather → terms → fused filter sums →
mix, so a block's ``[B, K, C]`` terms and ``[B, H, C]`` sums stay in cache; with one hidden layer
no response is written to memory, with two the second layer's matrix product over the block's
first-layer responses is (:func:`~._field_conv_terms.filtered_sums_fused`).

Derivatives: the forward's fused reduction cannot be transposed by JAX, so it sits behind a
``jax.custom_jvp``. Its tangent is the forward-mode derivative of the plain formula
(:func:`~._field_conv_terms.filtered_sums_plain`), taken block by block under ``jax.checkpoint``.
Every transformation then follows from JAX's own rules, in any order and under ``jax.jit``:
``jvp``, ``linearize``, ``jacfwd``, ``vmap``; reverse mode (``grad``, ``vjp``, ``jacrev``)
transposes the tangent, recomputing each block's responses instead of storing the ``V·K·H·C`` of
them (the checkpoint keeps only the inputs), and keeps the forward's ``V·2·H·C`` filtered sums for
the mix's gradient. Higher orders re-enter the same rule (its primal output calls the rule's own
function). Inputs without a tangent (usually the neighbourhood) arrive as symbolic zeros and cost
nothing.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from jax.custom_derivatives import SymbolicZero

from ._field_conv_terms import (
    as_complex,
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
        term = sums @ mix_matrix(dmix)
        dy = term if dy is None else dy + term
    if ds is None:
        ds = jnp.zeros_like(sums)
    return dy, ds


def _conv_jvp(delta, activation, primals, tangents):
    y, sums = _conv_and_sums(*primals, delta, activation)
    dy, _ = _out_tangent(primals, sums, tangents, delta, activation)
    return y, dy


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

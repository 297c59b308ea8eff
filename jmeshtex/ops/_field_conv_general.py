"""The general field convolution in plain JAX (every transformation applies through JAX's own
rules): any filter (one or two hidden layers, per-channel embeddings) with either filter argument.
:func:`~jmeshtex.ops.field_conv` runs it for the untransported argument (the transported one takes
the fused path of ``_field_conv_fast``); the tests compare the two paths.

Per block of vertices the responses ``[B, K, H, C]`` go through the filter MLP and are summed
against the transported features; the blocks run under ``jax.checkpoint``, so reverse mode
recomputes each block's responses instead of storing them.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ._field_conv_terms import act, as_complex, from_blocks, mix_halves, to_blocks


def conv_general(
    x, index, slots, a_w, bias, mix, channel, hidden, *, delta, activation, transported
):
    """The general path (two-layer filters, per-channel embedding, untransported argument), blocked."""
    v = x.shape[0]
    m_r, m_i = mix_halves(mix)  # rows ordered (h, c) like the block's sums
    xqr = jnp.take(x.real, index, axis=0, mode="clip")  # [V, K, C]
    xqi = jnp.take(x.imag, index, axis=0, mode="clip")
    per_vertex = (xqr, xqi, slots, bias, None if channel is None else channel[0])
    block = v if v <= GENERAL_SINGLE else GENERAL_BLOCK
    n_blocks = -(-v // block)
    cw = None if channel is None else channel[1]

    def body(args):
        xr_b, xi_b, sl_b, b_b, e_b = args
        ch = None if e_b is None else (e_b, cw)
        return _general_block(
            xr_b, xi_b, sl_b, b_b, ch, a_w, hidden, m_r, m_i, delta, activation, transported
        )

    if n_blocks == 1:  # small meshes: one block, no loop (fast to compile; residuals are small)
        return as_complex(body(per_vertex))
    y = jax.lax.map(jax.checkpoint(body), to_blocks(per_vertex, n_blocks, block))
    return as_complex(from_blocks(y, v))


#: vertices per block of the general path: its ``[B, K, H, C]`` responses stay in cache (block
#: sizes measured in docs/design_notes.md, "Field convolution")
GENERAL_BLOCK = 32
#: meshes of up to this many vertices run as one block (no loop: fast to compile)
GENERAL_SINGLE = 1024


def _general_block(
    xqr, xqi, slots, bias, channel, a_w, hidden, m_r, m_i, delta, activation, transported
):
    """One block of the general path: gathered ``x_q`` ``[B, K, C]`` → real ``[B, 2D]`` outputs.

    Responses are laid out ``[B, K, H, C]`` (channels innermost, as in the fast path; the second
    hidden layer is an ``H × H`` contraction over the third axis): with ``H`` innermost the forward is
    about 1.9x slower in CPU time at 30K vertices, C = 64, h = 8.
    """
    w, tr, ti, lr, li = (a[..., None] for a in slots)
    ur = tr * xqr - ti * xqi
    ui = tr * xqi + ti * xqr
    dr, di = (ur, ui) if transported else (xqr, xqi)
    inv = jax.lax.rsqrt(dr * dr + di * di + jnp.asarray(delta * delta, xqr.dtype))
    ar, ai = (lr * dr + li * di) * inv, (li * dr - lr * di) * inv  # [B, K, C]
    zr, zi = w * ur, w * ui
    pre = (
        ar[:, :, None, :] * a_w[0][:, None]
        + ai[:, :, None, :] * a_w[1][:, None]
        + bias[:, None, :, None]
    )
    if channel is not None:
        emb, cw = channel
        pre = pre + emb[:, None, None, :] * cw[:, None]
    phi = act(pre, activation)  # [B, K, H, C]
    if hidden is not None:
        hw, hb = hidden
        phi = act(jnp.einsum("bkic,ij->bkjc", phi, hw) + hb[:, None], activation)
    s_r = jnp.sum(zr[:, :, None, :] * phi, axis=1)  # [B, H, C]
    s_i = jnp.sum(zi[:, :, None, :] * phi, axis=1)
    b = s_r.shape[0]
    return s_r.reshape(b, -1) @ m_r + s_i.reshape(b, -1) @ m_i

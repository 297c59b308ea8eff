"""From scalars to tangent features and back: the entry and exit of a tangent-feature network.

A network of field convolutions takes tangent features (complex numbers in each vertex's frame)
and must return what the task needs — often scalars. :func:`tangent_gradient` lifts vertex scalars
to tangent vectors (their intrinsic gradient, which turns with the frame exactly as a tangent
feature does); :func:`tangent_invariants` reads frame-independent numbers out of tangent features
(moduli and relative phases between channels), which any real-valued head may then use.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._errors import InputError
from .._neighborhoods import VertexNeighborhood
from .._types import Array, ArrayLike, Complex, Float
from ._numerics import abs2


def tangent_gradient(
    f: Float[ArrayLike, "V C"], nbhd: VertexNeighborhood, *, ridge: float = 1e-10
) -> Complex[Array, "V C"]:
    """The intrinsic gradient of vertex scalars, as tangent features in each vertex's frame.

    At every vertex p, the least-squares fit over p's slots q (each counted once) of

    .. math:: f_q - f_p \\approx \\operatorname{Re}\\big(\\overline{g_p}\\, \\log_p(q)\\big)

    (a linear function on p's tangent plane; exact for a linear function on a flat mesh). ``g_p``
    turns with p's frame as every tangent feature does, so the lift is gauge-equivariant, and
    intrinsic because ``log`` is.

    Args:
      f: ``[V, C]`` real vertex scalars (padded rows: any finite value).
      nbhd: a :class:`~jmeshtex.VertexNeighborhood` (one-ring or k-NN); masked slots are ignored.
      ridge: relative Tikhonov term on each 2×2 normal matrix (a vertex whose slots span no
        direction gets ``g = 0``, not NaN).

    Returns:
      ``[V, C]`` complex gradients, in units of ``f`` per log-map unit.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.geometry import one_ring_neighborhood
      >>> v, faces = grid(4, 4)
      >>> nb = one_ring_neighborhood(v, faces, scale=None)  # log maps in mesh units
      >>> g = tangent_gradient(2 * v[:, :1] - v[:, 1:2], nb)
      >>> bool(np.allclose(np.abs(g), np.sqrt(5)))  # |∇(2x − y)| everywhere on the sheet
      True
    """
    f = jnp.asarray(f)
    if f.ndim != 2:
        raise InputError(f"tangent_gradient: f must be [V, C] real scalars, got shape {f.shape}")
    if jnp.iscomplexobj(f):
        raise InputError("tangent_gradient: f must be real (lift complex features directly)")
    if f.shape[0] != nbhd.index.shape[0]:
        raise InputError(
            f"tangent_gradient: f has {f.shape[0]} rows but the neighbourhood "
            f"{nbhd.index.shape[0]} vertices; pad f to the neighbourhood's V"
        )
    real = f.dtype
    zero = jnp.zeros((), real)
    w = nbhd.mask.astype(real)  # every slot counts once (cotangent weights may be negative)
    zx = jnp.where(nbhd.mask, jnp.real(jnp.asarray(nbhd.log)).astype(real), zero)
    zy = jnp.where(nbhd.mask, jnp.imag(jnp.asarray(nbhd.log)).astype(real), zero)
    diff = jnp.where(nbhd.mask[..., None], f[nbhd.index] - f[:, None, :], zero)  # [V, K, C]
    axx, axy, ayy = (jnp.sum(w * a * b, axis=1) for a, b in ((zx, zx), (zx, zy), (zy, zy)))
    bx = jnp.einsum("vk,vkc->vc", w * zx, diff)
    by = jnp.einsum("vk,vkc->vc", w * zy, diff)
    eps = ridge * (axx + ayy) + jnp.finfo(real).tiny
    axx, ayy = axx + eps, ayy + eps
    det = axx * ayy - axy * axy
    gx = (ayy[:, None] * bx - axy[:, None] * by) / det[:, None]
    gy = (axx[:, None] * by - axy[:, None] * bx) / det[:, None]
    g = jax.lax.complex(gx, gy)
    return jnp.where(nbhd.vertex_mask[:, None], g, jnp.zeros_like(g))


def tangent_invariants(x: Complex[ArrayLike, "V C"]) -> Float[Array, "V D"]:
    """Frame-independent real numbers from tangent features: moduli and relative phases.

    Returns ``[|x_c|]`` for every channel, then ``Re`` and ``Im`` of ``x_c \\overline{x_d}`` for
    every pair ``c < d``, divided by ``|x_c| |x_d|`` where both are non-zero (the cosine and sine of
    the angle between the two channels; 0 where either vanishes). A gauge change multiplies every
    channel at a vertex by the same unit number, which these quantities do not see; together they
    determine the features up to that common rotation.

    Args:
      x: ``[V, C]`` complex tangent features.

    Returns:
      ``[V, C + C (C - 1)]`` real invariants.

    Example:
      >>> import numpy as np
      >>> x = np.array([[1 + 0j, 1j]])
      >>> tangent_invariants(x).tolist(), tangent_invariants(x * np.exp(0.7j)).round(12).tolist()
      ([[1.0, 1.0, 0.0, -1.0]], [[1.0, 1.0, 0.0, -1.0]])
    """
    x = jnp.asarray(x)
    if x.ndim != 2 or not jnp.iscomplexobj(x):
        raise InputError(
            f"tangent_invariants: x must be [V, C] complex tangent features, got "
            f"{x.dtype} {x.shape}"
        )
    c = x.shape[1]
    m2 = abs2(x)
    modulus = jnp.where(m2 > 0, jnp.sqrt(jnp.where(m2 > 0, m2, 1.0)), 0.0)  # finite grads at 0
    out = [modulus]
    if c > 1:
        i, j = jnp.triu_indices(c, k=1)
        prod = x[:, i] * jnp.conj(x[:, j])
        scale = modulus[:, i] * modulus[:, j]
        safe = jnp.where(scale > 0, scale, 1.0).astype(prod.dtype)
        unit = jnp.where(scale > 0, prod / safe, jnp.zeros_like(prod))
        out += [jnp.real(unit), jnp.imag(unit)]
    return jnp.concatenate(out, axis=1)

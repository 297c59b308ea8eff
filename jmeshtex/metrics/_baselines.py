"""The protocol's reference colourings: a flat mean colour (the do-nothing floor) and the exemplar's
own colours permuted at random (the right colour histogram with no structure)."""

from __future__ import annotations

import numpy as np

from .._errors import InputError
from .._random import check_key, host_rng
from .._types import ArrayLike, Bool, Num


def _colors_and_mask(colors, mask, name: str) -> tuple[np.ndarray, np.ndarray]:
    c = np.asarray(colors)
    if c.ndim not in (2, 3) or c.shape[-1] not in (1, 3, 4) or c.size == 0:
        raise InputError(
            f"{name}: colors must be [V, C] vertex colours or an [H, W, C] texture (C = 1, 3 "
            f"or 4), got shape {c.shape}"
        )
    if np.issubdtype(c.dtype, np.floating) and not np.isfinite(c).all():
        raise InputError(f"{name}: colors contain NaN or inf")
    sites = c.shape[:-1]
    if mask is None:
        m = np.ones(sites, bool)
    else:
        m = np.asarray(mask, bool)
        if m.shape != sites:
            raise InputError(
                f"{name}: mask must be {list(sites)} (one flag per vertex / texel), got {list(m.shape)}"
            )
    if not m.any():
        raise InputError(f"{name}: the mask selects no vertex / texel")
    return c, m


def flat_baseline(
    colors: Num[ArrayLike, "*S C"],
    *,
    mask: Bool[ArrayLike, "*S"] | None = None,
) -> np.ndarray:
    """The do-nothing colouring: the mean colour of ``colors`` everywhere.

    .. math:: c'_i = \\frac{1}{|M|} \\sum_{j \\in M} c_j \\quad (i \\in M), \\qquad c'_i = c_i \\ (i \\notin M)

    Works for ``[V, C]`` vertex colours and ``[H, W, C]`` textures (the mean over vertices or
    texels). With a ``mask`` (e.g. the used texels of an atlas) the mean is taken over, and written
    to, the masked sites only; the others keep their colour.

    Args:
      colors: ``[V, C]`` or ``[H, W, C]`` colours (float or uint8; ``C`` = 1, 3 or 4).
      mask: ``[V]`` or ``[H, W]`` sites to use (default all).

    Returns:
      An array of the shape of ``colors``; float64 for float input, the input's dtype (rounded
      mean) for integer input.

    Raises:
      InputError: wrong shapes, NaN, an empty mask.

    Example:
      >>> flat_baseline(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])).tolist()
      [[0.5, 0.0, 0.5], [0.5, 0.0, 0.5]]
    """
    c, m = _colors_and_mask(colors, mask, "flat_baseline")
    out = c.astype(np.float64) if np.issubdtype(c.dtype, np.floating) else c.copy()
    mean = c[m].astype(np.float64).mean(0)
    out[m] = mean if np.issubdtype(c.dtype, np.floating) else np.rint(mean).astype(c.dtype)
    return out


def permuted_baseline(
    colors: Num[ArrayLike, "*S C"],
    *,
    key,
    mask: Bool[ArrayLike, "*S"] | None = None,
) -> np.ndarray:
    """The exemplar's own colours, randomly permuted over its vertices or texels.

    .. math:: c'_i = c_{\\pi(i)}, \\quad \\pi \\text{ a uniformly random permutation of } M

    The colour histogram is exactly the exemplar's (the same multiset of colours), all spatial
    structure is gone: a model that only learnt colour statistics scores like this. On VGG metrics
    (:func:`sifid`, :func:`gram_distance`, :func:`lpips`) a *texel*-level permutation is white noise,
    which excites the network's edge filters, and usually scores *worse* than the flat colour; a
    vertex-level permutation on a render (each vertex covers many pixels) is smoother.

    Args:
      colors: ``[V, C]`` vertex colours or an ``[H, W, C]`` texture (any dtype).
      key: a JAX PRNG key (:func:`jax.random.key`).
      mask: ``[V]`` or ``[H, W]`` sites to permute among (default all); the others stay.

    Returns:
      An array of the shape and dtype of ``colors``.

    Raises:
      InputError: wrong shapes, NaN, an empty mask, a key that is not a JAX key.

    Example:
      >>> import jax
      >>> c = np.arange(12.0).reshape(4, 3)
      >>> p = permuted_baseline(c, key=jax.random.key(0))
      >>> sorted(map(tuple, p)) == sorted(map(tuple, c))
      True
    """
    check_key(key)
    c, m = _colors_and_mask(colors, mask, "permuted_baseline")
    out = c.copy()
    sites = out[m]
    out[m] = sites[host_rng(key).permutation(len(sites))]
    return out

"""Colour-palette distance: how far a texture's colours are from an exemplar's, ignoring layout.

A joint RGB histogram with ``bins³`` cells per image (over the used texels only), and the total
variation distance between the two,

.. math:: d = \\tfrac12 \\sum_{c} |p_c - q_c| \\in [0, 1],

the share of one image's colour mass that would have to move to match the other's. Speckle of
colours the exemplar does not have (orange dots on a black-and-white cow) and a colour cast both
show here, while a Gram or patch distance can rank a flat colour first; a flat colour scores the
mass of every other colour in the exemplar.
"""

from __future__ import annotations

import numpy as np

from .._config import is_int
from .._errors import InputError
from .._types import Bool, Float


def _histogram(image, mask, bins: int) -> np.ndarray:
    x = np.asarray(image, np.float64)
    if x.ndim < 2 or x.shape[-1] < 3:
        raise InputError(f"palette_distance: images must be [..., 3] RGB, got shape {x.shape}")
    x = x[..., :3].reshape(-1, 3)
    if mask is not None:
        m = np.asarray(mask, bool).reshape(-1)
        if m.shape[0] != x.shape[0]:
            raise InputError(
                f"palette_distance: a mask of {m.shape[0]} texels for an image of {x.shape[0]}"
            )
        x = x[m]
    if x.shape[0] == 0 or not np.all(np.isfinite(x)):
        raise InputError("palette_distance: no texels to count, or non-finite colours")
    idx = np.clip((np.clip(x, 0.0, 1.0) * bins).astype(np.int64), 0, bins - 1)
    flat = (idx[:, 0] * bins + idx[:, 1]) * bins + idx[:, 2]
    h = np.bincount(flat, minlength=bins**3).astype(np.float64)
    return h / h.sum()


def palette_distance(
    a: Float[np.ndarray, "... 3"],
    b: Float[np.ndarray, "... 3"],
    *,
    mask_a: Bool[np.ndarray, "..."] | None = None,
    mask_b: Bool[np.ndarray, "..."] | None = None,
    bins: int = 8,
) -> float:
    """Total variation distance between the joint RGB histograms of two images (module docstring).

    Args:
      a, b: images (any shape ending in RGB) in [0, 1]; values outside are clipped.
      mask_a, mask_b: the texels to count (e.g. an atlas's used texels); None: all.
      bins: histogram cells per channel.

    Returns:
      The distance as a float in [0, 1] (0 for the same palette, 1 for disjoint ones).

    Example:
      >>> black, white = np.zeros((4, 4, 3)), np.ones((4, 4, 3))
      >>> cow = np.concatenate([black, white])
      >>> palette_distance(cow, cow), palette_distance(black, cow), palette_distance(black, white)
      (0.0, 0.5, 1.0)
    """
    if not is_int(bins, 1) or bins > 64:
        raise InputError(f"palette_distance: bins must be an int in [1, 64], got {bins!r}")
    p, q = _histogram(a, mask_a, bins), _histogram(b, mask_b, bins)
    return float(0.5 * np.abs(p - q).sum())

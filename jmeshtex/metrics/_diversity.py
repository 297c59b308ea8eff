"""Sample diversity: mean pairwise LPIPS between samples seen from the same view."""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._types import ArrayLike, Float
from ._perceptual import lpips
from ._sifid import as_float_images
from ._vgg import VGGWeights
from ._vgg_load import load_vgg16

_lpips_jit = jax.jit(lpips)


def diversity(
    images: Float[ArrayLike, "S H W 3"],
    *,
    weights: VGGWeights | None = None,
    batch: int = 8,
) -> float:
    """Mean pairwise LPIPS between ``S`` samples (e.g. renders of generated textures, one view).

    .. math:: D = \\binom{S}{2}^{-1} \\sum_{i < j} \\mathrm{LPIPS}(x_i, x_j)

    0 (to rounding) when all samples are identical; larger means more varied samples. The FLDM and Sin3DM papers
    report the same statistic (on their own renders and settings), so values are comparable only
    within one protocol. For several views, call it per view and average.

    Args:
      images: ``[S, H, W, 3]`` samples, uint8 or float in [0, 1], ``S ≥ 2``, at least 16×16.
      weights: the VGG with LPIPS heads (default :func:`load_vgg16`).
      batch: pairs per LPIPS call (memory bound).

    Returns:
      The mean distance, a Python float.

    Raises:
      InputError: fewer than two samples or not RGB images.

    Example:
      >>> x = np.random.default_rng(0).random((3, 16, 16, 3))
      >>> diversity(np.stack([x[0]] * 3)) < 1e-12 < diversity(x)
      True
    """
    x = as_float_images(images, "diversity", batched=True)
    if len(x) < 2:
        raise InputError(f"diversity needs at least 2 samples, got {len(x)}")
    weights = load_vgg16() if weights is None else weights
    pairs = np.array(list(itertools.combinations(range(len(x)), 2)))
    d = [
        np.asarray(_lpips_jit(jnp.asarray(x[p[:, 0]]), jnp.asarray(x[p[:, 1]]), weights=weights))
        for p in np.array_split(pairs, -(-len(pairs) // batch))
    ]
    return float(np.mean(np.concatenate(d)))

"""Exemplar, style and content images as the surface CNN reads them: ``[H, W, 3]`` float64 RGB in [0, 1]."""

from __future__ import annotations

import numpy as np

from .._errors import InputError


def as_rgb(image, name: str) -> np.ndarray:
    """``image`` as ``[H, W, 3]`` float64 RGB in [0, 1]: grey is repeated, alpha dropped, uint8 scaled.

    Raises:
      InputError: not an image, or colours outside [0, 1] (non-finite included); ``name`` says which.
    """
    image = np.asarray(image)
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    if image.ndim != 3 or image.shape[2] not in (1, 3, 4) or min(image.shape[:2]) < 1:
        raise InputError(
            f"{name} must be an [H, W, 3] RGB image (or grey / RGBA), got shape {image.shape}"
        )
    if image.shape[2] == 1:
        image = np.repeat(image, 3, axis=2)
    image = image[..., :3]
    if np.issubdtype(image.dtype, np.integer):
        image = image / 255.0
    image = image.astype(np.float64)
    if not np.isfinite(image).all() or image.min() < 0 or image.max() > 1:
        raise InputError(f"{name} colours must be finite and in [0, 1] (or uint8)")
    return image

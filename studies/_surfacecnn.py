"""What the surface-CNN studies share: the exemplars at a size, the folder of their PNGs."""

from __future__ import annotations

import pathlib

import numpy as np

PNG_DIR = pathlib.Path("/tmp/round2/surfacecnn_png")


def exemplar_image(kind: str, n: int) -> np.ndarray:
    """``brick`` (skimage's, grey) or ``stripes`` (a sine along the columns, period 8 pixels: smooth at
    texel scale, so colour jumps at seams stand out from the pattern's own variation)."""
    import skimage.data
    import skimage.transform

    if kind == "stripes":
        s = 0.5 + 0.5 * np.sin(2 * np.pi * np.arange(n) / 8.0)
        return np.repeat(np.repeat(s[None, :, None], n, 0), 3, 2)

    brick = skimage.data.brick().astype(np.float64) / 255.0
    brick = skimage.transform.resize(brick, (n, n), anti_aliasing=True)
    return np.repeat(brick[..., None], 3, axis=2)

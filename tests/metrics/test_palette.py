"""The colour-palette distance: exact on analytic palettes, and it sees speckle a flat colour hides."""

import numpy as np
import pytest

from jmeshtex import InputError
from jmeshtex.metrics import palette_distance


def test_exact_values_and_masks():
    black, white = np.zeros((4, 4, 3)), np.ones((4, 4, 3))
    cow = np.concatenate([black, white])
    assert palette_distance(cow, cow) == 0.0
    assert palette_distance(black, cow) == 0.5
    assert palette_distance(black, white) == 1.0
    mask = np.zeros(cow.shape[:2], bool)
    mask[:4] = True  # only the black half counted
    assert palette_distance(black, cow, mask_b=mask) == 0.0
    assert palette_distance(cow, cow[::-1, ::-1]) == 0.0  # layout is ignored


def test_speckle_and_cast_are_seen():
    rng = np.random.default_rng(0)
    cow = np.where(rng.random((64, 64, 1)) < 0.5, 0.05, 0.95) * np.ones(3)
    speckled = cow.copy()
    dots = rng.random((64, 64)) < 0.1
    speckled[dots] = [0.9, 0.5, 0.1]  # orange speckle
    cast = np.clip(cow * [1.0, 0.9, 0.8], 0, 1)
    assert palette_distance(speckled, cow) == pytest.approx(dots.mean(), abs=1e-12)
    assert palette_distance(cast, cow) > 0.4
    assert palette_distance(cow[:32], cow) < 0.05


def test_refusals():
    with pytest.raises(InputError, match="bins"):
        palette_distance(np.zeros((2, 2, 3)), np.zeros((2, 2, 3)), bins=0)
    with pytest.raises(InputError, match="no texels"):
        palette_distance(np.zeros((2, 2, 3)), np.zeros((2, 2, 3)), mask_a=np.zeros((2, 2), bool))
    with pytest.raises(InputError, match="RGB"):
        palette_distance(np.zeros((2, 2)), np.zeros((2, 2, 3)))

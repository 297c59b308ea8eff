"""`geometry.up_vector`: the one parser of axis names, used by the renderer and MeshMatch."""

from __future__ import annotations

import numpy as np
import pytest

from jmeshtex import ConfigError, InputError, meshmatch, render
from jmeshtex.geometry import UP_AXES, up_vector


@pytest.mark.parametrize("name", UP_AXES)
def test_axis_names_give_signed_unit_axes(name):
    v = up_vector(f" {name.upper()} ")
    i = "xyz".index(name[-1])
    assert v[i] == (-1.0 if name.startswith("-") else 1.0) and np.abs(v).sum() == 1.0


@pytest.mark.parametrize("bad", ["w", "", (0, 0, 0), (1, 0), (np.nan, 0, 1), np.ones((3, 1))])
def test_anything_else_is_an_input_error(bad):
    with pytest.raises(InputError):
        up_vector(bad)


def test_the_renderer_and_meshmatch_parse_axes_the_same_way():
    assert render.up_vector is up_vector and render.UP_AXES == UP_AXES
    for up in (*UP_AXES, (1.0, 2.0, 2.0)):
        c = meshmatch.Config.intrinsic(up=up)
        np.testing.assert_allclose(c.up_vector(), up_vector(up), atol=1e-15)
    for bad in ("w", (0.0, 0.0, 0.0), (np.nan, 0.0, 1.0)):
        with pytest.raises(ConfigError):
            meshmatch.Config.intrinsic(up=bad)

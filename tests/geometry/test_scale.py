"""check_mesh_scale: the shared scale and placement check, at and beyond its bounds."""

from __future__ import annotations

import numpy as np
import pytest

from jmeshtex import FaceIndexError, MeshError, MeshScaleError
from jmeshtex.data import icosphere
from jmeshtex.geometry import check_mesh_scale, mean_edge_length


def test_in_range_meshes_pass_and_return_their_mean_edge():
    v, f = icosphere(2)
    edge = mean_edge_length(v, f)
    for scale in (1e-2, 1.0, 1e6):
        assert check_mesh_scale(v * scale, f) == pytest.approx(edge * scale, rel=1e-12)
    assert check_mesh_scale(icosphere(2)) == pytest.approx(edge)  # a Mesh in place of the arrays


@pytest.mark.parametrize(
    ("scale", "offset", "match"),
    [
        (1e30, 0.0, "mean edge length"),
        (1e12, 0.0, "mean edge length"),
        (1e-3, 0.0, "mean edge length"),
        (1.0, 1e8, "from the origin"),
    ],
)
def test_extremes_are_refused_with_the_fix(scale, offset, match):
    v, f = icosphere(1)
    with pytest.raises(MeshScaleError, match=match) as info:
        check_mesh_scale(v * scale + offset, f, what="target")
    message = str(info.value)
    assert message.startswith("target: ") and "Fix: centre and rescale" in message
    assert isinstance(info.value, MeshError)


def test_bounds_are_inclusive_and_adjustable():
    v, f = icosphere(1)
    edge = mean_edge_length(v, f)
    check_mesh_scale(v, f, min_edge=edge, max_edge=edge)
    with pytest.raises(MeshScaleError):
        check_mesh_scale(v, f, min_edge=np.nextafter(edge, np.inf))
    centre = np.array([3.0, 4.0, 0.0]) * edge  # 5 mean edges out
    check_mesh_scale(v + centre, f, max_offset=5.0 + 1e-9)
    with pytest.raises(MeshScaleError, match="5 mean edges"):
        check_mesh_scale(v + centre, f, max_offset=4.9)


def test_structure_is_checked_first():
    v, f = icosphere(1)
    with pytest.raises(FaceIndexError):
        check_mesh_scale(v * 1e30, f + len(v))

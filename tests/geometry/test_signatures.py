"""Host geometry signatures are checked at run time in the test suite (jaxtyping + beartype): a
neighbourhood argument given a Mesh, or a wrong shape, fails at the call naming the argument."""

from __future__ import annotations

import numpy as np
import pytest
from jaxtyping import TypeCheckError

from jmeshtex.data import icosphere
from jmeshtex.geometry import knn_from_one_ring, one_ring_neighborhood, surface_correspondence

MESH = icosphere(1)


def test_a_mesh_where_a_neighbourhood_is_expected_names_the_argument():
    with pytest.raises(TypeCheckError, match=r"parameter 'ring'"):
        knn_from_one_ring(MESH, 8)


def test_a_wrong_shape_fails_naming_the_argument():
    points = np.zeros((5, 2))  # [N, 2] where points in space, [N, 3], are expected
    with pytest.raises(TypeCheckError, match=r"parameter 'points'"):
        surface_correspondence(*MESH, points)


def test_valid_calls_pass_the_checks():
    ring = one_ring_neighborhood(*MESH)
    assert knn_from_one_ring(ring, 8).index.shape == (42, 8)

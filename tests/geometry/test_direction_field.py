"""Direction fields: the global projected field and the smoothest (connection-Laplacian) field."""

import numpy as np
import pytest

from jmeshtex import InputError
from jmeshtex.data import grid, icosphere, torus
from jmeshtex.geometry import (
    connection_laplacian,
    global_direction_field,
    project_direction,
    smoothest_direction_field,
    tangent_frames,
    tangent_from_3d,
)


def _energy(v, f, t):
    L, area = connection_laplacian(v, f)
    u = tangent_from_3d(t, tangent_frames(v, f))
    return float((np.conj(u) @ (L @ u)).real / np.sum(area * np.abs(u) ** 2))


def test_flat_sheet_fields_are_the_projected_vector():
    v, f = grid(3)
    want = np.tile([0.6, 0.8, 0.0], (len(v), 1))
    np.testing.assert_allclose(
        global_direction_field(v, f, primary=(3.0, 4.0, 5.0)), want, atol=1e-12
    )
    np.testing.assert_allclose(
        smoothest_direction_field(v, f, primary=(3.0, 4.0, 0.0)), want, atol=1e-9
    )


def test_fields_are_unit_tangent_vectors_on_a_sphere():
    v, f = icosphere(3)
    normal = tangent_frames(v, f).normal
    for t in (global_direction_field(v, f), smoothest_direction_field(v, f)):
        np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-12)
        assert np.abs(np.sum(t * normal, axis=1)).max() < 1e-12


def test_fallback_where_the_normal_is_parallel_to_the_vector():
    n = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 0, 1.0]])
    t = project_direction(np.zeros((3, 3)), n)
    np.testing.assert_allclose(t, [[0, 1.0, 0], [0, 1.0, 0], [1.0, 0, 0]], atol=1e-15)


def test_smoothest_field_has_lower_energy_than_the_global_one_on_a_torus():
    v, f = torus(24, 12)
    smooth = _energy(v, f, smoothest_direction_field(v, f))
    glob = _energy(v, f, global_direction_field(v, f))
    # a torus carries a parallel field (energy ~0 up to discretisation); x projected is far from it
    assert smooth < 0.2 * glob
    L, area = connection_laplacian(v, f)
    assert abs(L - L.conj().T).max() < 1e-12


def test_bad_vectors_raise():
    v, f = grid(1)
    with pytest.raises(InputError):
        global_direction_field(v, f, primary=(0.0, 0.0, 0.0))
    with pytest.raises(InputError):
        smoothest_direction_field(v, f, iterations=0)

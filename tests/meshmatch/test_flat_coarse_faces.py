"""A coarse level whose copied positions make a face flat in space still prepares: its one-rings
and tracer tables come from mollified edge lengths (every edge lengthened by the same small ε)."""

from __future__ import annotations

import numpy as np
import pytest

from jmeshtex import DegenerateFaceError, InputError
from jmeshtex.data import icosphere
from jmeshtex.geometry import (
    edge_lengths,
    face_areas,
    mesh_hierarchy,
    one_ring_neighborhood,
    tracer_geometry,
)
from jmeshtex.meshmatch import Config
from jmeshtex.meshmatch._prepare import level_arrays, mollified_lengths
from jmeshtex.meshmatch.core import prepare_side


def _flattened_hierarchy():
    v, f = icosphere(3)
    h = mesh_hierarchy(v, f, levels=3)
    v1 = np.array(h.vertices[1])
    a, b, c = h.faces[1][0]
    v1[c] = 0.5 * (v1[a] + v1[b])  # face 0 of level 1 now has zero area in space
    assert face_areas(edge_lengths(v1, h.faces[1]))[0] < 1e-15
    return (v, f), h._replace(vertices=(h.vertices[0], v1, h.vertices[2]))


def test_a_flat_coarse_face_uses_the_intrinsic_lengths():
    mesh, h = _flattened_hierarchy()
    with pytest.raises(DegenerateFaceError):  # what prepare_side raised before
        one_ring_neighborhood(h.vertices[1], h.faces[1])
    config = Config(levels=3)
    side = prepare_side(mesh, config, hierarchy=h)
    nb = side.neighborhoods[1]
    assert np.isfinite(nb.log).all() and np.isfinite(nb.transport).all() and (nb.area > 0).all()
    # the radii are the positions' edge lengths, lengthened by about 1e-4 mean edges
    v1, f1 = h.vertices[1], h.faces[1]
    mean = edge_lengths(v1, f1).mean()
    plain = np.linalg.norm(v1[nb.index] - v1[:, None], axis=-1)
    gap = np.where(nb.mask, np.abs(nb.log) - plain, 0.0)
    assert 0.5e-4 * mean < gap.max() < 3e-4 * mean and gap.min() > -1e-12
    # a level whose positions are fine keeps the unmollified tables
    np.testing.assert_allclose(
        side.neighborhoods[2].log, one_ring_neighborhood(h.vertices[2], h.faces[2], scale=None).log
    )
    # the traced fans of that level are finite too
    n = len(h.vertices[1])
    arr, _ = level_arrays(
        side,
        1,
        np.array([1.0, 2.0]),
        config,
        np.full((n, 3), 0.5),
        np.ones(n, bool),
        side.features,
        "float64",
    )
    assert all(np.isfinite(np.asarray(x)).all() for x in arr if np.asarray(x).dtype.kind in "fc")


def test_mollified_lengths_have_the_asked_slack():
    lengths = np.array([[1.0, 1.0, 2.0], [3.0, 4.0, 5.0]])
    out = mollified_lengths(lengths, 0.01)
    slack = out.sum(axis=1, keepdims=True) - 2 * out
    assert abs(slack.min() - 0.01) < 1e-12 and np.allclose(out - lengths, 0.01)
    np.testing.assert_array_equal(
        mollified_lengths(lengths[1:], 0.01), lengths[1:]
    )  # slack already 2


def test_lengths_equal_to_the_positions_give_the_same_tables():
    v, f = icosphere(2)
    lengths = edge_lengths(v, f)
    a, b = one_ring_neighborhood(v, f), one_ring_neighborhood(v, f, lengths=lengths)
    np.testing.assert_allclose(a.log, b.log)
    np.testing.assert_allclose(a.transport, b.transport)
    np.testing.assert_allclose(
        tracer_geometry(v, f).corners, tracer_geometry(v, f, lengths=lengths).corners
    )


@pytest.mark.parametrize("fn", [one_ring_neighborhood, tracer_geometry])
def test_bad_lengths_are_typed_errors(fn):
    v, f = icosphere(1)
    with pytest.raises(InputError, match="lengths must be finite, positive and"):
        fn(v, f, lengths=np.full(f.shape, np.nan))
    flat = np.ones(f.shape)
    flat[0] = (1.0, 1.0, 2.0)  # a triangle with zero area
    with pytest.raises(DegenerateFaceError):
        fn(v, f, lengths=flat)

"""fold_sheet and hinge: exact isometries (edge lengths kept), the expected motion, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from jmeshtex import InputError
from jmeshtex.data import grid, icosphere
from jmeshtex.geometry import edge_lengths
from jmeshtex.testing import fold_sheet, hinge


def test_single_fold_moves_the_far_side_rigidly():
    v, f = grid(8, 4, size=(2.0, 1.0))
    angle = 0.7
    out = fold_sheet(v, f, lines=[("x", 0.75)], angles=[angle])
    near = v[:, 0] <= 0.75 + 1e-12
    np.testing.assert_array_equal(out[near], v[near])
    d = v[~near, 0] - 0.75  # distance beyond the line
    np.testing.assert_allclose(out[~near, 0], 0.75 + d * np.cos(angle), atol=1e-15)
    np.testing.assert_allclose(out[~near, 2], d * np.sin(angle), atol=1e-15)  # positive angle lifts
    np.testing.assert_allclose(out[~near, 1], v[~near, 1], atol=0)
    np.testing.assert_allclose(edge_lengths(out, f), edge_lengths(v, f), rtol=1e-14)


@pytest.mark.parametrize(
    "lines, angles",
    [
        ([("x", 0.25), ("x", 0.5), ("x", 0.75)], [1.0, -2.0, 2.5]),
        ([("y", 0.375), ("y", 0.125)], [np.pi, 0.4]),  # given outer first: applied inner first
        ([("x", 0.75), ((0.25, 0.0), (-1.0, 0.0))], [0.8, 1.3]),  # two disjoint flaps
        ([((0.5, 0.5), (1.0, -1.0))], [2.0]),  # the diagonal y = x, a mesh line of the uniform grid
    ],
)
def test_folds_preserve_every_edge_length(lines, angles):
    v, f = grid(8, diagonals="uniform")
    v = v + np.array([0.0, 0.0, 0.25])  # any plane z = const
    out = fold_sheet(v, f, lines=lines, angles=angles)
    assert np.abs(out - v).max() > 0.1
    np.testing.assert_allclose(edge_lengths(out, f), edge_lengths(v, f), rtol=1e-14)
    # vertices on no moving side stay put
    still = np.ones(len(v), bool)
    for line in lines:
        p, n = (
            ((line[1], 0.0), (1.0, 0.0))
            if line[0] == "x"
            else ((0.0, line[1]), (0.0, 1.0))
            if line[0] == "y"
            else line
        )
        still &= (v[:, :2] - np.asarray(p, float)) @ np.asarray(n, float) <= 1e-12
    np.testing.assert_array_equal(out[still], v[still])


def test_nested_folds_compose_like_a_paper_strip():
    """Two folds of +90°: the far strip ends up upside down above the start."""
    v, f = grid(3, 1, size=(3.0, 1.0))
    out = fold_sheet(v, f, lines=[("x", 1.0), ("x", 2.0)], angles=[np.pi / 2, np.pi / 2])
    far = np.isclose(v[:, 0], 3.0)
    np.testing.assert_allclose(out[far][:, [0, 2]], [[0.0, 1.0]] * far.sum(), atol=1e-15)


def test_hinge_on_a_curved_mesh():
    v, f = icosphere(2)
    # the cap z > 0 is attached along the equator ring: not a hinge (the ring is not on one line)
    with pytest.raises(InputError, match="away from the axis"):
        hinge(
            v, f, moving=v[:, 2] > 1e-9, axis_point=[0, 0, 0], axis_direction=[1, 0, 0], angle=0.3
        )
    # the whole mesh is a rigid piece by itself
    out = hinge(
        v,
        f,
        moving=np.ones(len(v), bool),
        axis_point=[1, 2, 3],
        axis_direction=[0, 1, 1],
        angle=1.1,
    )
    np.testing.assert_allclose(edge_lengths(out, f), edge_lengths(v, f), rtol=1e-14)
    d = np.array([0, 1, 1]) / np.sqrt(2)
    np.testing.assert_allclose(
        (out - [1, 2, 3]) @ d, (v - [1, 2, 3]) @ d, atol=1e-14
    )  # axial part kept


def test_bad_input():
    v, f = grid(4)
    with pytest.raises(InputError, match="crosses"):
        fold_sheet(v, f, lines=[("x", 0.3)], angles=[1.0])  # between columns: cuts through faces
    with pytest.raises(InputError, match="cross inside"):
        fold_sheet(v, f, lines=[("x", 0.5), ("y", 0.5)], angles=[1.0, 1.0])
    with pytest.raises(InputError, match="one angle per line"):
        fold_sheet(v, f, lines=[("x", 0.5)], angles=[1.0, 2.0])
    with pytest.raises(InputError, match="flat sheet"):
        fold_sheet(v + np.array([[0, 0, 1]]) * v[:, :1], f, lines=[("x", 0.5)], angles=[1.0])
    with pytest.raises(InputError, match="'x' or 'y'"):
        fold_sheet(v, f, lines=[("z", 0.5)], angles=[1.0])
    with pytest.raises(InputError, match="non-zero normal"):
        fold_sheet(v, f, lines=[((0.5, 0.5), (0.0, 0.0))], angles=[1.0])
    with pytest.raises(InputError, match="axis_direction"):
        hinge(
            v, f, moving=v[:, 0] > 0.5, axis_point=[0.5, 0, 0], axis_direction=[0, 0, 0], angle=1.0
        )
    with pytest.raises(InputError, match="bool"):
        hinge(
            v,
            f,
            moving=np.arange(len(v)),
            axis_point=[0.5, 0, 0],
            axis_direction=[0, 1, 0],
            angle=1.0,
        )

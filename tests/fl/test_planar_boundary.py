"""Planar training meshes have no boundary slivers: the hull is sampled at the interior's spacing.

Before the boundary was sampled explicitly, Delaunay joined the corners to points a hair inside the
rectangle with triangles as long as a side (edge 1.5 against a median of 0.06 on the demo sheet),
which folded visibly once the sheet was bent and gave the corner vertices one-rings spanning the
sheet."""

from __future__ import annotations

import numpy as np
import pytest

from jmeshtex.fl.core import planar_mesh


@pytest.mark.parametrize(
    ("shape", "n"), [((100, 150, 3), 600), ((64, 64, 3), 200), ((40, 120, 3), 3000)]
)
def test_no_edge_much_longer_than_the_typical_one(shape, n):
    mesh = planar_mesh(np.zeros(shape), n, rng=np.random.default_rng(0))
    v, f = mesh.vertices, mesh.faces
    edges = np.linalg.norm(v[f[:, [1, 2, 0]]] - v[f], axis=-1)
    assert mesh.num_vertices == n
    assert edges.max() < 3.0 * np.median(edges), (edges.max(), np.median(edges))
    # every vertex is used and the sheet still covers the whole rectangle
    assert np.unique(f).size == n
    area = 0.5 * np.abs(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])[:, 2]).sum()
    np.testing.assert_allclose(area, shape[1] / shape[0], rtol=1e-9)


def test_tiny_meshes_keep_their_corners():
    mesh = planar_mesh(np.zeros((8, 8, 3)), 4, rng=np.random.default_rng(0))
    assert mesh.num_vertices == 4 and len(mesh.faces) == 2

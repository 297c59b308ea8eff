"""Transfer onto real meshes from ../shared/data: the open, multi-component teapot and the closed cow."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jmeshtex.dgts import transfer
from jmeshtex.geometry import boundary_loops, prepare_mesh
from jmeshtex.io import load_mesh


@pytest.mark.shared_data
@pytest.mark.parametrize("name, open_", [("teapot.obj", True), ("cow.obj", False)])
def test_transfer_on_real_meshes(shared_data, tiny_model, name, open_):
    mesh, _ = prepare_mesh(load_mesh(shared_data / name), repair=True)
    assert bool(boundary_loops(mesh.faces, mesh.num_vertices)) == open_
    res = transfer(tiny_model, mesh, start_level=1, key=jax.random.key(0))
    assert res.vertices.shape == (1, mesh.num_vertices, 3) and np.isfinite(res.vertices).all()
    scale = np.ptp(mesh.vertices, axis=0).max()
    assert np.abs(res.vertices[0] - mesh.vertices).max() < 0.2 * scale

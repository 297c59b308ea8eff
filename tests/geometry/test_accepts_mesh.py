"""Every host geometry function of a mesh takes a ``jmeshtex.Mesh`` where it takes its arrays."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from jmeshtex import geometry
from jmeshtex.data import icosphere

ARRAY_FIRST = {
    ("vertices", "faces"): "accepts_mesh",
    ("faces", "num_vertices"): "accepts_mesh_faces",
}


def _mesh_functions():
    for name in sorted(dir(geometry)):
        fn = getattr(geometry, name)
        if name.startswith("_") or not inspect.isfunction(fn):
            continue
        first = tuple(inspect.signature(inspect.unwrap(fn)).parameters)[:2]
        if first in ARRAY_FIRST:
            yield name, fn, first


def test_every_function_of_mesh_arrays_is_wrapped_to_take_a_mesh():
    found = list(_mesh_functions())
    assert len(found) >= 25
    unwrapped = [name for name, fn, _ in found if not hasattr(fn, "__wrapped__")]
    assert not unwrapped, f"decorate with jmeshtex._mesh.accepts_mesh(_faces): {unwrapped}"


@pytest.mark.parametrize(
    "name",
    [
        "one_ring_neighborhood",
        "geodesic_knn_neighborhood",
        "vertex_normals",
        "mean_edge_length",
        "edge_lengths",
        "tangent_frames",
        "face_neighborhood",
        "unique_edges",
        "connected_components",
        "boundary_edges",
    ],
)
def test_a_mesh_gives_what_its_arrays_give(name):
    mesh = icosphere(1)
    fn = getattr(geometry, name)
    first = tuple(inspect.signature(inspect.unwrap(fn)).parameters)[:2]
    arrays = (
        (mesh.vertices, mesh.faces) if first[0] == "vertices" else (mesh.faces, mesh.num_vertices)
    )
    by_mesh, by_arrays = fn(mesh), fn(*arrays)
    for a, b in zip(_leaves(by_mesh), _leaves(by_arrays), strict=True):
        np.testing.assert_array_equal(a, b)


def _leaves(x):
    if isinstance(x, tuple):
        return [leaf for item in x for leaf in _leaves(item)]
    if hasattr(x, "_asdict"):
        return [leaf for v in x._asdict().values() if v is not None for leaf in _leaves(v)]
    return [np.asarray(x)]

"""The embedded Spot is the author's mesh, atlas and texture (to float32 / 8-bit precision)."""

import numpy as np

from jmeshtex.data import spot
from jmeshtex.io import load_mesh


def test_embedded_spot_equals_the_authors_files(shared_data):
    folder = shared_data / "spot"
    ref = load_mesh(folder / "spot_triangulated.obj", texture=folder / "spot_texture.png")
    m = spot()
    np.testing.assert_array_equal(m.faces, ref.faces)
    np.testing.assert_allclose(m.vertices, ref.vertices, atol=1e-6)
    np.testing.assert_allclose(m.uv, ref.uv, atol=1e-6)
    np.testing.assert_allclose(m.texture, ref.texture[..., :3], atol=0.5 / 255 + 1e-6)


def test_embedded_spot_is_a_closed_textured_surface():
    m = spot()
    edges = np.sort(m.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert (counts == 2).all()  # closed and manifold: every edge in two faces
    assert m.num_vertices - len(counts) + m.num_faces == 2  # genus 0
    assert np.isfinite(m.uv).all()  # (the author's atlas reaches slightly past [0, 1])
    assert 0.0 <= m.texture.min() and m.texture.max() <= 1.0

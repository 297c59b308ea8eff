"""Real meshes from ../shared/data: Spot (textured, UV seams) and the untextured cow (xatlas)."""

import jax
import numpy as np

from jmeshtex.geometry import prepare_mesh, tracer_geometry
from jmeshtex.io import load_mesh
from jmeshtex.surfacecnn import Config, synthesize
from jmeshtex.surfacecnn.core import texel_pyramid, texel_taps, texture_atlas


def test_spot_closed_surface_taps_never_stop_and_cross_seams(shared_data):
    mesh = load_mesh(shared_data / "spot" / "spot_triangulated.obj")
    g = tracer_geometry(mesh.vertices, mesh.faces)
    atlas = texture_atlas(mesh.vertices, mesh.faces, mesh.uv, size=128, geometry=g)
    frames = atlas.frame
    np.testing.assert_allclose(
        np.einsum("nij,nkj->nik", frames, frames),
        np.broadcast_to(np.eye(3), frames.shape),
        atol=1e-12,
    )
    taps = texel_taps(mesh.vertices, mesh.faces, atlas, geometry=g)
    assert not taps.stopped.any()  # a closed surface: no walk hits a boundary
    # taps land about one texel away in UV space except across seams (jumps between charts)
    own = taps.end_uv[:, 4:5]
    jump = np.linalg.norm(taps.end_uv - own, axis=-1) * 128
    assert np.median(jump[:, [1, 3, 5, 7]]) < 2.0
    assert (jump > 10).any()  # some walks crossed a UV seam into another chart
    pyr = texel_pyramid(mesh.vertices, mesh.faces, atlas, levels=3, taps=taps, geometry=g)
    sizes = [len(r) for r in pyr.representative]
    assert all(a > b for a, b in zip(sizes, sizes[1:], strict=False))


def test_untextured_cow_is_unwrapped_and_synthesised(shared_data):
    mesh, report = prepare_mesh(
        load_mesh(shared_data / "cow.obj"), repair=True
    )  # splits one bow-tie vertex
    assert mesh.uv is None
    ex = np.random.default_rng(0).uniform(size=(16, 16, 3)) * [1.0, 0.5, 0.2]
    result = synthesize(
        mesh,
        ex,
        Config(size=32, steps=15),
        key=jax.random.key(0),
        layers=("relu1_1", "relu1_2"),
        progress=False,
    )
    assert result.mesh.uv.shape == (mesh.num_faces, 3, 2)
    assert result.final_loss < 0.5 * result.losses[0]

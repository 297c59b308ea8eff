"""Surface patches: an exemplar mapped isometrically onto a plane scores at the crop floor."""

import jax
import numpy as np
import pytest
import skimage.data

from jmeshtex import InputError, Mesh
from jmeshtex.data import grid, icosphere
from jmeshtex.metrics import (
    exemplar_crops,
    log_radial_spectrum,
    surface_patch_table,
    surface_patches,
    uv_charts,
)


@pytest.fixture(scope="module")
def plane_table():
    ex = skimage.data.brick()[:256, :256].astype(np.float64) / 255.0
    ex = np.repeat(ex[..., None], 3, axis=2)
    v, f = grid(4)
    mesh = Mesh(v, f, uv=v[f][..., :2])  # the unit square, UV = xy: 1 texel = 1/256
    noise = np.random.default_rng(0).uniform(0, 0.2, size=ex.shape)
    return surface_patch_table(
        mesh, ex, ex, step=1 / 256, key=jax.random.key(3), num=24, initial=noise
    )


def test_isometric_exemplar_scores_at_the_floor(plane_table):
    t = plane_table
    # the exemplar itself on the plane: patches are exemplar crops (up to walks stopped by the
    # square's border and the crops' sampling): within the crop-to-crop spread
    assert t["texture"]["gram"] < 2.0 * t["floor"]["gram"]
    assert t["texture"]["spectrum"] < 2.0 * t["floor"]["spectrum"]
    for baseline in ("flat", "permuted", "initial"):
        assert t[baseline]["gram"] > 3 * t["texture"]["gram"], baseline
        assert t[baseline]["spectrum"] > 3 * t["texture"]["spectrum"], baseline
    assert t["texture"]["charts"] == 1.0 and t["texture"]["off_chart"] == 0.0


def test_patches_on_the_plane_are_the_image_rows_and_columns():
    v, f = grid(2)
    mesh = Mesh(v, f, uv=v[f][..., :2])
    p = surface_patches(mesh, num=3, step=0.01, size=4, key=jax.random.key(0))
    # columns grow along +u, rows along −v (image rows), one step apart
    np.testing.assert_allclose(np.diff(p.uv[..., 0], axis=2), 0.01, atol=1e-9)
    np.testing.assert_allclose(np.diff(p.uv[..., 1], axis=1), -0.01, atol=1e-9)


def test_seam_crossings_counted_on_an_unwrapped_sphere():
    from jmeshtex.surfacecnn import unwrap_uv

    m = icosphere(2)
    mesh = Mesh(m.vertices, m.faces, uv=unwrap_uv(m.vertices, m.faces))
    assert len(np.unique(uv_charts(mesh.faces, mesh.uv))) > 1
    p = surface_patches(mesh, num=16, step=0.05, size=16, key=jax.random.key(1))
    assert p.charts.max() > 1 and (p.off_chart > 0).any()
    assert (p.stopped == 0).all()  # closed surface


def test_spectrum_sees_structure_the_mean_hides():
    rng = np.random.default_rng(0)
    noise = rng.uniform(size=(4, 32, 32, 3))
    flat = np.full_like(noise, 0.5)
    assert (log_radial_spectrum(noise) > log_radial_spectrum(flat) + 5).all()


def test_bad_input_is_refused():
    v, f = grid(1)
    with pytest.raises(InputError, match="no UVs"):
        surface_patches(Mesh(v, f), num=1, step=0.1, key=jax.random.key(0))
    with pytest.raises(InputError, match="spans"):
        exemplar_crops(np.zeros((8, 8, 3)), num=1, size=16, key=jax.random.key(0))

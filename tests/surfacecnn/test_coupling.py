"""Every texel coupled: chart-border texels read by a neighbour or tied to the texels they abut."""

import jax
import jax.numpy as jnp
import numpy as np

from jmeshtex import Mesh
from jmeshtex.data import grid, icosphere
from jmeshtex.geometry import tracer_geometry
from jmeshtex.io import load_mesh
from jmeshtex.ops import TexelNeighborhood, texel_conv
from jmeshtex.surfacecnn import Config, prepare_surface, synthesize, unwrap_uv
from jmeshtex.surfacecnn._neighborhood import _read_through
from jmeshtex.surfacecnn.core import (
    apply_tie,
    border_ties,
    read_counts,
    seam_chroma,
    texel_density_spread,
    texel_taps,
    texture_atlas,
    unread_share,
)


def _is_free(tie):
    index, weight = tie
    return (index[:, 0] == np.arange(len(index))) & (weight[:, 0] == 1.0)


def _check_tie(tie):
    index, weight = tie
    np.testing.assert_allclose(weight.sum(axis=1), 1.0, atol=1e-12)
    assert (weight >= 0).all()
    free = _is_free(tie)
    # a tied texel shows only free texels (no chains), and never itself
    used = weight > 0
    assert free[index[used]].all() or free.all()
    tied = np.nonzero(~free)[0]
    assert not (index[tied][used[tied]] == np.repeat(tied, used[tied].sum(axis=1))).any()


def test_spot_every_texel_is_coupled(shared_data):
    mesh = load_mesh(shared_data / "spot" / "spot_triangulated.obj")
    atlas = texture_atlas(mesh.vertices, mesh.faces, mesh.uv, size=128)
    loose = texel_taps(mesh.vertices, mesh.faces, atlas, boundary="opposite", couple=False)
    taps = texel_taps(mesh.vertices, mesh.faces, atlas, boundary="opposite")
    assert unread_share(loose)["nearest"] > 0.01  # Spot's chart borders: the failure mode
    assert unread_share(taps) == {"nearest": 0.0, "bilinear": 0.0, "either": 0.0}
    _check_tie(taps.tie)
    assert 0.02 < (~_is_free(taps.tie)).mean() < 0.2  # the partially covered border texels


def test_xatlas_icosphere_every_texel_is_coupled():
    v, f = icosphere(2).vertices, icosphere(2).faces
    atlas = texture_atlas(v, f, unwrap_uv(v, f), size=48)
    loose = texel_taps(v, f, atlas, couple=False)
    taps = texel_taps(v, f, atlas)
    assert unread_share(loose)["either"] > 0
    assert unread_share(taps)["either"] == 0.0
    _check_tie(taps.tie)


def test_flat_sheet_has_no_ties_and_keeps_its_taps():
    v, f = grid(2)
    atlas = texture_atlas(v, f, v[f][..., :2], size=8)
    taps, loose = texel_taps(v, f, atlas), texel_taps(v, f, atlas, couple=False)
    assert _is_free(taps.tie).all()
    np.testing.assert_array_equal(taps.bilinear.index, loose.bilinear.index)
    np.testing.assert_array_equal(taps.nearest.index, loose.nearest.index)
    assert (read_counts(taps.nearest) >= 3).all()


def test_read_through_equals_convolving_the_tied_colours():
    rng = np.random.default_rng(0)
    N = 30
    index = rng.integers(0, N, size=(N, 9, 4))
    weight = rng.uniform(size=(N, 9, 4)) * (rng.uniform(size=(N, 9, 4)) > 0.3)
    tie_index = np.tile(np.arange(N)[:, None], (1, 4))
    tie_weight = np.zeros((N, 4))
    tie_weight[:, 0] = 1.0
    tied = rng.choice(N, 8, replace=False)
    free = np.setdiff1d(np.arange(N), tied)
    tie_index[tied] = rng.choice(free, size=(8, 4))
    tie_weight[tied] = rng.dirichlet(np.ones(4), size=8)
    idx, w = _read_through(index, weight, (tie_index, tie_weight))
    assert idx.shape[-1] >= 4
    x = jnp.asarray(rng.normal(size=(N, 3)))
    k = jnp.asarray(rng.normal(size=(3, 3, 3, 5)))
    mask = np.ones(N, bool)
    got = texel_conv(x, TexelNeighborhood(idx, w, mask), k, jnp.zeros(5))
    want = texel_conv(
        apply_tie(x, (tie_index, tie_weight)),
        TexelNeighborhood(index, weight, mask),
        k,
        jnp.zeros(5),
    )
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)


def test_synthesis_shows_tied_colours():
    m = icosphere(2)
    mesh = Mesh(m.vertices, m.faces, uv=unwrap_uv(m.vertices, m.faces))
    surface = prepare_surface(mesh, size=32, levels=1)
    tie = surface.pyramid.tie
    assert not _is_free(tie).all()
    r = synthesize(
        mesh,
        np.random.default_rng(0).uniform(size=(16, 16, 3)),
        Config(size=32, steps=3),
        key=jax.random.key(0),
        layers=("relu1_1", "pool1"),
        surface=surface,
        progress=False,
    )
    c = np.asarray(r.colors, np.float64)
    np.testing.assert_allclose(apply_tie(c, tie), c, atol=1e-6)  # tied texels show their tie


def test_border_ties_identity_without_partial_texels():
    v, f = grid(2)
    index, weight = border_ties(texture_atlas(v, f, v[f][..., :2], size=8))
    assert (index[:, 0] == np.arange(64)).all() and (weight[:, 0] == 1).all()


def test_seam_chroma_flags_coloured_borders():
    v, f = icosphere(2).vertices, icosphere(2).faces
    atlas = texture_atlas(v, f, unwrap_uv(v, f), size=32)
    geometry = tracer_geometry(v, f)
    grey = np.full((atlas.num_texels, 3), 0.5)
    grey[:, 0] += 0.1
    assert abs(seam_chroma(atlas, grey, geometry)["ratio"] - 1) < 1e-12
    from jmeshtex.surfacecnn.core import border_texels

    specks = grey.copy()
    specks[border_texels(atlas, geometry), 1] = 1.0
    assert seam_chroma(atlas, specks, geometry)["ratio"] > 3


def test_texel_density_spread_even_for_xatlas(shared_data):
    mesh = load_mesh(shared_data / "spot" / "spot_triangulated.obj")
    own = texel_density_spread(mesh.vertices, mesh.faces, mesh.uv)
    xat = texel_density_spread(mesh.vertices, mesh.faces, unwrap_uv(mesh.vertices, mesh.faces))
    assert xat["ratio_p95_p5"] < 1.3 < 2 < own["ratio_p95_p5"]

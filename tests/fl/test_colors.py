"""SurfaceColors: texture (bilinear UV lookup) and vertex-colour (barycentric) sources."""

from __future__ import annotations

import numpy as np
import pytest

from jmeshtex import InputError, Mesh
from jmeshtex.data import grid
from jmeshtex.fl.core import surface_colors


def _textured_grid(n=4):
    v, f = grid(n)
    tex = np.zeros((8, 8, 3), np.float32)
    tex[..., 0] = np.linspace(0, 1, 8)[None, :]  # red grows to the right (u)
    tex[..., 1] = np.linspace(1, 0, 8)[:, None]  # green grows upwards (v; row 0 is the top)
    return Mesh(v, f, uv=v[f][..., :2], texture=tex)


def test_vertex_colors_interpolate_barycentrically_exactly(rng):
    v, f = grid(3)
    colors = rng.random((len(v), 3))
    sc = surface_colors(Mesh(v, f, vertex_colors=colors))
    face = rng.integers(0, len(f), 20)
    bary = rng.dirichlet(np.ones(3), 20)
    expected = np.einsum("nk,nkc->nc", bary, colors[f[face]])
    np.testing.assert_allclose(sc.at_barycentric(face, bary), expected, atol=1e-12)


def test_texture_lookup_is_bilinear_in_uv():
    mesh = _textured_grid()
    sc = surface_colors(mesh)
    assert sc.source == "texture"
    # a linear ramp is reproduced exactly by bilinear interpolation between texel centres
    face = np.arange(mesh.num_faces)
    bary = np.full((mesh.num_faces, 3), 1 / 3)
    uv = np.einsum("nk,nkd->nd", bary, mesh.uv)
    inner = (uv[:, 0] > 1 / 16) & (uv[:, 0] < 15 / 16) & (uv[:, 1] > 1 / 16) & (uv[:, 1] < 15 / 16)
    rgb = sc.at_barycentric(face, bary)
    np.testing.assert_allclose(rgb[inner, 0], (uv[inner, 0] * 8 - 0.5) / 7, atol=1e-6)
    np.testing.assert_allclose(rgb[inner, 1], (uv[inner, 1] * 8 - 0.5) / 7, atol=1e-6)


def test_at_points_matches_barycentric_lookup_on_a_retriangulated_copy(rng):
    mesh = _textured_grid(4)
    sc = surface_colors(mesh)
    face = rng.integers(0, mesh.num_faces, 30)
    bary = rng.dirichlet(np.ones(3), 30)
    points = np.einsum("nk,nkd->nd", bary, mesh.vertices[mesh.faces[face]])
    np.testing.assert_allclose(sc.at_points(points), sc.at_barycentric(face, bary), atol=1e-9)
    # points slightly off the surface project onto it
    np.testing.assert_allclose(
        sc.at_points(points + [0, 0, 0.01]), sc.at_barycentric(face, bary), atol=1e-9
    )


def test_grey_and_alpha_textures_become_rgb():
    v, f = grid(1)
    grey = np.full((4, 4, 1), 0.25, np.float32)
    sc = surface_colors(Mesh(v, f, uv=v[f][..., :2], texture=grey))
    assert sc.at_barycentric(np.array([0]), np.array([[1.0, 0, 0]])).tolist() == [
        [0.25, 0.25, 0.25]
    ]


def test_missing_colour_source_is_a_typed_error():
    v, f = grid(1)
    with pytest.raises(InputError, match="neither a UV texture nor vertex colours"):
        surface_colors(Mesh(v, f))
    with pytest.raises(InputError, match="no UV coordinates"):
        surface_colors(Mesh(v, f, texture=np.zeros((2, 2, 3))))
    with pytest.raises(InputError, match="bary must have shape"):
        surface_colors(Mesh(v, f, vertex_colors=np.ones((4, 3)))).at_barycentric(
            np.array([0]), np.ones((2, 3))
        )

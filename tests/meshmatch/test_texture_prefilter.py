"""Source colours from a UV texture: the area prefilter (the vertex's hat-weighted one-ring mean)
against point samples at the corners."""

from __future__ import annotations

import numpy as np
import pytest

from jmeshtex import InputError, Mesh
from jmeshtex.data import grid
from jmeshtex.meshmatch import vertex_colors_from_texture


def _sheet(texture, cells=8):
    """The unit square in ``cells × cells`` cells, uv = (x, y), with ``texture``."""
    v, f = grid(cells)
    return Mesh(v, f, uv=v[f][..., :2], texture=np.asarray(texture, np.float32))


def _checker(size, cell):
    i, j = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    return np.repeat((((i // cell) + (j // cell)) % 2).astype(np.float64)[..., None], 3, axis=2)


def test_a_checker_finer_than_the_vertices_averages_out_instead_of_aliasing():
    """Vertices 32 texels apart on a checker of 5-texel squares: point samples land on either
    square (0 or 1), the area prefilter gives about the checker's mean everywhere."""
    mesh = _sheet(_checker(256, 5))
    point = vertex_colors_from_texture(mesh, prefilter="point")[:, 0]
    area = vertex_colors_from_texture(mesh)[:, 0]
    assert point.std() > 0.3  # aliased: the samples keep the squares' extremes
    assert np.isin(np.round(point, 6), [0.0, 1.0]).mean() > 0.6
    assert abs(area.mean() - 0.5) < 0.05
    assert area.std() < 0.06
    assert np.abs(area - 0.5).max() < 0.2


def test_smooth_textures_keep_their_values():
    """A linear ramp is kept at interior vertices (their rings are point-symmetric), a constant
    everywhere; the filter only removes what the vertices cannot hold."""
    size = 128
    u = (np.arange(size) + 0.5) / size
    ramp = np.repeat(np.repeat(u[None, :, None], size, axis=0), 3, axis=2)  # value = u
    mesh = _sheet(ramp)
    area = vertex_colors_from_texture(mesh)[:, 0]
    x = mesh.vertices
    interior = (x[:, 0] > 0) & (x[:, 0] < 1) & (x[:, 1] > 0) & (x[:, 1] < 1)
    np.testing.assert_allclose(area[interior], x[interior, 0], atol=2e-3)
    flat = vertex_colors_from_texture(_sheet(np.full((16, 16, 3), 0.3)))
    np.testing.assert_allclose(flat, 0.3, atol=1e-6)


def test_the_prefilter_is_checked():
    mesh = _sheet(np.zeros((4, 4, 3)))
    with pytest.raises(InputError, match="prefilter"):
        vertex_colors_from_texture(mesh, prefilter="gaussian")
    with pytest.raises(InputError, match="no UV texture"):
        vertex_colors_from_texture(Mesh(mesh.vertices, mesh.faces))


def test_transfer_reads_a_texture_through_the_area_prefilter():
    """``transfer`` matches the area-filtered colours by default (a self-transfer of the fine
    checker comes out near its mean), point samples on request (then it keeps 0 / 1 extremes)."""
    import jax

    from jmeshtex.meshmatch import Config, transfer

    mesh = _sheet(_checker(256, 5))
    cfg = Config(levels=1, steps=2, coarse_steps=4, hks_eigenpairs=8)
    area = transfer(mesh, Mesh(mesh.vertices, mesh.faces), key=jax.random.key(0), config=cfg)
    point = transfer(
        mesh,
        Mesh(mesh.vertices, mesh.faces),
        key=jax.random.key(0),
        config=cfg,
        texture_prefilter="point",
    )
    assert np.abs(area.mesh.vertex_colors[:, 0] - 0.5).max() < 0.2
    assert point.mesh.vertex_colors[:, 0].std() > 0.3

"""Orientation across UV seams: a 3D-continuous stripe field runs straight over a seam, stripes laid
out in UV space turn there, and unrelated directions score 2/π."""

import numpy as np
import pytest

from jmeshtex import InputError, Mesh
from jmeshtex.data import grid
from jmeshtex.metrics import RANDOM_ALIGNMENT, seam_orientation, stripe_texture


def two_charts(n: int = 16) -> Mesh:
    """The unit square cut along x = 0.5; the right half's chart is turned by 90° in UV."""
    v, f = grid(n)
    xy = v[f][..., :2]
    left = (xy[..., 0].mean(axis=1) < 0.5)[:, None, None]
    turned = np.stack([0.5 + 0.45 * xy[..., 1], 0.52 + 0.45 * (1.0 - xy[..., 0])], axis=-1)
    return Mesh(v, f, uv=np.where(left, 0.02 + 0.45 * xy, turned))


def test_separates_seamless_stripes_from_stripes_that_turn_at_the_seam():
    mesh = two_charts()
    control = seam_orientation(mesh, stripe_texture(mesh, 128, direction=(1, 0.4, 0), period=0.1))
    assert control.seam_edges == 16 and control.interior_edges > 500
    assert control.seam > 0.99 and control.interior > 0.99
    # the same stripes laid out in the image: straight in every chart, turned 90° at the seam
    yy, xx = np.mgrid[0:128, 0:128]
    image = 0.5 + 0.5 * np.cos(2 * np.pi * (xx * np.cos(0.5) + yy * np.sin(0.5)) / 6.0)
    turned = seam_orientation(mesh, image)
    assert turned.interior > 0.99
    assert turned.seam < 0.05


def test_unrelated_directions_score_two_over_pi():
    mesh = two_charts(32)  # 32 seam edges
    rng = np.random.default_rng(0)
    seam = [seam_orientation(mesh, rng.uniform(size=(128, 128, 3))).seam for _ in range(8)]
    assert abs(np.mean(seam) - RANDOM_ALIGNMENT) < 0.08  # 256 edges, sd of |cos| 0.31 / 16


def test_a_fold_does_not_change_alignment():
    """Unfolding across an edge keeps 3D-continuous stripes aligned on a bent sheet."""
    mesh = two_charts()
    v = np.asarray(mesh.vertices, np.float64).copy()
    bent = v[:, 0] > 0.5
    v[bent, 2] = (v[bent, 0] - 0.5) * np.sin(0.6)
    v[bent, 0] = 0.5 + (v[bent, 0] - 0.5) * np.cos(0.6)
    folded = Mesh(v, mesh.faces, uv=mesh.uv)
    r = seam_orientation(folded, stripe_texture(folded, 128, direction=(0.3, 1, 0), period=0.1))
    assert r.seam > 0.98
    np.testing.assert_allclose(r.edge_dihedral[r.edge_seam], np.degrees(0.6), atol=1e-6)
    assert r.seam_at(30.0, 180.0) == r.seam and np.isnan(r.seam_at(0.0, 30.0))


def test_rejects_bad_input():
    v, f = grid(2)
    with pytest.raises(InputError):
        seam_orientation(Mesh(v, f), np.zeros((8, 8, 3)))
    with pytest.raises(InputError):
        seam_orientation(Mesh(v, f, uv=v[f][..., :2]), np.zeros((8, 4, 3)))

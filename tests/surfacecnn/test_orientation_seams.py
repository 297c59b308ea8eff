"""Oriented stripes synthesised on a cylinder cut into two charts run straight across the long seams.

The two halves of the cylinder are laid out as two UV charts, the second turned by 60° in the
image, so a texture that followed the UV layout would turn by 60° at both seams (alignment
cos 60° = 0.5), while the surface frames (the cylinder's axis) are continuous across them.
"""

import jax
import numpy as np
import pytest

from jmeshtex import Mesh
from jmeshtex.metrics import RANDOM_ALIGNMENT, seam_orientation, stripe_texture
from jmeshtex.surfacecnn import Config, prepare_surface, synthesize, synthesize_uv
from jmeshtex.surfacecnn.core import tap_fidelity

LAYERS = ("relu1_1", "relu1_2", "pool1", "relu2_1", "relu2_2", "pool2", "relu3_1")
SIZE, AXIS = 80, (0.0, 0.0, 1.0)


def cut_cylinder(n_theta: int = 48, n_z: int = 16, turn: float = np.deg2rad(60.0)) -> Mesh:
    """An open cylinder (radius 1, height 2) whose halves θ < π and θ > π are two UV charts."""
    theta = np.arange(n_theta) * 2 * np.pi / n_theta
    z = np.linspace(0.0, 2.0, n_z + 1)
    vertices = np.array([[np.cos(t), np.sin(t), h] for h in z for t in theta])
    scale = 0.14

    def chart(s, h, second):
        if not second:
            return (0.03 + scale * s, 0.03 + scale * h)
        x, y = scale * (s - 1.5 * np.pi), scale * (h - 1.0)
        c, si = np.cos(turn), np.sin(turn)
        return (0.5 + c * x - si * y, 0.66 + si * x + c * y)

    faces, uv = [], []
    for j in range(n_z):
        for i in range(n_theta):
            a, b = j * n_theta + i, j * n_theta + (i + 1) % n_theta
            c, d = b + n_theta, a + n_theta
            s0, s1, second = theta[i], theta[i] + 2 * np.pi / n_theta, theta[i] > np.pi - 1e-9
            for tri, pts in (
                ((a, b, c), ((s0, z[j]), (s1, z[j]), (s1, z[j + 1]))),
                ((a, c, d), ((s0, z[j]), (s1, z[j + 1]), (s0, z[j + 1]))),
            ):
                faces.append(tri)
                uv.append([chart(s, h, second) for s, h in pts])
    return Mesh(vertices, np.array(faces), uv=np.array(uv))


def diagonal_stripes(n: int = 64, period: float = 8.0) -> np.ndarray:
    yy, xx = np.mgrid[0:n, 0:n]
    s = 0.5 + 0.5 * np.cos(2 * np.pi * (xx + yy) / np.sqrt(2) / period)
    s = np.clip((s - 0.5) * 2.0 + 0.5, 0.0, 1.0)[..., None]
    return (0.15 + 0.75 * s) * np.ones(3)


@pytest.fixture(scope="module")
def cylinder():
    mesh = cut_cylinder()
    surface = prepare_surface(mesh, size=SIZE, levels=2, frame_vector=AXIS)
    return mesh, surface


def test_the_layout_has_two_long_seams_and_continuous_frames(cylinder):
    mesh, surface = cylinder
    control = seam_orientation(mesh, stripe_texture(mesh, SIZE, direction=(0, 1, 1), period=0.6))
    assert control.seam_edges >= 24  # both vertical seams, 16 edges each, minus faces too thin
    assert control.seam > 0.97 and control.interior > 0.97


def test_border_taps_read_where_interior_taps_read(cylinder):
    """Per level, the taps of nodes at a chart border land as far and in the same direction (in the
    node's frame) as the taps of nodes inside a chart."""
    mesh, surface = cylinder
    fidelity = tap_fidelity(mesh, surface)
    for level in fidelity:
        border, inside = level["seam"], level["inside"]
        assert border["angle_deg"] <= inside["angle_deg"] + 6.0, level
        assert abs(border["length"] - inside["length"]) <= 0.15, level


@pytest.mark.slow
def test_stripes_run_straight_across_the_seams(cylinder, key):
    mesh, surface = cylinder
    config = Config(size=SIZE, steps=120, frame_vector=AXIS, unwrap="mesh", layers=LAYERS)
    kw = dict(key=jax.random.key(0), surface=surface, progress=False)
    laid = mesh.replace(uv=surface.atlas.uv)
    result = seam_orientation(laid, synthesize(mesh, diagonal_stripes(), config, **kw).texture)
    flat = seam_orientation(laid, synthesize_uv(mesh, diagonal_stripes(), config, **kw).texture)
    print(
        f"seam {result.seam:.3f} / interior {result.interior:.3f}; UV-space 2D {flat.seam:.3f} / {flat.interior:.3f}"
    )
    assert result.interior > 0.95 and flat.interior > 0.95  # straight stripes inside the charts
    assert flat.seam < 0.7  # the UV-space synthesis turns by the charts' 60° at the seams
    assert result.seam > 0.9 and result.seam > RANDOM_ALIGNMENT + 0.2, (result.seam, flat.seam)

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


# --- a crease: a sheet folded by 90°, the global vector oblique to the fold ---------------------

FOLD_VECTOR = (1.0, 1.0, 0.0)  # projected: 45° to the fold line below it, along it above it


def folded_sheet(n: int = 32, charts: bool = False, turn: float = np.deg2rad(60.0)) -> Mesh:
    """A 1 × 2 sheet in intrinsic coordinates ``(x, y)``, ``y ∈ [−1, 1]``, folded by 90° along
    ``y = 0``: ``(x, y, 0)`` below the fold, ``(x, 0, y)`` above it (faces meet at a 90° dihedral).
    One UV chart, or (``charts``) the halves as two charts, the upper one turned by ``turn``."""
    xs, ys = np.linspace(0.0, 1.0, n + 1), np.linspace(-1.0, 1.0, 2 * n + 1)
    X, Y = np.meshgrid(xs, ys)
    X, Y = X.ravel(), Y.ravel()
    vertices = np.stack([X, np.minimum(Y, 0.0), np.maximum(Y, 0.0)], axis=1)
    idx = np.arange(len(X)).reshape(2 * n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    faces = np.concatenate(
        [np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]
    )
    upper = Y[faces].mean(axis=1) > 0
    st = np.stack([X, Y], axis=1)[faces]  # [F, 3, 2] intrinsic coordinates
    if not charts:
        uv = 0.02 + 0.96 * np.stack([st[..., 0] * 0.5, (st[..., 1] + 1.0) * 0.5], axis=-1)
    else:  # the same texel density in both charts: 0.32 UV units per unit of length
        uv = np.empty_like(st)
        uv[~upper] = 0.03 + 0.32 * (st[~upper] + np.array([0.0, 1.0]))
        c_, s_ = np.cos(turn), np.sin(turn)
        rotated = 0.32 * st[upper] @ np.array([[c_, s_], [-s_, c_]])
        uv[upper] = rotated - rotated.reshape(-1, 2).min(axis=0) + np.array([0.5, 0.03])
    return Mesh(vertices, faces, uv=uv)


def _intrinsic_angle(atlas) -> tuple[np.ndarray, np.ndarray]:
    """Per texel its intrinsic ``y`` and the angle (degrees) of its frame ``t`` in the unfolded
    sheet: ``(t_x, t_y)`` below the fold, ``(t_x, t_z)`` above it."""
    p, t = atlas.point, atlas.frame[:, 0]
    above = p[:, 2] > 1e-12
    y = np.where(above, p[:, 2], p[:, 1])
    return y, np.degrees(np.arctan2(np.where(above, t[:, 2], t[:, 1]), t[:, 0]))


@pytest.mark.parametrize("smoothing", [0.0, 4.0])
def test_frames_turn_gradually_across_a_crease(smoothing):
    """The paper's frames (``frame_smoothing=0``) turn by the fold's whole 45° intrinsic kink within
    about one face at the crease; smoothed over 4 texels, texel rows one texel apart differ by at
    most 45° / (2·4) (the slope of the heat step's response at the crease) plus the discretisation's
    slack, the two sides meet halfway, and far from the crease the frames are the projected vector."""
    from jmeshtex.surfacecnn.core import texture_atlas

    mesh = folded_sheet()
    atlas = texture_atlas(
        mesh.vertices,
        mesh.faces,
        mesh.uv,
        size=64,
        frame_vector=FOLD_VECTOR,
        frame_smoothing=smoothing,
    )
    h = atlas.texel_size
    y, angle = _intrinsic_angle(atlas)
    rows = np.round(y / h).astype(int)
    mean = {r: angle[rows == r].mean() for r in np.unique(rows)}
    steps = [abs(mean[r + 1] - mean[r]) for r in mean if r + 1 in mean]
    far = np.abs(y) > 6 * max(smoothing, 1.0) * h
    expected = np.where(y[far] < 0, 45.0, 0.0)
    np.testing.assert_allclose(angle[far], expected, atol=0.5)  # the projected vector
    if smoothing == 0.0:
        assert max(steps) > 20.0, max(steps)  # the kink sits between two texel rows
    else:
        assert max(steps) < 45.0 / (2 * smoothing) + 3.0, max(steps)  # 7.3° measured
        assert abs(np.median(angle[np.abs(y) < 0.5 * h]) - 22.5) < 3.0  # meets halfway


def test_frame_smoothing_is_refused_when_negative():
    from jmeshtex import InputError
    from jmeshtex.surfacecnn.core import texture_atlas, vertex_directions

    mesh = folded_sheet(4)
    with pytest.raises(InputError, match="frame_smoothing"):
        texture_atlas(mesh.vertices, mesh.faces, mesh.uv, size=8, frame_smoothing=-1.0)
    with pytest.raises(InputError, match="smoothing"):
        vertex_directions(mesh.vertices, mesh.faces, smoothing=float("nan"))


def column_stripes(n: int = 64, period: float = 8.0) -> np.ndarray:
    """A sine along the exemplar's columns: the stripe normal is the frames' ``t``."""
    s = 0.5 + 0.5 * np.sin(2 * np.pi * np.arange(n) / period)
    return np.repeat(np.repeat(s[None, :, None], n, 0), 3, 2)


@pytest.mark.slow
def test_stripes_continue_across_a_crease_seam():
    """Stripes synthesised on a sheet folded by 90° and cut into two UV charts at the fold (the
    upper one turned by 60° in the image) continue across the crease with the default frames; the
    paper's frames, which turn by the 45° kink of the projected vector at the crease, leave them
    turning there."""
    from jmeshtex.surfacecnn.core import FRAME_SMOOTHING

    mesh = folded_sheet(24, charts=True)
    config = Config(size=64, steps=100, frame_vector=FOLD_VECTOR, unwrap="mesh", layers=LAYERS)
    result = {}
    for smoothing in (0.0, FRAME_SMOOTHING):
        surface = prepare_surface(
            mesh, size=64, levels=2, frame_vector=FOLD_VECTOR, frame_smoothing=smoothing
        )
        kw = dict(key=jax.random.key(0), surface=surface, progress=False)
        texture = synthesize(mesh, column_stripes(), config, **kw).texture
        result[smoothing] = seam_orientation(mesh.replace(uv=surface.atlas.uv), texture)
    paper, smoothed = result[0.0], result[FRAME_SMOOTHING]
    print(
        f"crease seam {paper.seam:.3f} (paper's frames) / {smoothed.seam:.3f} (smoothed); "
        f"interior {paper.interior:.3f} / {smoothed.interior:.3f}; {smoothed.seam_edges} edges"
    )
    assert smoothed.seam_edges >= 16  # the fold's 24 edges, less faces with too few texels
    assert smoothed.interior > 0.95 and paper.interior > 0.95  # straight inside the charts
    assert smoothed.seam > 0.9, smoothed.seam  # continues across the crease
    assert smoothed.seam > paper.seam + 0.05, (paper.seam, smoothed.seam)

"""Off-screen rendering: image contents (silhouette, depth order, colour sources, textures), PNGs, errors."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import matplotlib.image
import numpy as np
import pytest

from jmeshtex import InputError, Mesh, MeshIOError
from jmeshtex.data import grid, icosphere, torus
from jmeshtex.geometry import boundary_edges
from jmeshtex.render import render_grid, render_mesh

TOP = (90.0, -90.0)  # looking down -z: x to the right, y up


def _not_white(img: np.ndarray) -> np.ndarray:
    return (img < 250).any(axis=2)


def test_image_size_dtype_and_sphere_silhouette():
    v, f = icosphere(3)
    img = render_mesh((v, f), size=(160, 120))
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8
    # the bounding sphere fills 92 % of the shorter side: a centred disc of diameter ~110 px
    mask = _not_white(img)
    ys, xs = np.nonzero(mask)
    assert 100 <= np.ptp(xs) + 1 <= 116 and 100 <= np.ptp(ys) + 1 <= 116
    assert abs(xs.mean() - 80) < 4 and abs(ys.mean() - 60) < 4
    disc = np.pi * (np.ptp(xs) + 1) * (np.ptp(ys) + 1) / 4
    assert abs(mask.sum() / disc - 1) < 0.05


def test_flat_shading_depends_on_the_light():
    v, f = icosphere(3)
    img = render_mesh((v, f), size=(128, 128)).astype(float)
    lit = img[_not_white(img.astype(np.uint8))].mean(axis=1)
    # the light sits above-left of the camera: a range of brightness, brightest upper left
    assert lit.max() - lit.min() > 60
    assert img[40, 40].mean() > img[88, 88].mean() + 20


def _two_squares(near_first: bool):
    """Two horizontal squares, the near one (z = 1) red, the far one (z = 0) blue, overlapping."""
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    near = np.c_[sq, np.ones(4)]
    far = np.c_[sq * 2 - 0.5, np.zeros(4)]
    quads = np.array([[0, 1, 2], [0, 2, 3]])
    v = np.concatenate([near, far]) if near_first else np.concatenate([far, near])
    f_near, f_far = (quads, quads + 4) if near_first else (quads + 4, quads)
    f = np.concatenate([f_near, f_far])
    colors = np.array([[1.0, 0, 0]] * 2 + [[0, 0, 1.0]] * 2)
    return v, f, colors


@pytest.mark.parametrize("near_first", [True, False])
def test_painter_order_by_depth_not_by_input_order(near_first):
    v, f, colors = _two_squares(near_first)
    img = render_mesh((v, f), face_colors=colors, view=TOP, size=(100, 100)).astype(int)
    center = img[50, 50]
    assert center[0] > 150 and center[2] < 60  # the near red square hides the blue one
    corner = img[
        25, 75
    ]  # only the far square covers this pixel (x = y = 1.31; near: [0, 1], far: [-0.5, 1.5])
    assert corner[2] > 150 and corner[0] < 60


def test_scalars_follow_the_colormap():
    v, f = grid(16)
    img = render_mesh((v, f), scalars=v[:, 0], cmap="gray", view=TOP, size=(100, 100)).astype(int)
    # dark on the left, bright on the right (per-face means of x jitter within a grid cell, so
    # compare averages over columns of pixels)
    thirds = img[30:70, 22:79, 0].reshape(40, 3, 19).mean(axis=(0, 2))
    assert thirds[0] + 40 < thirds[1] < thirds[2] - 40
    # face scalars and clim: everything above vmax saturates
    fx = v[f].mean(axis=1)[:, 0]
    img2 = render_mesh(
        (v, f), scalars=fx, cmap="gray", clim=(0.0, 0.25), view=TOP, size=(100, 100)
    ).astype(int)
    assert np.ptp(img2[50, 50:80, 0]) <= 3


def test_vertex_and_face_colors(rng):
    v, f = grid(4)
    red = np.tile([255, 0, 0], (len(v), 1)).astype(np.uint8)
    img = render_mesh(Mesh(v, f, vertex_colors=red), view=TOP, size=(64, 64)).astype(int)
    assert img[32, 32, 0] > 150 and img[32, 32, 1] < 40 and img[32, 32, 2] < 40
    green = np.tile([0.0, 1.0, 0.0, 0.5], (len(f), 1))
    img = render_mesh((v, f), face_colors=green, view=TOP, size=(64, 64)).astype(int)
    assert img[32, 32, 1] > 150 and img[32, 32, 0] < 40


def test_uv_texture_orientation():
    # texture: left half red, right half blue in the bottom rows (v < 0.5), green on top (v > 0.5)
    tex = np.zeros((64, 64, 3))
    tex[:, :32, 0] = 1.0
    tex[:, 32:, 2] = 1.0
    tex[:32] = [0.0, 1.0, 0.0]  # row 0 is the top of the image, v = 1
    v, f = grid(16)
    img = render_mesh(Mesh(v, f, uv=v[f][..., :2], texture=tex), view=TOP, size=(100, 100))
    bottom_left, bottom_right, top = img[80, 25], img[80, 75], img[20, 50]
    assert bottom_left[0] > 150 and bottom_left[2] < 60
    assert bottom_right[2] > 150 and bottom_right[0] < 60
    assert top[1] > 150 and top[0] < 60
    # per-vertex UVs and uint8 textures give the same picture
    img2 = render_mesh(
        Mesh(v, f, uv=v[:, :2], texture=(tex * 255).astype(np.uint8)), view=TOP, size=(100, 100)
    )
    np.testing.assert_array_equal(img2, img)


def test_vectors_and_edges_draw_red_on_top():
    v, f = torus(12, 8)
    plain = render_mesh((v, f), size=(128, 128))
    tangent = np.stack([-v[:, 1], v[:, 0], np.zeros(len(v))], axis=1)
    arrows = render_mesh((v, f), vectors=tangent, size=(128, 128))
    red = lambda img: ((img[..., 0] > 150) & (img[..., 1] < 90)).sum()  # noqa: E731
    assert red(plain) == 0 and red(arrows) > 100
    gv, gf = grid(6)
    lines = render_mesh((gv, gf), edges=boundary_edges(gf), size=(128, 128))
    assert red(lines) > 100


def test_arrows_on_the_far_side_of_a_closed_mesh_are_hidden():
    v, f = icosphere(2)
    tangent = np.cross(v, [0.0, 0.0, 1.0]) + 1e-3  # no zero vectors
    red = lambda img: ((img[..., 0] > 150) & (img[..., 1] < 90)).sum()  # noqa: E731
    # only the back half's vertices carry vectors: nothing must show from the front
    back = np.where((v @ [0.0, -1.0, 0.0])[:, None] < -0.2, tangent, 0.0)
    assert red(render_mesh((v, f), vectors=back, view=(0.0, -90.0), size=(96, 96))) == 0
    assert red(render_mesh((v, f), vectors=back, view=(0.0, 90.0), size=(96, 96))) > 30


def test_png_is_written_atomically_and_matches(tmp_path):
    v, f = icosphere(1)
    path = tmp_path / "sub" / "sphere.png"
    img = render_mesh((v, f), path, scalars=v[:, 2], size=(80, 60), title="a title")
    assert sorted(p.name for p in path.parent.iterdir()) == ["sphere.png"]  # no temporary left over
    back = matplotlib.image.imread(path)
    np.testing.assert_array_equal(np.round(back[..., :3] * 255).astype(np.uint8), img)
    # writing over an existing file replaces it
    img2 = render_mesh((v, f), str(path), size=(80, 60))
    np.testing.assert_array_equal(
        np.round(matplotlib.image.imread(path)[..., :3] * 255).astype(np.uint8), img2
    )
    with pytest.raises(MeshIOError, match="inside-a-file.png"):  # a file where a folder must be
        render_mesh((v, f), path / "inside-a-file.png", size=(80, 60))


def test_render_grid_layout(tmp_path):
    black = np.zeros((20, 30, 3), np.uint8)
    white = np.ones((20, 30))
    panel = render_grid([black, white], tmp_path / "g.png", columns=2)
    assert panel.shape == (20, 60, 3)
    assert panel[:, :28].max() < 10 and panel[:, 32:].min() > 245
    titled = render_grid([black, white, black], titles=["a", "b", "c"])
    assert titled.shape == (2 * (20 + 20), 2 * 30, 3)  # 2x2 cells with a 20 px title strip each
    assert titled[20 + 2 : 40 - 2, 2:28].max() < 10  # first image under its title
    assert (tmp_path / "g.png").exists()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"scalars": np.zeros(42), "face_colors": np.zeros((80, 3))}, "face_colors and scalars"),
        ({"uv": np.zeros((80, 3, 2))}, "both uv and texture"),
        ({"scalars": np.zeros(7)}, r"scalars must be real \[V=42\] or \[F=80\]"),
        ({"scalars": np.full(42, np.nan)}, "NaN"),
        ({"scalars": np.zeros(42), "cmap": "no-such-map"}, "unknown colormap"),
        ({"vertex_colors": np.zeros((42, 2))}, r"vertex_colors must be numeric \[42, 3\]"),
        ({"vectors": np.zeros((42, 3), complex)}, "tangent frames"),
        ({"vectors": np.zeros((41, 3))}, r"vectors must be real \[V=42, 3\]"),
        ({"edges": np.array([[0, 42]])}, "edges must be integer vertex pairs"),
        ({"size": (4, 4)}, "between 16 and 8192"),
        ({"view": (10.0, 20.0, 30.0)}, r"view must be \(elevation, azimuth\)"),
        ({"uv": np.zeros((80, 3, 2)), "texture": np.zeros((4, 4, 2))}, r"texture must be an image"),
    ],
)
def test_bad_input_raises_input_error(kwargs, match):
    v, f = icosphere(1)
    # colours of the mesh itself travel in the Mesh, the rest are arguments
    own = {k: kwargs.pop(k) for k in ("vertex_colors", "uv", "texture") if k in kwargs}
    with pytest.raises(InputError, match=match):
        render_mesh(Mesh(v, f, **own), **kwargs)


def test_render_grid_errors():
    with pytest.raises(InputError, match="at least one image"):
        render_grid([])
    with pytest.raises(InputError, match="one title per image"):
        render_grid([np.zeros((4, 4))], titles=["a", "b"])
    with pytest.raises(InputError, match=r"images\[0\] must be an image"):
        render_grid([np.zeros(4)])


def test_needs_no_display_and_no_pyplot(tmp_path):
    # an unusable interactive backend and no display: rendering must not care (Agg canvas only)
    env = {k: val for k, val in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["MPLBACKEND"] = "TkAgg"
    code = (
        "import sys; from jmeshtex.data import icosphere; from jmeshtex.render import render_mesh; "
        f"render_mesh(icosphere(1), {str(tmp_path / 'x.png')!r}, size=(32, 32)); "
        "assert 'matplotlib.pyplot' not in sys.modules, 'pyplot was imported'"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert pathlib.Path(tmp_path / "x.png").exists()

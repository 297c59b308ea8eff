"""save_mesh / save_png: round trips per format, atomic writes, per-stem side files, errors."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest
from hypothesis import given, settings

from jmeshtex import (
    EmptyMeshError,
    FaceIndexError,
    InputError,
    Mesh,
    MeshIOError,
    NonFiniteVertexError,
)
from jmeshtex.data import icosphere, torus
from jmeshtex.io import load_mesh, load_texture, save_mesh, save_png
from jmeshtex.testing import valid_meshes


def _bytes01(rng, shape) -> np.ndarray:
    """float32 values k/255, which an 8-bit file stores exactly."""
    return rng.integers(0, 256, shape).astype(np.float32) / np.float32(255)


def _seamed_sphere(rng):
    """An icosphere with longitude/latitude UVs: corners of faces across the date line differ."""
    v, f = icosphere(1)
    u = np.arctan2(v[:, 1], v[:, 0]) / (2 * np.pi) + 0.5
    w = np.arccos(np.clip(v[:, 2], -1, 1)) / np.pi
    uv = np.stack([u[f], 1 - w[f]], axis=-1)
    wrap = (uv[..., 0].max(axis=1) - uv[..., 0].min(axis=1)) > 0.5
    uv[wrap, :, 0] = np.where(uv[wrap, :, 0] < 0.5, uv[wrap, :, 0] + 1.0, uv[wrap, :, 0])
    return Mesh(v, f, uv=uv, texture=_bytes01(rng, (6, 9, 3)), name="sphere")


GEOMETRY_TOL = {".obj": 0.0, ".ply": 0.0, ".off": 0.0, ".glb": 1e-7}  # GLB stores float32


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".off", ".glb"])
def test_geometry_round_trip(tmp_path, suffix):
    v, f = torus(7, 5)
    v = v * np.pi  # digits that decimal text must carry exactly
    save_mesh(Mesh(v, f), tmp_path / f"t{suffix}")
    back = load_mesh(tmp_path / f"t{suffix}")
    np.testing.assert_array_equal(back.faces, f)
    np.testing.assert_allclose(
        back.vertices, v, rtol=0, atol=GEOMETRY_TOL[suffix] * np.abs(v).max()
    )
    if GEOMETRY_TOL[suffix] == 0:
        np.testing.assert_array_equal(back.vertices, v)


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".glb"])
def test_textured_round_trip(tmp_path, rng, suffix):
    m = _seamed_sphere(rng)
    save_mesh(m, tmp_path / f"s{suffix}")
    back = load_mesh(tmp_path / f"s{suffix}")
    np.testing.assert_array_equal(back.faces, m.faces)
    tol = 1e-7 if suffix == ".glb" else 0.0
    np.testing.assert_allclose(back.vertices, m.vertices, rtol=0, atol=tol)
    np.testing.assert_allclose(back.uv, m.uv, rtol=0, atol=tol * 2)
    np.testing.assert_array_equal(back.texture, m.texture)
    assert back.split_to_merged is not None  # the seam is stored split and merged back
    np.testing.assert_array_equal(back.split_to_merged[back.split_faces], back.faces)


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".glb"])
def test_uvs_without_texture_stay_without(tmp_path, rng, suffix):
    """trimesh invents a grey 2x2 image for UVs without a texture; it must not come back."""
    m = _seamed_sphere(rng).replace(texture=None)
    save_mesh(m, tmp_path / f"u{suffix}")
    back = load_mesh(tmp_path / f"u{suffix}")
    assert back.texture is None and back.uv is not None
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"u{suffix}"]


@pytest.mark.parametrize(
    "suffix, channels", [(".obj", 3), (".ply", 3), (".ply", 4), (".glb", 3), (".glb", 4)]
)
def test_vertex_color_round_trip(tmp_path, rng, suffix, channels):
    v, f = icosphere(1)
    colors = _bytes01(rng, (len(v), channels))
    if channels == 4:
        colors[0, 3] = 0.5  # not fully opaque, so the alpha channel is kept
    save_mesh(Mesh(v, f, vertex_colors=colors), tmp_path / f"c{suffix}")
    back = load_mesh(tmp_path / f"c{suffix}")
    expected = colors.copy()
    if channels == 4:
        expected[0, 3] = np.float32(128) / np.float32(255)  # 0.5 is stored as 128/255
    np.testing.assert_array_equal(back.vertex_colors, expected)


@pytest.mark.parametrize("suffix", [".obj", ".ply"])
def test_uv_texture_and_colors_together(tmp_path, rng, suffix):
    m = _seamed_sphere(rng)
    colors = _bytes01(rng, (m.num_vertices, 3))
    save_mesh(m.replace(vertex_colors=colors), tmp_path / f"both{suffix}")
    back = load_mesh(tmp_path / f"both{suffix}")
    np.testing.assert_array_equal(back.uv, m.uv)
    np.testing.assert_array_equal(back.texture, m.texture)
    np.testing.assert_array_equal(back.vertex_colors, colors)


@settings(max_examples=8, deadline=None)
@given(mesh=valid_meshes(max_vertices=120))
def test_random_valid_meshes_round_trip_exactly(tmp_path_factory, mesh):
    folder = tmp_path_factory.mktemp("rt")
    for suffix in (".obj", ".ply", ".off"):
        save_mesh(mesh, folder / f"m{suffix}")
        back = load_mesh(folder / f"m{suffix}")
        np.testing.assert_array_equal(back.vertices, mesh.vertices)
        np.testing.assert_array_equal(back.faces, mesh.faces)


def test_failed_save_leaves_the_previous_file_intact(tmp_path, monkeypatch):
    path = tmp_path / "keep.off"
    save_mesh(Mesh(*icosphere(0)), path)
    before = path.read_bytes()
    from jmeshtex.io import _save

    def broken_fsync(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(_save.os, "fsync", broken_fsync)
    with pytest.raises(MeshIOError, match="No space left"):
        save_mesh(Mesh(*icosphere(2)), path)  # the new data were half written when it failed
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.off"]  # no temporary left over

    def interrupted(fd):
        raise KeyboardInterrupt

    monkeypatch.setattr(_save.os, "fsync", interrupted)
    with pytest.raises(KeyboardInterrupt):
        save_mesh(Mesh(*icosphere(2)), path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.off"]


def test_bad_data_fail_before_touching_files(tmp_path, rng):
    m = _seamed_sphere(rng)
    save_mesh(m, tmp_path / "s.obj")
    snapshot = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    bad = m.texture.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(InputError, match="NaN"):
        save_mesh(m.replace(texture=bad), tmp_path / "s.obj")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == snapshot


def test_textured_objs_in_one_folder_keep_their_own_side_files(tmp_path, rng):
    a = _seamed_sphere(rng)
    b = a.replace(texture=_bytes01(rng, (3, 5, 3)))
    save_mesh(a, tmp_path / "a.obj")
    save_mesh(b, tmp_path / "b.obj")
    save_mesh(b, tmp_path / "a.ply")  # same stem as a.obj, other texture
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["a.mtl", "a.obj", "a.ply", "a.png", "a_texture.png", "b.mtl", "b.obj", "b.png"]
    np.testing.assert_array_equal(load_mesh(tmp_path / "a.obj").texture, a.texture)
    np.testing.assert_array_equal(load_mesh(tmp_path / "b.obj").texture, b.texture)
    np.testing.assert_array_equal(load_mesh(tmp_path / "a.ply").texture, b.texture)


def test_formats_that_cannot_hold_data_warn(tmp_path, rng):
    m = _seamed_sphere(rng)
    with pytest.warns(UserWarning, match="OFF stores geometry only"):
        save_mesh(m, tmp_path / "s.off")
    colors = _bytes01(rng, (m.num_vertices, 4))
    colors[:, 3] = 0.5
    with pytest.warns(UserWarning, match="alpha is dropped"):
        save_mesh(Mesh(m.vertices, m.faces, vertex_colors=colors), tmp_path / "c.obj")
    with pytest.warns(UserWarning, match="colours are dropped"):
        save_mesh(m.replace(vertex_colors=colors), tmp_path / "c.glb")
    with pytest.warns(UserWarning, match="texture but no UVs"):
        save_mesh(m.replace(uv=None), tmp_path / "t.ply")


def test_save_errors(tmp_path):
    v, f = icosphere(0)
    with pytest.raises(MeshIOError, match="unsupported mesh format '.stl'"):
        save_mesh(Mesh(v, f), tmp_path / "m.stl")
    with pytest.raises(MeshIOError, match="does not exist"):
        save_mesh(Mesh(v, f), tmp_path / "missing" / "m.obj")
    (tmp_path / "dir.obj").mkdir()
    with pytest.raises(MeshIOError, match="directory"):
        save_mesh(Mesh(v, f), tmp_path / "dir.obj")
    with pytest.raises(EmptyMeshError):
        save_mesh(Mesh(v, np.zeros((0, 3), int)), tmp_path / "m.obj")
    bad = v.copy()
    bad[3] = np.inf
    with pytest.raises(NonFiniteVertexError):
        save_mesh((bad, f), tmp_path / "m.obj")
    with pytest.raises(FaceIndexError):
        save_mesh((v, f + 1), tmp_path / "m.obj")
    with pytest.raises(InputError, match="uv"):
        save_mesh(Mesh(v, f, uv=np.zeros((len(f), 2))), tmp_path / "m.obj")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.obj"]


def test_file_permissions_follow_umask_and_existing_files(tmp_path):
    mask = os.umask(0o022)
    try:
        save_mesh(Mesh(*icosphere(0)), tmp_path / "m.off")
        assert stat.S_IMODE((tmp_path / "m.off").stat().st_mode) == 0o644
        os.chmod(tmp_path / "m.off", 0o600)
        save_mesh(Mesh(*icosphere(1)), tmp_path / "m.off")
        assert stat.S_IMODE((tmp_path / "m.off").stat().st_mode) == 0o600
    finally:
        os.umask(mask)


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_png_round_trip(tmp_path, rng, channels):
    image = _bytes01(rng, (5, 7, channels))
    save_png(image, tmp_path / "x.png")
    np.testing.assert_array_equal(load_texture(tmp_path / "x.png"), image)
    save_png((image * 255).round().astype(np.uint8), tmp_path / "y.png")  # uint8 as is
    np.testing.assert_array_equal(load_texture(tmp_path / "y.png"), image)


def test_png_clips_and_rejects(tmp_path):
    save_png(np.array([[-0.5, 0.25, 1.5]]), tmp_path / "g.png")  # [H, W] grey, clipped
    expected = np.array([[0, 64, 255]], np.float32) / np.float32(255)
    np.testing.assert_array_equal(load_texture(tmp_path / "g.png")[..., 0], expected)
    with pytest.raises(InputError, match="NaN"):
        save_png(np.full((2, 2), np.nan), tmp_path / "n.png")
    with pytest.raises(InputError, match="shape"):
        save_png(np.zeros((2, 2, 5)), tmp_path / "n.png")
    with pytest.raises(InputError, match=".png"):
        save_png(np.zeros((2, 2)), tmp_path / "n.jpg")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.png"]


def test_png_folder_must_exist_unless_parents(tmp_path):
    with pytest.raises(MeshIOError, match="does not exist"):
        save_png(np.zeros((2, 2)), tmp_path / "new" / "a.png")
    assert not (tmp_path / "new").exists()
    save_png(np.zeros((2, 2)), tmp_path / "new" / "deeper" / "a.png", parents=True)
    assert load_texture(tmp_path / "new" / "deeper" / "a.png").shape == (2, 2, 1)

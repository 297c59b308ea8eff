"""What load_mesh drops it says; malformed text files are typed errors, not silent misreads."""

from __future__ import annotations

import numpy as np
import pytest

from jmeshtex import MeshIOError, MeshRepairWarning
from jmeshtex.io import load_mesh, save_mesh, save_png

OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n"


def test_utf8_bom_obj_keeps_its_first_vertex(tmp_path):
    plain, bom = tmp_path / "plain.obj", tmp_path / "bom.obj"
    plain.write_text(OBJ)
    bom.write_bytes(b"\xef\xbb\xbf" + OBJ.encode())
    a, b = load_mesh(plain), load_mesh(bom)
    assert b.num_vertices == a.num_vertices == 4
    np.testing.assert_array_equal(b.vertices, a.vertices)
    np.testing.assert_array_equal(b.faces, a.faces)


def test_two_coordinate_vertices_are_a_typed_error(tmp_path):
    path = tmp_path / "flat.obj"
    path.write_text("v 0 0\nv 1 0\nv 0 1\nf 1 2 3\n")
    with pytest.raises(MeshIOError, match=r"line 1 is a vertex with 2 coordinates"):
        load_mesh(path)


def test_ascii_ply_whose_header_count_lies_is_a_typed_error(tmp_path):
    v, f = np.eye(3).tolist() + [[0.0, 0.0, 0.0]], [[0, 1, 2], [0, 2, 3]]
    body = "".join(f"{x} {y} {z}\n" for x, y, z in v) + "".join(f"3 {a} {b} {c}\n" for a, b, c in f)

    def ply(nv: int) -> str:
        return (
            "ply\nformat ascii 1.0\n"
            f"element vertex {nv}\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 2\nproperty list uchar int vertex_indices\nend_header\n" + body
        )

    good, bad = tmp_path / "good.ply", tmp_path / "bad.ply"
    good.write_text(ply(4))
    bad.write_text(ply(5))  # one face line would be read as a vertex
    assert load_mesh(good).num_vertices == 4
    with pytest.raises(MeshIOError, match=r"declares 5 vertex, 2 face .* body has 6 lines"):
        load_mesh(bad)


def _textured(tmp_path):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    uv = np.array([[[0, 0], [1, 0], [0, 1]]], float)
    from jmeshtex import Mesh

    tex = np.full((4, 4, 3), 0.5, np.float32)
    path = tmp_path / "m.obj"
    save_mesh(Mesh(v, np.array([[0, 1, 2]]), uv=uv, texture=tex), path)
    return path


def test_a_missing_texture_or_mtl_is_a_warning_naming_the_file(tmp_path):
    path = _textured(tmp_path)
    assert load_mesh(path).texture is not None  # complete: no warning (warnings are errors here)
    png = next(tmp_path.glob("*.png"))
    png.write_bytes(b"not a png")
    with pytest.warns(
        MeshRepairWarning, match=rf"texture .*{png.name} named by m.mtl cannot be read"
    ):
        assert load_mesh(path).texture is None
    png.unlink()
    with pytest.warns(MeshRepairWarning, match=rf"texture {png.name} .* is missing"):
        load_mesh(path)
    next(tmp_path.glob("*.mtl")).unlink()
    with pytest.warns(MeshRepairWarning, match=r"material file m\.mtl is missing"):
        load_mesh(path)
    # a texture given explicitly still works, with the warning about the file's own
    save_png(np.zeros((2, 2, 3)), tmp_path / "given.png")
    with pytest.warns(MeshRepairWarning, match="missing"):
        assert load_mesh(path, texture=tmp_path / "given.png").texture.shape == (2, 2, 3)


def test_info_shows_what_was_dropped(tmp_path, capsys):
    from jmeshtex.cli import main

    path = _textured(tmp_path)
    next(tmp_path.glob("*.png")).unlink()
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "note: m.obj: the texture" in out and "is missing" in out


def test_fifos_and_devices_are_refused_before_any_read(tmp_path):
    import os

    from jmeshtex.io import load_texture

    fifo = tmp_path / "m.obj"
    os.mkfifo(fifo)
    zero = tmp_path / "z.obj"
    zero.symlink_to("/dev/zero")
    with pytest.raises(MeshIOError, match="FIFO"):
        load_mesh(fifo)
    with pytest.raises(MeshIOError, match="character device"):
        load_mesh(zero)
    with pytest.raises(MeshIOError, match="FIFO"):
        load_texture(fifo)
    # a FIFO named by the MTL is dropped with a note, never opened
    (tmp_path / "t.obj").write_text("mtllib p.mtl\n" + OBJ)
    os.mkfifo(tmp_path / "p.mtl")
    with pytest.warns(MeshRepairWarning, match="p.mtl cannot be read"):
        assert load_mesh(tmp_path / "t.obj").num_faces == 4


def test_the_size_cap_and_the_memory_budget_name_their_limits(tmp_path, monkeypatch):
    import struct
    import zlib

    from jmeshtex.io import _read, load_texture

    path = tmp_path / "m.obj"
    path.write_text(OBJ)
    monkeypatch.setattr(_read, "MAX_INPUT_BYTES", 10)
    with pytest.raises(MeshIOError, match=r"more than the 10 bytes"):
        load_mesh(path)
    monkeypatch.undo()

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))

    big = tmp_path / "big.png"
    ihdr = struct.pack(">IIBBBBB", 100_000, 100_000, 8, 2, 0, 0, 0)
    big.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b""))
    with pytest.raises(MeshIOError, match=r"GiB budget"):
        load_texture(big)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "OBJ indices start at 1"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "v index 4, but the file has 3"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/2\n", "vt index 2, but the file has 1"),
        ("v 0 0 0 nan 0 0\nv 1 0 0 1 0 0\nv 0 1 0 0 1 0\nf 1 2 3\n", "vertex colour"),
    ],
)
def test_bad_obj_indices_and_colours_are_typed_errors(tmp_path, text, match):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(MeshIOError, match=match):
        load_mesh(path)


def test_tabs_load_and_short_faces_are_counted(tmp_path):
    tabs = tmp_path / "tabs.obj"
    tabs.write_text(OBJ.replace(" ", "\t"))
    assert load_mesh(tabs).num_faces == 4
    short = tmp_path / "short.obj"
    short.write_text(OBJ + "f 1 2\nf 3\n")
    with pytest.warns(MeshRepairWarning, match="dropped 2 face line"):
        assert load_mesh(short).num_faces == 4


@pytest.mark.parametrize("faces", [3, 5])  # header says 4
def test_off_counts_must_match_the_body(tmp_path, faces):
    body = ["0 0 0", "1 0 0", "0 1 0", "0 0 1"] + ["3 0 1 2", "3 0 2 3", "3 0 3 1", "3 1 3 2"]
    body += ["3 0 1 3"] * (faces == 5)
    path = tmp_path / "m.off"
    path.write_text("OFF\n4 4 0\n" + "\n".join(body[: 4 + faces]) + "\n")
    with pytest.raises(MeshIOError, match="declares 4 vertices and 4 faces"):
        load_mesh(path)


@pytest.mark.parametrize("bad", [np.nan, np.inf, 1e6, -1.0])
def test_float_images_must_hold_texels_in_0_1(tmp_path, bad):
    from PIL import Image

    from jmeshtex.io import load_texture

    data = np.full((4, 4), 0.5, np.float32)
    data[1, 2] = bad
    path = tmp_path / "f.tiff"
    Image.fromarray(data, mode="F").save(path)
    with pytest.raises(MeshIOError, match=r"texels must lie in \[0, 1\]"):
        load_texture(path)

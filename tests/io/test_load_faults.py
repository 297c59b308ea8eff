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

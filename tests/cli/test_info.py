"""``jmeshtex info``: statistics and verdict, JSON and PNG side outputs, clean errors, exit codes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jmeshtex import Mesh
from jmeshtex.cli import main
from jmeshtex.data import icosphere, torus
from jmeshtex.io import load_texture, save_mesh

BOWTIE_OBJ = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv -1 0 0\nv -1 -1 0\nf 1 2 3\nf 1 4 5\n"


def _row(out: str, key: str) -> str:
    line = next(line for line in out.splitlines() if line.strip().startswith(key + " "))
    return line.strip()[len(key) :].strip()


def test_valid_mesh_prints_statistics_and_exits_0(tmp_path, capsys):
    path = tmp_path / "torus.off"
    save_mesh(Mesh(*torus(8, 5)), path)
    assert main(["info", str(path)]) == 0
    captured = capsys.readouterr()
    out = captured.out
    assert out.splitlines()[0] == str(path)
    assert _row(out, "verdict") == "valid"
    assert (_row(out, "vertices"), _row(out, "faces"), _row(out, "genus")) == ("40", "80", "1")
    assert _row(out, "boundary loops") == "0" and _row(out, "closed") == "True"
    assert captured.err == ""


def test_json_is_written(tmp_path, capsys):
    path = tmp_path / "ball.obj"
    save_mesh(Mesh(*icosphere(1)), path)
    out_json = tmp_path / "stats.json"
    assert main(["info", str(path), "--json", str(out_json)]) == 0
    record = json.loads(out_json.read_text())
    assert record["path"] == str(path) and record["valid"] is True
    assert (record["vertices"], record["faces"], record["edges"], record["genus"]) == (
        42,
        80,
        120,
        0,
    )
    assert len(record["bbox_min"]) == 3 and record["error"] is None
    assert f"wrote {out_json}" in capsys.readouterr().out
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporaries


def test_invalid_mesh_prints_the_typed_error_and_exits_2(tmp_path, capsys):
    path = tmp_path / "bowtie.obj"
    path.write_text(BOWTIE_OBJ)
    out_json = tmp_path / "stats.json"
    assert main(["info", str(path), "--json", str(out_json)]) == 2
    captured = capsys.readouterr()
    assert "INVALID (NonManifoldVertexError)" in captured.out
    assert captured.err.startswith("jmeshtex info: error: non-manifold (bow-tie) vertices")
    assert "(count 1: 0)" in captured.err and "repair=True" in captured.err
    assert "Traceback" not in captured.err + captured.out
    record = json.loads(out_json.read_text())  # the statistics are still written
    assert record["valid"] is False and record["error_type"] == "NonManifoldVertexError"


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("missing.obj", None, "neither a mesh file nor one of the procedural names"),
        ("junk.ply", b"not a ply file", "cannot read mesh"),
        ("mesh.stl", b"solid x\n", "unsupported mesh format"),
    ],
)
def test_unreadable_files_give_a_clean_message(tmp_path, capsys, name, content, message):
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("jmeshtex info: error: ") and message in err
    assert "Traceback" not in err and err.count("\n") == 1


def test_render_writes_a_png(tmp_path, capsys):
    path = tmp_path / "ball.ply"
    v, f = icosphere(1)
    save_mesh(Mesh(v, f, vertex_colors=np.abs(v)), path)
    png = tmp_path / "ball.png"
    assert main(["info", str(path), "--render", str(png)]) == 0
    image = load_texture(png)[..., :3]
    assert image.shape[0] >= 64 and image.shape[1] >= 64
    assert (image < 0.9).any(axis=2).mean() > 0.02  # something was drawn on the white background
    assert f"wrote {png}" in capsys.readouterr().out


def test_info_is_listed_in_help(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "info" in capsys.readouterr().out


@pytest.mark.shared_data
def test_suzanne_is_reported_invalid(shared_data, capsys):
    assert main(["info", str(shared_data / "suzanne.obj")]) == 2
    captured = capsys.readouterr()
    assert "duplicate faces" in captured.err and "(269, 270)" in captured.err
    assert (
        "note: suzanne.obj: split 468 polygon faces (4 corners) into 936 triangles" in captured.out
    )


def test_a_quad_file_says_its_polygons_were_split(tmp_path, capsys):
    path = tmp_path / "quad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert _row(out, "verdict") == "valid" and _row(out, "faces") == "2"
    assert (
        "  note: quad.obj: split 1 polygon face (4 corners) into 2 triangles"
        in out.splitlines()[-1]
    )


def test_procedural_meshes_are_accepted(capsys):
    assert main(["info", "icosphere:1"]) == 0
    out = capsys.readouterr().out
    assert (_row(out, "vertices"), _row(out, "faces")) == ("42", "80") and "note:" not in out


@pytest.mark.shared_data
def test_spot_with_its_texture(shared_data, capsys):
    spot = shared_data / "spot"
    assert (
        main(
            [
                "info",
                str(spot / "spot_triangulated.obj"),
                "--texture",
                str(spot / "spot_texture.png"),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert _row(out, "vertices") == "2930" and _row(out, "stored vertices").startswith("3225")
    assert _row(out, "texture") == "1024x1024x3" and _row(out, "genus") == "0"

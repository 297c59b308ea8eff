"""``jmeshtex surfacecnn``: end-to-end runs writing texture, textured mesh, renders and summary."""

import json

import numpy as np
import pytest

from jmeshtex import Mesh, surfacecnn
from jmeshtex.cli._main import main
from jmeshtex.data import icosphere
from jmeshtex.io import load_mesh, save_mesh, save_png


@pytest.fixture
def files(tmp_path):
    v, f = icosphere(1)
    save_mesh(Mesh(v, f), tmp_path / "ball.obj")  # untextured: unwrapped with xatlas
    rng = np.random.default_rng(0)
    save_png(rng.uniform(size=(24, 24, 3)), tmp_path / "exemplar.png")
    return tmp_path


def test_synthesize_then_stylize(files, capsys):
    out = files / "out"
    rc = main(
        [
            "surfacecnn",
            "synthesize",
            "--mesh",
            str(files / "ball.obj"),
            "--exemplar",
            str(files / "exemplar.png"),
            "--size",
            "16",
            "--steps",
            "3",
            "--layers",
            "relu1_1",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert rc == 0
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["losses"]) == 3 and summary["size"] == 16
    assert (out / "checkpoints").is_dir() and surfacecnn.load(out).losses.tolist() == summary[
        "losses"
    ]
    for name in (
        "texture.png",
        "textured.obj",
        "textured.png",
        "render_front.png",
        "render_back.png",
        "surfacecnn.png",
        "views.png",
    ):
        assert (out / name).is_file(), name
    mesh = load_mesh(out / "textured.obj")
    assert mesh.uv is not None and mesh.texture.shape[:2] == (16, 16)
    assert "wrote" in capsys.readouterr().out
    # the textured result has UVs and a texture: stylise it
    out2 = files / "out2"
    rc = main(
        [
            "surfacecnn",
            "stylize",
            "--mesh",
            str(out / "textured.obj"),
            "--style",
            str(files / "exemplar.png"),
            "--size",
            "16",
            "--steps",
            "2",
            "--layers",
            "relu1_1",
            "--content-layer",
            "relu1_2",
            "--out",
            str(out2),
            "--quiet",
        ]
    )
    assert rc == 0 and (out2 / "texture.png").is_file()


def test_errors_are_one_line(files, capsys):
    rc = main(
        [
            "surfacecnn",
            "stylize",
            "--mesh",
            str(files / "ball.obj"),
            "--style",
            str(files / "exemplar.png"),
            "--size",
            "16",
            "--steps",
            "1",
            "--out",
            str(files / "o"),
            "--quiet",
        ]
    )
    assert rc == 2 and "content" in capsys.readouterr().err
    rc = main(
        [
            "surfacecnn",
            "synthesize",
            "--mesh",
            str(files / "ball.obj"),
            "--exemplar",
            str(files / "exemplar.png"),
            "--layers",
            "relu9_1",
            "--size",
            "16",
            "--out",
            str(files / "o"),
            "--quiet",
        ]
    )
    assert rc == 2 and "VGG layer names" in capsys.readouterr().err
    rc = main(
        [
            "surfacecnn",
            "synthesize",
            "--mesh",
            str(files / "ball.obj"),
            "--exemplar",
            str(files / "exemplar.png"),
            "--vgg19",
            str(files / "vgg19.h5"),
            "--out",
            str(files / "o"),
        ]
    )
    assert rc == 2 and "vgg19.h5" in capsys.readouterr().err


def test_procedural_mesh_seed_and_resume(files):
    """``--mesh`` takes a procedural spec; ``--seed`` is the key; ``--resume`` continues the checkpoints."""
    args = [
        "surfacecnn",
        "synthesize",
        "--mesh",
        "icosphere:1",
        "--exemplar",
        str(files / "exemplar.png"),
        "--size",
        "8",
        "--layers",
        "relu1_1",
        "--quiet",
    ]
    assert main([*args, "--steps", "4", "--seed", "1", "--out", str(files / "a")]) == 0
    assert main([*args, "--steps", "4", "--seed", "2", "--out", str(files / "b")]) == 0
    a, b = surfacecnn.load(files / "a"), surfacecnn.load(files / "b")
    assert a.mesh.num_vertices == 42 and not np.array_equal(a.colors, b.colors)
    # resuming run "a" (4 steps done) to 6 steps gives the uninterrupted 6-step run
    assert main([*args, "--steps", "6", "--seed", "1", "--out", str(files / "a"), "--resume"]) == 0
    assert main([*args, "--steps", "6", "--seed", "1", "--out", str(files / "c")]) == 0
    resumed, fresh = surfacecnn.load(files / "a"), surfacecnn.load(files / "c")
    assert resumed.stats["resumed_at"] == 4 and fresh.stats["resumed_at"] == 0
    np.testing.assert_array_equal(resumed.colors, fresh.colors)

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


@pytest.mark.parametrize(
    "verb, extra, message",
    [
        ("stylize", ["--size", "16", "--steps", "1", "--quiet"], "content"),
        ("synthesize", ["--layers", "relu9_1", "--size", "16", "--quiet"], "VGG layer names"),
        ("synthesize", ["--vgg19", "vgg19.h5"], "vgg19.h5"),
    ],
    ids=["stylize-without-content-layer", "unknown-vgg-layer", "missing-vgg19-file"],
)
def test_errors_are_one_line(files, capsys, verb, extra, message):
    image = "--style" if verb == "stylize" else "--exemplar"
    extra = [str(files / a) if a.endswith(".h5") else a for a in extra]  # a file that is not there
    args = [
        "surfacecnn",
        verb,
        "--mesh",
        str(files / "ball.obj"),
        image,
        str(files / "exemplar.png"),
    ]
    rc = main([*args, *extra, "--out", str(files / "o")])
    assert rc == 2 and message in capsys.readouterr().err


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


def test_exemplar_native_resolution_and_scale(tmp_path):
    from jmeshtex.cli._surfacecnn import _image

    save_png(np.random.default_rng(0).uniform(size=(600, 40, 3)), tmp_path / "tall.png")
    assert _image(tmp_path / "tall.png", None).shape == (600, 40, 3)  # no silent downsizing
    assert _image(tmp_path / "tall.png", None, 0.5).shape == (300, 20, 3)
    assert _image(tmp_path / "tall.png", 300, 1.0).shape == (300, 20, 3)  # an explicit cap


def test_render_up_follows_the_mesh_kind():
    import argparse

    from jmeshtex.cli._surfacecnn import render_up

    def ns(mesh, up=None):
        return argparse.Namespace(mesh=mesh, up=up)

    assert render_up(ns("spot.obj")) == "y"  # mesh files: the OBJ/glTF convention
    assert render_up(ns("icosphere:2")) == "z"  # jmeshtex's procedural meshes are Z-up
    assert render_up(ns("spot.obj", "-z")) == "-z"


def test_unwrap_mesh_keeps_uvs_and_reports_their_spread(files, capsys):
    v, f = icosphere(1)
    uv = surfacecnn.unwrap_uv(v, f)
    uv[:10] *= 0.5  # uneven texel density on purpose
    save_mesh(Mesh(v, f, uv=uv), files / "uv_ball.obj")
    args = ["surfacecnn", "synthesize", "--mesh", str(files / "uv_ball.obj"), "--exemplar"]
    args += [str(files / "exemplar.png"), "--size", "16", "--steps", "1", "--layers", "relu1_1"]
    assert main([*args, "--unwrap", "mesh", "--out", str(files / "a"), "--quiet"]) == 0
    assert "texel density" in capsys.readouterr().out
    np.testing.assert_allclose(surfacecnn.load(files / "a").mesh.uv, uv, atol=1e-5)
    assert main([*args, "--out", str(files / "b"), "--quiet"]) == 0  # default: xatlas
    assert not np.allclose(surfacecnn.load(files / "b").mesh.uv, uv, atol=1e-3)


@pytest.mark.parametrize("flag", [[], ["--frame-smoothing", "0"], ["--frame-smoothing", "2.5"]])
def test_frame_smoothing_reaches_the_config(files, flag):
    """``--frame-smoothing`` sets ``Config.frame_smoothing`` (0: the paper's frames); without it the
    library's default holds."""
    from jmeshtex.cli._main import build_parser
    from jmeshtex.cli._surfacecnn import _setup

    argv = ["surfacecnn", "synthesize", "--mesh", "icosphere:1", "--exemplar", "e.png"]
    args = build_parser().parse_args([*argv, "--out", str(files / "o"), *flag])
    _, config, _ = _setup(args)
    expected = float(flag[1]) if flag else surfacecnn.Config().frame_smoothing
    assert config.frame_smoothing == expected


def test_frame_smoothing_out_of_range_is_a_usage_error(files, capsys):
    argv = ["surfacecnn", "synthesize", "--mesh", "icosphere:1", "--exemplar", "e.png"]
    with pytest.raises(SystemExit) as refused:  # argparse refuses it before anything runs
        main([*argv, "--frame-smoothing", "-1", "--out", str(files / "o")])
    assert refused.value.code == 2
    assert "--frame-smoothing: -1 is out of range" in capsys.readouterr().err

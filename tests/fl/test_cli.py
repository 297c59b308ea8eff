"""`jmeshtex fl train|encode|reconstruct`, run in-process on tiny settings."""

from __future__ import annotations

import json

import jax
import matplotlib.image
import numpy as np
import pytest

from jmeshtex import Mesh, fl
from jmeshtex.cli import main
from jmeshtex.data import grid, striped_sphere
from jmeshtex.io import Checkpoints, save_mesh, save_png
from tests._presets import FL_MICRO_NETWORK

#: trainings of 2-3 steps: their steps compile at the suite's quick XLA level (conftest.py)
pytestmark = pytest.mark.few_steps

TINY = {
    "latent_dim": 3,
    **FL_MICRO_NETWORK,
    "min_vertices": 10,
    "max_vertices": 14,
    "meshes_per_image": 1,
    "batch_size": 1,
    "max_image_size": 16,
    "warmup_steps": 0,
    "checkpoint_every": 1,
}


def test_pretrain_encode_reconstruct(tmp_path, capsys):
    images = tmp_path / "images"
    images.mkdir()
    rng = np.random.default_rng(0)
    for i in range(2):
        save_png(rng.random((16, 16, 3)).astype(np.float32), images / f"im{i}.png")
    (tmp_path / "config.json").write_text(json.dumps(TINY))
    run = tmp_path / "run"
    flags = ["--images", str(images), "--out", str(run), "--steps", "2"]
    flags += ["--config", str(tmp_path / "config.json"), "--quiet", "--seed", "3"]
    assert main(["fl", "train", *flags]) == 0
    assert (run / "model.npz").exists() and Checkpoints(run / "checkpoints").latest_step() == 2
    summary = json.loads(capsys.readouterr().out)
    assert summary["steps"] == 2 and np.isfinite(summary["final_loss"])
    model, extra = fl.load(run), fl.load_extra(run)
    assert model.config.latent_dim == 3 and model.config.batch_size == 1 and extra["seed"] == 3
    # the CLI is the library call with key = jax.random.key(--seed)
    direct = fl.train(str(images), model.config, key=jax.random.key(3), progress=False)
    np.testing.assert_allclose(summary["final_loss"], direct.losses["loss"].mean(), rtol=1e-12)
    # `pretrain` is the same subcommand; the finished run is resumed, not redone
    assert main(["fl", "pretrain", *flags]) == 0
    assert json.loads(capsys.readouterr().out)["final_loss"] == summary["final_loss"]

    v, f = grid(4)
    mesh = Mesh(
        v, f, uv=v[f][..., :2], texture=rng.random((16, 16, 3)).astype(np.float32), name="sheet"
    )
    save_mesh(mesh, tmp_path / "sheet.obj")
    tex = tmp_path / "sheet.png"
    assert tex.exists()
    sheet = ["--mesh", str(tmp_path / "sheet.obj"), "--texture", str(tex), "--model", str(run)]
    assert main(["fl", "encode", *sheet, "--out", str(tmp_path / "lat.npz")]) == 0
    with np.load(tmp_path / "lat.npz") as data:
        assert data["mu"].shape == (25, 3) and np.iscomplexobj(data["mu"])
    # a procedural mesh spec (vertex colours), and the shipped model by default
    assert (
        main(
            [
                "fl",
                "encode",
                "--mesh",
                "striped-sphere:2",
                "--out",
                str(tmp_path / "sphere.npz"),
                "--seed",
                "1",
            ]
        )
        == 0
    )
    with np.load(tmp_path / "sphere.npz") as data:
        assert data["mu"].shape == (162, 8)
        expected = fl.encode(
            fl.load_pretrained(), striped_sphere(subdivisions=2), key=jax.random.key(1)
        ).mu
        np.testing.assert_array_equal(data["mu"], expected)
    capsys.readouterr()

    out = tmp_path / "recon"
    flags = ["--out", str(out), "--size", "16", "--no-lpips"]
    assert main(["fl", "reconstruct", *sheet, *flags]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics) >= {"psnr", "dssim", "texels"} and metrics["texels"] == 256
    # the baselines that bound it, scored on the same texels
    assert set(metrics["baselines"]) == {"p1_oracle", "p1_fit", "flat_color"}
    assert all({"psnr", "dssim"} <= set(m) for m in metrics["baselines"].values())
    assert metrics["baselines"]["p1_fit"]["psnr"] >= metrics["baselines"]["flat_color"]["psnr"]
    assert matplotlib.image.imread(out / "reconstructed_texture.png").shape[:2] == (16, 16)
    assert (out / "side_by_side.png").exists()


def test_errors_are_one_line_with_status_2(tmp_path, capsys):
    v, f = grid(2)
    save_mesh(Mesh(v, f, name="plain"), tmp_path / "plain.obj")
    assert (
        main(
            [
                "fl",
                "encode",
                "--mesh",
                str(tmp_path / "plain.obj"),
                "--model",
                str(tmp_path / "none.npz"),
                "--out",
                str(tmp_path / "x.npz"),
            ]
        )
        == 2
    )
    assert "cannot read FL-VAE model" in capsys.readouterr().err
    assert (
        main(
            [
                "fl",
                "pretrain",
                "--images",
                str(tmp_path / "missing"),
                "--out",
                str(tmp_path / "r"),
                "--steps",
                "1",
                "--quiet",
            ]
        )
        == 2
    )
    assert "does not exist" in capsys.readouterr().err


def test_train_preset_stops_after_and_draws_the_loss_curve(tmp_path, capsys):
    over = {
        "latent_dim": 3,
        **FL_MICRO_NETWORK,
        "texture_size": 16,
        "pixels_per_vertex": 8.0,
        "procedural_fraction": 1.0,
        "warmup_steps": 0,
        "checkpoint_every": 1,
    }
    (tmp_path / "over.json").write_text(json.dumps(over))
    run = tmp_path / "run"
    args = [
        "fl",
        "train",
        "--preset",
        "small",
        "--config",
        str(tmp_path / "over.json"),
        "--steps",
        "3",
        "--out",
        str(run),
        "--quiet",
    ]
    assert main([*args, "--stop-after", "2"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["steps"] == 2 and summary["preset"] == "small"
    assert (run / "loss_curve.png").read_bytes()[:4] == b"\x89PNG"
    model = fl.load(run)
    assert model.config == fl.Config.small(**over, steps=3)  # the preset under the JSON overrides
    assert main(args) == 0  # the same command continues the run
    assert json.loads(capsys.readouterr().out)["steps"] == 3

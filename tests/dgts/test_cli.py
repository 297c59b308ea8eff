"""`jmeshtex dgts prepare|train|transfer|interpolate`, run in-process on tiny settings."""

from __future__ import annotations

import jax
import matplotlib.image
import numpy as np
import pytest

from jmeshtex.cli import main
from jmeshtex.dgts import load
from jmeshtex.io import load_mesh
from tests.dgts.conftest import TINY


def test_prepare_train_transfer_interpolate(tmp_path, capsys, tiny_model, monkeypatch):
    # same settings as the tiny fixtures (conftest), so the compiled steps are reused
    monkeypatch.setenv("JMESHTEX_JAX_CACHE", "0")  # no persistent cache written by the tests
    d = tmp_path / "dgts"
    assert (
        main(
            [
                "dgts",
                "prepare",
                "--reference",
                "icosphere:2",
                "--template",
                "icosahedron",
                "--levels",
                "2",
                "--steps",
                "20",
                "--samples",
                "200",
                "--out",
                str(d),
                "--quiet",
            ]
        )
        == 0
    )
    for name in (
        "training.npz",
        "reference.obj",
        "level_00.obj",
        "level_01.obj",
        "levels.png",
        "prepare.json",
    ):
        assert (d / name).exists(), name
    assert load_mesh(d / "level_01.obj").num_faces == 80
    train = ["dgts", "train", str(d), "--steps", "2", "--layers", "3", "--features", "4", "4", "4"]
    train += ["--seed", "3", "--shared-levels", "2", "--quiet"]
    assert main(train) == 0
    assert (d / "sample.png").exists() and (d / "checkpoints").is_dir()
    model = load(d / "model")
    assert model.num_levels == 2 and model.config == TINY
    # the prepared meshes and the model are the fixtures' (same settings, same keys)
    for a, b in zip(jax.tree.leaves(model), jax.tree.leaves(tiny_model), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert "resumed" not in capsys.readouterr().out
    assert main(train) == 0
    assert (
        "resumed from checkpoint step 4" in capsys.readouterr().out
    )  # a second run resumes, nothing to do
    out = tmp_path / "out"
    transfer = ["dgts", "transfer", "--model", str(d), "--target", "torus:8:6"]
    assert main([*transfer, "--samples", "2", "--out", str(out)]) == 0
    m = load_mesh(out / "sample_01.obj")
    assert m.num_faces == 96 and np.isfinite(m.vertices).all()  # a 20-face template: level 1
    assert (
        "start level 1 (matched to the target's faces, within --max-faces 500000): 96 target "
        "faces -> 96" in capsys.readouterr().out
    )
    budget = ["--start-level", "0", "--max-faces", "384", "--zero-noise-from", "0"]
    assert main([*transfer, *budget, "--out", str(tmp_path / "budget")]) == 0
    assert "start level 0 (given): 96 target faces -> 384" in capsys.readouterr().out
    stop = ["--start-level", "0", "--stop-level", "0", "--out", str(tmp_path / "stop")]
    assert main([*transfer, *stop]) == 0
    assert "start level 0 (given): 96 target faces -> 96" in capsys.readouterr().out
    assert main([*transfer, "--max-faces", "95", "--out", str(tmp_path / "budget")]) == 2
    assert "max_faces=95" in capsys.readouterr().err
    img = matplotlib.image.imread(out / "transfer.png")
    assert (img[..., :3] < 0.9).any(axis=2).mean() > 0.05  # something was drawn
    assert (
        main(
            [
                "dgts",
                "interpolate",
                "--model",
                str(d / "model"),
                "--target",
                "grid:4",
                "--frames",
                "3",
                "--start-level",
                "1",
                "--out",
                str(out),
                "--overwrite",  # the folder holds the transfer's output: another command's
            ]
        )
        == 0
    )
    assert (out / "frame_02.obj").exists() and (out / "interpolate.png").exists()
    assert "wrote" in capsys.readouterr().out


def test_compilation_cache_folder(tmp_path, monkeypatch):
    from jmeshtex.cli._common import compilation_cache

    monkeypatch.setenv("JMESHTEX_JAX_CACHE", "0")
    assert compilation_cache() is None
    monkeypatch.delenv("JMESHTEX_JAX_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    import jax

    before = jax.config.jax_compilation_cache_dir
    try:
        assert (
            compilation_cache() == tmp_path / "jmeshtex" / "jax"
            and (tmp_path / "jmeshtex" / "jax").is_dir()
        )
        assert jax.config.jax_compilation_cache_dir == str(tmp_path / "jmeshtex" / "jax")
    finally:
        jax.config.update("jax_compilation_cache_dir", before)


def test_errors_are_one_line_with_status_2(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("JMESHTEX_JAX_CACHE", "0")
    assert (
        main(
            [
                "dgts",
                "transfer",
                "--model",
                str(tmp_path),
                "--target",
                "torus",
                "--out",
                str(tmp_path / "out"),
            ]
        )
        == 2
    )
    assert "holds no DGTS model" in capsys.readouterr().err
    assert main(["dgts", "prepare", "--reference", "no-such-mesh.obj", "--out", str(tmp_path)]) == 2
    assert "neither a mesh file" in capsys.readouterr().err


def test_prepare_remeshes_and_train_on_all_of_them(tmp_path, capsys, monkeypatch):
    """``prepare --remeshes 2`` writes a second fit from a turned template (the same reference, the
    same face counts, other positions), and ``train`` trains one model on both."""
    from jmeshtex.dgts import load_training_meshes

    monkeypatch.setenv("JMESHTEX_JAX_CACHE", "0")
    d = tmp_path / "dgts"
    prepare = ["dgts", "prepare", "--reference", "icosphere:2", "--template", "icosahedron"]
    prepare += ["--levels", "2", "--steps", "5", "--samples", "100", "--remeshes", "2"]
    assert main([*prepare, "--out", str(d), "--quiet"]) == 0
    first, second = (load_training_meshes(d / n) for n in ("training.npz", "training_remesh1.npz"))
    assert [len(f) for f in second.faces] == [20, 80]
    turn = np.linalg.lstsq(first.template, second.template, rcond=None)[0]  # template @ turn
    np.testing.assert_allclose(turn @ turn.T, np.eye(3), atol=1e-9)
    assert np.abs(turn - np.eye(3)).max() > 0.1 and np.linalg.det(turn) > 0
    train_args = ["dgts", "train", str(d), "--steps", "2", "--layers", "3"]
    train_args += ["--features", "4", "4", "4", "--shared-levels", "2", "--quiet"]
    assert main(train_args) == 0
    model = load(d / "model")
    from jmeshtex.dgts import train

    direct = train([first, second], TINY, key=jax.random.key(0), progress=False).model  # seed 0
    for a, b in zip(jax.tree.leaves(model), jax.tree.leaves(direct), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    with pytest.raises(SystemExit) as refused:  # argparse refuses it before anything runs
        main(["dgts", "prepare", "--reference", "icosphere:2", "--remeshes", "0", "--out", str(d)])
    assert refused.value.code == 2 and "--remeshes: 0 is out of range" in capsys.readouterr().err


def test_a_stopped_prepare_resumes_after_its_last_finished_level(tmp_path, monkeypatch):
    """Interrupted in the second fit's level 1, ``prepare`` keeps the folder and the finished
    levels; run again, it fits only what is left and writes what an uninterrupted run writes."""
    import jmeshtex.dgts._multiscale as multiscale
    from jmeshtex.dgts import load_training_meshes

    monkeypatch.setenv("JMESHTEX_JAX_CACHE", "0")
    prepare = ["dgts", "prepare", "--reference", "icosphere:2", "--template", "icosahedron"]
    prepare += ["--levels", "2", "--steps", "5", "--samples", "100", "--remeshes", "2", "--quiet"]
    assert main([*prepare, "--out", str(tmp_path / "whole")]) == 0
    fit_level, fits = multiscale.fit_level, []

    def stopped_in_the_fourth_fit(*args, **kwargs):
        fits.append(kwargs["num_samples"])
        if len(fits) == 4:
            raise KeyboardInterrupt
        return fit_level(*args, **kwargs)

    monkeypatch.setattr(multiscale, "fit_level", stopped_in_the_fourth_fit)
    d = tmp_path / "stopped"
    assert main([*prepare, "--out", str(d)]) == 130
    assert (d / "training.npz").is_file() and (
        d / "training_remesh1.levels" / "levels.npz"
    ).is_file()
    fits.clear()
    monkeypatch.setattr(
        multiscale, "fit_level", lambda *a, **k: fits.append(k["num_samples"]) or fit_level(*a, **k)
    )
    assert main([*prepare, "--out", str(d)]) == 0
    assert fits == [200]  # the remesh's level 1 only (level l fits on (l + 1) * 100 samples)
    assert not list(d.glob("*.levels"))  # removed once every fit is done
    for name in ("training.npz", "training_remesh1.npz"):
        a, b = load_training_meshes(d / name), load_training_meshes(tmp_path / "whole" / name)
        for x, y in zip(a.vertices, b.vertices, strict=True):
            np.testing.assert_array_equal(x, y)

"""Output folders: inputs never overwritten, foreign files and checkpoints never deleted, one process."""

from __future__ import annotations

import hashlib
import json
import pathlib

import numpy as np
import pytest

from jmeshtex import InputError, OutputLockedError
from jmeshtex.cli import main
from jmeshtex.cli._output import MANIFEST, claim_output, read_owner, release_all
from jmeshtex.data import icosphere
from jmeshtex.io import atomic_write, save_mesh, save_png


def _digest(folder: pathlib.Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _exemplar(path: pathlib.Path) -> pathlib.Path:
    rng = np.random.default_rng(0)
    save_png(rng.random((8, 8, 3)).astype(np.float32), path)
    return path


def test_surfacecnn_never_deletes_another_commands_checkpoints(tmp_path, capsys):
    run = tmp_path / "fl_run"
    (run / "checkpoints" / "7").mkdir(parents=True)
    (run / "checkpoints" / "7" / "state").write_bytes(b"training state of another command")
    atomic_write(run / MANIFEST, json.dumps({"command": "fl train"}))
    exemplar = _exemplar(tmp_path / "ex.png")
    before = {k: v for k, v in _digest(run).items() if not k.startswith(".jmeshtex")}
    mine = lambda: {k: v for k, v in _digest(run).items() if not k.startswith(".jmeshtex")}  # noqa: E731
    base = ["surfacecnn", "synthesize", "--mesh", "icosphere:1", "--exemplar", str(exemplar)]
    assert main([*base, "--out", str(run), "--steps", "1", "--quiet"]) == 2
    assert "fl train" in capsys.readouterr().err
    # --overwrite lets it write there, but never deletes (or resumes from) what it did not write
    assert main([*base, "--out", str(run), "--steps", "1", "--quiet", "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert "checkpoints" in err and "Traceback" not in err
    assert mine() == before
    # the folder is surfacecnn's now, but the checkpoints stay foreign: a plain rerun still refuses
    assert read_owner(run) == "surfacecnn synthesize"
    assert main([*base, "--out", str(run), "--steps", "1", "--quiet"]) == 2
    assert "checkpoints" in capsys.readouterr().err
    assert mine() == before


def test_outputs_refuse_to_overwrite_inputs(tmp_path, capsys):
    v, f = icosphere(1)
    mesh = tmp_path / "target.ply"
    save_mesh((v, f), mesh)
    obj = tmp_path / "reference.obj"
    save_mesh((v, f), obj)
    before = _digest(tmp_path)
    cases = [
        ["meshmatch", "transfer", "--source", "striped-sphere:1", "--target", str(mesh)],
        ["dgts", "prepare", "--reference", str(obj)],
    ]
    for argv in cases:
        assert main([*argv, "--out", str(tmp_path), "--overwrite"]) == 2, argv
        err = capsys.readouterr().err
        assert "refusing to write" in err and err.count("\n") == 1, err
    assert main(["fl", "encode", "--mesh", str(obj), "--out", str(obj)]) == 2
    assert "refusing to write --out" in capsys.readouterr().err
    assert _digest(tmp_path) == before


def test_foreign_files_need_overwrite_and_the_owner_may_come_back(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text("the user's own file")
    with pytest.raises(InputError, match="--overwrite"):
        claim_output(out, command="meshmatch transfer")
    assert read_owner(out) is None
    claim_output(out, command="meshmatch transfer", overwrite=True)
    release_all()
    assert read_owner(out) == "meshmatch transfer"
    claim_output(out, command="meshmatch transfer")  # its own folder: no flag needed
    release_all()
    with pytest.raises(InputError, match="meshmatch transfer"):
        claim_output(out, command="fldm train")


def test_one_process_per_output_folder(tmp_path):
    out = claim_output(tmp_path / "out", command="fldm train")
    try:
        with pytest.raises(OutputLockedError, match="in use"):
            claim_output(out, command="fldm train")
    finally:
        release_all()
    claim_output(out, command="fldm train")  # released: free again
    release_all()


def test_out_that_is_a_file_or_a_link_is_refused(tmp_path):
    a_file = tmp_path / "file"
    a_file.write_text("x")
    with pytest.raises(InputError, match="not a folder"):
        claim_output(a_file, command="fl reconstruct")
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "missing")
    with pytest.raises(InputError, match="symbolic link"):
        claim_output(link, command="fl reconstruct")


def test_a_link_planted_in_the_output_folder_does_not_redirect_a_write(tmp_path):
    outside = tmp_path / "outside.txt"
    outside.write_text("not yours")
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").symlink_to(outside)
    atomic_write(out / "summary.json", "{}")
    assert outside.read_text() == "not yours"
    assert not (out / "summary.json").is_symlink()


def test_info_reports_never_replace_the_mesh(tmp_path, capsys):
    v, f = icosphere(1)
    mesh = tmp_path / "m.obj"
    save_mesh((v, f), mesh)
    before = _digest(tmp_path)
    assert main(["info", str(mesh), "--json", str(mesh)]) == 2
    assert main(["info", str(mesh), "--render", str(mesh)]) == 2
    err = capsys.readouterr().err
    assert "refusing to write --json" in err and "refusing to write --render" in err
    assert _digest(tmp_path) == before

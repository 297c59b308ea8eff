"""``jmeshtex demo``: writes the picture and the report, never overwrites a previous run silently."""

from __future__ import annotations

import matplotlib.image
import pytest

from jmeshtex.cli import _demo, main


def test_quick_demo_writes_png_and_report(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--quick", "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {out / 'demo.png'}" in printed

    img = matplotlib.image.imread(out / "demo.png")
    rows, cols = 2, 2  # four panels: mesh, HKS, tangent axes, boundary
    assert img.shape[:2] == (rows * (_demo.PANEL_SIZE[1] + 20), cols * _demo.PANEL_SIZE[0])
    assert (img[..., :3] < 0.9).any(axis=2).mean() > 0.1  # something was drawn

    report = (out / "report.txt").read_text()
    assert "torus: 512 vertices, 1024 faces" in report
    assert "grid: 169 vertices, 288 faces" in report
    for step in _demo.STEPS:
        line = next(line for line in report.splitlines() if line.startswith(step.name))
        seconds = float(line[len(step.name) :].split()[0])
        assert 0.0 <= seconds < 120.0
    assert "total:" in report
    # the equivariance selection ran and passed; the MeshMatch stage wrote its pictures
    assert "0 failed → verify.txt" in report
    assert "pass" in (out / "verify.txt").read_text()
    # every method stage wrote its pictures into its own folder
    for folder in ("meshmatch", "dgts", "surfacecnn", "fl", "fldm"):
        assert list((out / folder).glob("*.png")), folder


def _only_meshes(monkeypatch):
    steps = [_demo.Step("procedural meshes", _demo._meshes)]
    monkeypatch.setattr(_demo, "STEPS", steps)


def test_existing_non_empty_folder_is_not_overwritten(tmp_path, monkeypatch, capsys):
    _only_meshes(monkeypatch)
    (tmp_path / "report.txt").write_text("an earlier run")
    assert main(["demo", "--out", str(tmp_path), "--quick", "--no-progress"]) == 0
    assert (tmp_path / "report.txt").read_text() == "an earlier run"
    assert (tmp_path / "run-1" / "report.txt").exists()
    assert f"wrote {tmp_path / 'run-1'}" in capsys.readouterr().out
    assert main(["demo", "--out", str(tmp_path), "--quick", "--no-progress"]) == 0
    assert (tmp_path / "run-2" / "report.txt").exists()
    # --force writes into the folder itself
    assert main(["demo", "--out", str(tmp_path), "--quick", "--force", "--no-progress"]) == 0
    report = (tmp_path / "report.txt").read_text()
    assert "procedural meshes" in report


def test_out_is_a_file_gives_a_clear_error(tmp_path, capsys):
    target = tmp_path / "a-file"
    target.write_text("x")
    assert main(["demo", "--out", str(target), "--quick", "--no-progress"]) == 2
    assert "is not a folder" in capsys.readouterr().err


def test_help_lists_demo(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "demo" in capsys.readouterr().out

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
        seconds, cpu = (float(x) for x in line[len(step.name) :].split()[:2])
        # the report's times are well-formed; how fast they are is the benchmarks' business
        # (timed assertions in tests fail on a loaded machine)
        assert seconds >= 0.0 and cpu >= 0.0
    assert "total:" in report
    # the equivariance selection ran and passed; the MeshMatch stage wrote its pictures
    assert "0 failed → verify.txt" in report
    assert "pass" in (out / "verify.txt").read_text()
    # per step: wall and process CPU seconds
    assert "cpu s" in report and "process CPU time" in report
    # every method stage wrote its figure (render.figure: a title strip, panels) into its own folder
    for folder in ("meshmatch", "dgts", "surfacecnn", "fl", "fldm"):
        fig = matplotlib.image.imread(out / folder / f"{folder}.png")[..., :3]
        assert fig.shape[1] >= 4 * 240, folder  # exemplar | result(s) | baselines side by side
        assert (fig < 0.9).any(axis=2).mean() > 0.1, folder  # the renders are drawn
    # the stage summaries carry their baselines next to the result
    assert (
        "random field" in report
        and "flat" in report
        and "shuffled" in report
        and "no displacement" in report
    )


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
    # --force writes into the folder itself, but never replaces a file jmeshtex did not write
    assert main(["demo", "--out", str(tmp_path), "--quick", "--force", "--no-progress"]) == 2
    assert "not a file this command wrote" in capsys.readouterr().err
    assert (tmp_path / "report.txt").read_text() == "an earlier run"
    # ... while its own earlier output is replaced
    run = tmp_path / "run-1"
    assert main(["demo", "--out", str(run), "--quick", "--force", "--no-progress"]) == 0
    assert "procedural meshes" in (run / "report.txt").read_text()


def test_out_is_a_file_gives_a_clear_error(tmp_path, capsys):
    target = tmp_path / "a-file"
    target.write_text("x")
    assert main(["demo", "--out", str(target), "--quick", "--no-progress"]) == 2
    assert "is not a folder" in capsys.readouterr().err


def test_progress_moves_inside_a_step(tmp_path, monkeypatch, capsys):
    seen = []

    def long_step(ctx):
        seen.append(ctx["progress"] is not None)
        ctx["progress"]("halfway through")
        return "done"

    monkeypatch.setattr(_demo, "STEPS", [_demo.Step("a long step", long_step)])
    _demo.run_demo(tmp_path, quick=True, progress=True)
    assert seen == [True]
    assert "a long step: halfway through" in capsys.readouterr().err


def test_no_progress_gives_the_stages_no_hook(tmp_path, monkeypatch):
    seen = []
    monkeypatch.setattr(
        _demo, "STEPS", [_demo.Step("a step", lambda ctx: seen.append(ctx.get("progress")) or "ok")]
    )
    _demo.run_demo(tmp_path, quick=True, progress=False)
    assert seen == [None]


def test_verify_selection_covers_every_method_once():
    from jmeshtex import testing

    testing.load_entries()
    for name, transform in _demo.VERIFY_SELECTION + _demo.QUICK_VERIFY_SELECTION:
        assert transform in testing.transforms_of(testing.REGISTRY[name]), (name, transform)
    prefixes = [name.split(".")[0] for name, _ in _demo.VERIFY_SELECTION]
    for method in ("dgts", "fl", "fldm", "meshmatch", "surfacecnn"):
        assert prefixes.count(method) == 1, method
    assert "negative.complex_bias" in {
        name for name, _ in _demo.VERIFY_SELECTION
    }  # a failure it must flag


def test_help_lists_demo(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "demo" in capsys.readouterr().out

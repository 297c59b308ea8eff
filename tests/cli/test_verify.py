"""``jmeshtex verify``: the registry listing, a filtered run with its JSON, --quiet."""

from __future__ import annotations

import json

from jmeshtex.cli import main


def test_list_names_operators_and_transforms(capsys):
    assert main(["verify", "--list"]) == 0
    out = capsys.readouterr().out
    assert "geometry.knn.transport" in out and "\ntransforms:" in out and "gauge" in out


def test_a_filtered_run_writes_its_json_quietly(tmp_path, capsys):
    path = tmp_path / "verify.json"
    argv = [
        "verify",
        "--only",
        "geometry.knn.transport",
        "--transforms",
        "gauge",
        "--dtype",
        "float64",
        "--quiet",
        "--json",
        str(path),
    ]
    assert main(argv) == 0
    captured = capsys.readouterr()
    record = json.loads(path.read_text())
    assert record["failed"] == 0 and len(record["results"]) == 1
    assert record["results"][0]["transform"] == "gauge"
    assert "1 checks: 1 passed, 0 failed" in captured.out
    assert "verify:" not in captured.err  # --quiet: no progress bar

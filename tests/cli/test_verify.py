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


def test_unknown_names_are_one_line_and_module_registers_users_operators(tmp_path, capsys):
    assert main(["verify", "--only", "user.nothing", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "not registered: user.nothing" in err and "--module" in err and "Traceback" not in err
    assert main(["verify", "--module", "no_such_module_xyz", "--list"]) == 2
    assert "cannot import" in capsys.readouterr().err


def test_module_registers_a_users_operator(tmp_path, monkeypatch, capsys):
    (tmp_path / "my_entries_mod.py").write_text(
        "from jmeshtex.testing import Entry, Field, register\n"
        "register(Entry('user.double', lambda s, p, x: Field('vertex_scalar', 2 * x),\n"
        "               {'x': ('vertex_scalar', 2)}, ('rigid', 'permute_vertices')), replace=True)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    from jmeshtex.testing import REGISTRY

    try:
        argv = ["verify", "--module", "my_entries_mod", "--only", "user.double", "--quiet"]
        assert main([*argv, "--dtype", "float64"]) == 0
        assert "2 checks: 2 passed" in capsys.readouterr().out
    finally:
        REGISTRY.pop("user.double", None)

"""``jmeshtex verify --module``: a user's module, imported from the working directory, checked alone
(``--all`` adds the built-ins); unknown transforms are a typed one-line error."""

from __future__ import annotations

import sys

import pytest

from jmeshtex.cli import main
from jmeshtex.testing import REGISTRY

MODULE = (
    "from jmeshtex.testing import Entry, Field, register\n"
    "register(Entry('user.{name}', lambda s, p, x: Field('vertex_scalar', 2 * x),\n"
    "               {{'x': ('vertex_scalar', 2)}}, ('rigid', 'permute_vertices')), replace=True)\n"
)


@pytest.fixture
def user_module(tmp_path, monkeypatch):
    """A module ``<name>.py`` in a fresh working directory that registers ``user.<name>``."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", ".")])
    names = []

    def write(name):
        (tmp_path / f"{name}.py").write_text(MODULE.format(name=name))
        names.append(name)
        return name

    yield write
    for name in names:
        REGISTRY.pop(f"user.{name}", None)
        sys.modules.pop(name, None)


def test_module_from_the_working_directory_runs_only_its_entries(user_module, capsys):
    name = user_module("verify_mod_only")
    assert main(["verify", "--module", name, "--dtype", "float64", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "2 checks: 2 passed" in out  # rigid and permute_vertices of user.verify_mod_only only
    assert f"user.{name}" in out and "geometry." not in out and "ops." not in out


def test_all_adds_the_builtins(user_module, capsys):
    name = user_module("verify_mod_all")
    assert main(["verify", "--module", name, "--all", "--list"]) == 0
    out = capsys.readouterr().out
    assert f"user.{name}" in out and "ops.field_conv" in out


def test_a_module_that_registers_nothing_is_a_one_line_error(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", list(sys.path))
    (tmp_path / "verify_mod_empty.py").write_text("X = 1\n")
    try:
        assert main(["verify", "--module", "verify_mod_empty", "--quiet"]) == 2
    finally:
        sys.modules.pop("verify_mod_empty", None)
    err = capsys.readouterr().err
    assert "registered no operator" in err and "Traceback" not in err


def test_unknown_transforms_are_a_typed_error(capsys):
    argv = ["verify", "--only", "geometry.knn.transport", "--transforms", "bogus", "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--transforms: unknown bogus" in err and "gauge" in err and "Traceback" not in err

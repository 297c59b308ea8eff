"""Every exception class of the package is defined in `jmeshtex/_errors.py` and exported by `jmeshtex`."""

from __future__ import annotations

import ast
import pathlib

import jmeshtex
from jmeshtex import _errors, dgts

ROOT = pathlib.Path(__file__).resolve().parents[1] / "jmeshtex"
_SUFFIXES = ("Error", "Exception", "Warning")


def exception_classes_outside_errors(root: pathlib.Path) -> list[str]:
    """``file:line Name`` of every public class named ``*Error``/``*Exception``/``*Warning`` or
    deriving from one, outside ``_errors.py``."""
    found = []
    for path in sorted(root.rglob("*.py")):
        if path.name == "_errors.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.ClassDef) or node.name.startswith("_"):
                continue
            bases = [
                b.id if isinstance(b, ast.Name) else getattr(b, "attr", "") for b in node.bases
            ]
            if node.name.endswith(_SUFFIXES) or any(b.endswith(_SUFFIXES) for b in bases):
                found.append(f"{path.relative_to(root.parent)}:{node.lineno} {node.name}")
    return found


def test_the_check_finds_an_error_class(tmp_path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "_a.py").write_text(
        "class BudgetError(ValueError):\n    pass\n\nclass Fine:\n    pass\n\n"
        "class Sub(BudgetError):\n    pass\n\nclass _Private(Exception):\n    pass\n"
    )
    assert exception_classes_outside_errors(tmp_path / "pkg") == [
        "pkg/_a.py:1 BudgetError",
        "pkg/_a.py:7 Sub",
    ]


def test_every_error_class_lives_in_errors_py():
    assert exception_classes_outside_errors(ROOT) == []


def test_every_error_class_is_exported_by_the_package():
    defined = {
        name
        for name, obj in vars(_errors).items()
        if isinstance(obj, type)
        and issubclass(obj, (Exception, Warning))
        and obj.__module__ == _errors.__name__
    }
    assert defined and not defined - set(dir(jmeshtex)), sorted(defined - set(dir(jmeshtex)))
    assert dgts.FaceBudgetError is jmeshtex.FaceBudgetError


def test_tests_import_errors_from_the_package_not_from_errors_py():
    tests = pathlib.Path(__file__).resolve().parent
    found = [
        f"{path.relative_to(tests.parent)}:{node.lineno}"
        for path in sorted(tests.rglob("*.py"))
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.ImportFrom) and node.module == "jmeshtex._errors"
    ]
    assert found == [], "import errors with `from jmeshtex import ...`"

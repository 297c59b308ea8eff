"""The layer rules of DESIGN.md, checked on the source: imports go through a package's ``__init__``,
``jmeshtex.ops`` stands without ``geometry`` and scipy (and ``io`` without both), methods stay apart from each other and from
``testing`` / ``cli``.

The private-import rule (:func:`private_imports`) covers every module under ``jmeshtex/`` and
``benchmarks/`` and ``studies/`` and the code cells of ``notebooks/*.ipynb``; ``tests/`` may import the private
modules of the package they test and are not checked. Root-level private modules (``jmeshtex/_*.py``)
are the designated shared internals and may be imported from anywhere. Tests import neither the
CLI's demo stages (``jmeshtex.cli._stages``: shared fixtures live in ``jmeshtex.testing``) nor error
classes from ``jmeshtex._errors`` (:func:`forbidden_test_imports`).
"""

from __future__ import annotations

import ast
import json
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
METHODS = ("dgts", "fl", "fldm", "surfacecnn", "meshmatch")
ALLOWED_METHOD_IMPORTS = {
    ("fldm", "fl")
}  # DESIGN.md: methods never import each other, except fldm -> fl


def _module_parts(rel: pathlib.PurePosixPath) -> tuple[list[str], list[str]]:
    """(dotted module parts, parts of the package a relative import starts from) of a source file."""
    parts = list(rel.with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
        return parts, parts
    return parts, parts[:-1]


def _imports(tree: ast.AST, package: list[str]):
    """``(line, target module parts, imported names)`` of every import, relative ones resolved.

    ``import a.b.c`` gives ``(["a", "b", "c"], [])``; ``from a.b import c, d`` gives
    ``(["a", "b"], ["c", "d"])``. A relative import that climbs out of the package gives ``[]``.
    """
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name.split("."), []
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                if node.level - 1 > len(package):
                    continue
                base = package[: len(package) - (node.level - 1)]
                module = base + (node.module.split(".") if node.module else [])
            else:
                module = (node.module or "").split(".")
            yield node.lineno, module, [a.name for a in node.names]


def _home(rel: pathlib.PurePosixPath) -> str | None:
    """The top-level ``jmeshtex`` subpackage a file belongs to ('' for root modules, None outside)."""
    parts = rel.parts
    if parts[0] != "jmeshtex":
        return None
    return parts[1] if len(parts) > 2 else ""


def private_imports(source: str, rel: pathlib.PurePosixPath) -> list[tuple[int, str]]:
    """``(line, what)`` of the imports in ``source`` (the file ``rel``, relative to the repository) of
    another package's internals.

    Offences: a private module below a package (``jmeshtex.pkg._mod``, from ``import``, ``from ...
    import`` or a relative import) or an underscore name imported from a package
    (``from jmeshtex.pkg import _x``), unless ``pkg`` is the file's own top-level package.
    Root-level private modules (``jmeshtex._errors``) are allowed everywhere.
    """
    home = _home(rel)
    package = _module_parts(rel)[1] if rel.parts[0] == "jmeshtex" else []
    out = []
    for line, module, names in _imports(ast.parse(source), package):
        if len(module) < 2 or module[0] != "jmeshtex" or module[1] == home:
            continue
        if module[1].startswith("_"):  # a root-level private module, or something below one
            continue
        private = [p for p in module[2:] if p.startswith("_") and not p.startswith("__")]
        if private:
            out.append((line, f"imports {'.'.join(module)}"))
        elif len(module) == 2:
            hidden = [n for n in names if n.startswith("_") and not n.startswith("__")]
            if hidden:
                out.append((line, f"imports private names {hidden} from {'.'.join(module)}"))
    return out


def method_imports(source: str, rel: pathlib.PurePosixPath) -> list[tuple[int, str]]:
    """``(line, what)`` of the imports of ``jmeshtex.testing`` / ``jmeshtex.cli`` / another method from inside a method package."""
    home = _home(rel)
    if home not in METHODS:
        return []
    out = []
    for line, module, names in _imports(ast.parse(source), _module_parts(rel)[1]):
        if not module or module[0] != "jmeshtex":
            continue
        targets = {module[1]} if len(module) > 1 else set(names)
        for target in sorted(targets):
            if target in ("testing", "cli"):
                out.append((line, f"method {home} imports jmeshtex.{target}"))
            elif (
                target in METHODS
                and target != home
                and (home, target) not in ALLOWED_METHOD_IMPORTS
            ):
                out.append((line, f"method {home} imports method {target}"))
    return out


def _notebook_cells(path: pathlib.Path):
    """Code cells of a notebook as Python source (IPython magics and shell lines blanked)."""
    cells = json.loads(path.read_text())["cells"]
    for i, cell in enumerate(cells):
        if cell.get("cell_type") != "code":
            continue
        src = cell["source"] if isinstance(cell["source"], str) else "".join(cell["source"])
        lines = ["" if line.lstrip().startswith(("%", "!")) else line for line in src.split("\n")]
        yield i, "\n".join(lines)


def _sources():
    """``(relative path shown in messages, path for the rules, source)`` of every checked module."""
    for path in sorted(
        [
            *ROOT.glob("jmeshtex/**/*.py"),
            *ROOT.glob("benchmarks/**/*.py"),
            *ROOT.glob("studies/**/*.py"),
        ]
    ):
        rel = pathlib.PurePosixPath(path.relative_to(ROOT).as_posix())
        yield str(rel), rel, path.read_text()
    for path in sorted(ROOT.glob("notebooks/*.ipynb")):
        rel = pathlib.PurePosixPath(path.relative_to(ROOT).as_posix())
        for i, src in _notebook_cells(path):
            yield f"{rel}[cell {i}]", rel, src


def _offenders(rule) -> list[str]:
    found = []
    for shown, rel, source in _sources():
        found += [f"{shown}:{line}: {what}" for line, what in rule(source, rel)]
    return found


# ------------------------------------------------------------------------------ the rules themselves


@pytest.mark.parametrize(
    ("path", "source", "flagged"),
    [
        ("jmeshtex/fl/_a.py", "from ..ops._field_conv import x", True),
        ("jmeshtex/fl/_a.py", "from jmeshtex.ops._field_conv import x", True),
        ("jmeshtex/fl/_a.py", "import jmeshtex.ops._field_conv", True),
        ("jmeshtex/fl/_a.py", "def f():\n    from ..ops import _field_conv", True),
        ("jmeshtex/fl/_a.py", "from jmeshtex.ops import _responses", True),
        ("jmeshtex/cli/_stages/fl.py", "from ...fl._vae import x", True),
        ("jmeshtex/testing/_methods/fl.py", "from ...fl import _vae", True),
        ("benchmarks/x.py", "from jmeshtex.cli._stages.meshmatch import psnr", True),
        ("notebooks/x.ipynb", "import jmeshtex.fl._vae as v", True),
        ("jmeshtex/fl/_a.py", "from ._vae import x", False),  # own package
        ("jmeshtex/cli/_stages/fl.py", "from .._common import x", False),  # own top-level package
        (
            "jmeshtex/fl/_a.py",
            "from .._errors import InputError",
            False,
        ),  # root-level shared internals
        ("jmeshtex/fl/_a.py", "from .._mesh_arrays import coerce_faces", False),
        ("jmeshtex/fl/_a.py", "from ..ops import field_conv", False),  # through the __init__
        ("benchmarks/x.py", "from jmeshtex import __version__, _errors", False),
        ("benchmarks/x.py", "from _harness import Report", False),
    ],
)
def test_private_import_rule(path, source, flagged):
    assert bool(private_imports(source, pathlib.PurePosixPath(path))) == flagged


@pytest.mark.parametrize(
    ("path", "source", "flagged"),
    [
        ("jmeshtex/dgts/_a.py", "from ..testing import registry", True),
        ("jmeshtex/dgts/_a.py", "from .. import cli", True),
        ("jmeshtex/dgts/_a.py", "from ..fl import encode", True),
        ("jmeshtex/dgts/_a.py", "import jmeshtex.meshmatch", True),
        ("jmeshtex/fl/_a.py", "from ..fldm import sample", True),
        ("jmeshtex/fldm/_a.py", "from ..fl import encode", False),  # the one allowed direction
        ("jmeshtex/fldm/_a.py", "from ..ops import field_conv", False),
        ("jmeshtex/testing/_methods/fl.py", "from ...fl import encode", False),  # not a method
    ],
)
def test_method_import_rule(path, source, flagged):
    assert bool(method_imports(source, pathlib.PurePosixPath(path))) == flagged


#: what a test may not import: the CLI's demo stages (shared fixtures live in jmeshtex.testing or
#: jmeshtex.data) and the error classes' private module (errors come from ``jmeshtex``)
TEST_FORBIDDEN = (("jmeshtex", "cli", "_stages"), ("jmeshtex", "_errors"))


def forbidden_test_imports(source: str, rel: pathlib.PurePosixPath) -> list[tuple[int, str]]:
    """``(line, what)`` of the imports in a test file of the CLI's stages or of ``jmeshtex._errors``.

    ``from jmeshtex import _errors`` (the module itself, to list what it defines) stays allowed;
    importing names from it (``from jmeshtex._errors import X``) or anything below
    ``jmeshtex.cli._stages`` is flagged.
    """
    package = _module_parts(rel)[1]
    out = []
    for line, module, names in _imports(ast.parse(source), package):
        for forbidden in TEST_FORBIDDEN:
            k = len(forbidden)
            below = tuple(module[:k]) == forbidden
            named = tuple(module) == forbidden[:-1] and forbidden[-1] in names
            if below or (named and forbidden[-1] == "_stages"):
                out.append((line, f"imports {'.'.join(forbidden)}"))
    return out


@pytest.mark.parametrize(
    ("source", "flagged"),
    [
        ("from jmeshtex.cli._stages.fldm import learning_check", True),
        ("import jmeshtex.cli._stages.fldm", True),
        ("from jmeshtex.cli import _stages", True),
        ("def f():\n    from jmeshtex.cli._stages import dgts", True),
        ("from jmeshtex._errors import InputError", True),
        ("import jmeshtex._errors as e", True),
        ("from jmeshtex import InputError, _errors", False),  # the module, to list what it defines
        ("from jmeshtex.testing import fldm_learning_check", False),
        ("from jmeshtex.cli import main", False),
        ("from jmeshtex.fldm._train import make_train_step", False),  # its own package's internals
    ],
)
def test_test_file_import_rule(source, flagged):
    found = forbidden_test_imports(source, pathlib.PurePosixPath("tests/fldm/test_x.py"))
    assert bool(found) == flagged


# ------------------------------------------------------------------------------- the code base


def test_no_module_imports_another_packages_private_modules():
    offenders = _offenders(private_imports)
    print("\n".join(offenders))
    assert not offenders, (
        f"{len(offenders)} imports of another package's internals (export the name from the package "
        "__init__ with a docstring, or move the shared helper into a root-level jmeshtex/_*.py):\n"
        + "\n".join(offenders)
    )


def test_tests_import_neither_the_cli_stages_nor_the_errors_module():
    offenders = [
        f"{path.relative_to(ROOT).as_posix()}:{line}: {what}"
        for path in sorted([*ROOT.glob("tests/**/*.py"), *ROOT.glob("equivariance_tests/**/*.py")])
        for line, what in forbidden_test_imports(
            path.read_text(), pathlib.PurePosixPath(path.relative_to(ROOT).as_posix())
        )
    ]
    assert not offenders, (
        "move shared fixtures to jmeshtex.testing or jmeshtex.data and import errors from "
        "jmeshtex:\n" + "\n".join(offenders)
    )


def test_methods_import_neither_each_other_nor_testing_nor_cli():
    offenders = _offenders(method_imports)
    print("\n".join(offenders))
    assert not offenders, "\n".join(offenders)


@pytest.mark.parametrize(
    ("package", "forbidden"),
    [
        ("jmeshtex.ops", ("jmeshtex.geometry", "scipy")),  # pure JAX: no host geometry, no scipy
        ("jmeshtex.io", ("jmeshtex.geometry", "jmeshtex.ops")),  # the bottom layer
        # beside ops/nn: jax and optax only
        ("jmeshtex.optim", ("jmeshtex.geometry", "jmeshtex.ops", "jmeshtex.nn", "scipy", "flax")),
    ],
)
def test_a_lower_layer_imports_without_the_ones_above(package, forbidden):
    code = (
        f"import sys, {package}\n"
        f"bad = sorted(m for m in sys.modules if any(m == f or m.startswith(f + '.') for f in {forbidden!r}))\n"
        "print('\\n'.join(bad))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    loaded = out.stdout.split()
    assert not loaded, f"import {package} loads {len(loaded)} modules it must not: {loaded[:20]}"

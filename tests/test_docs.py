"""The API reference (``docs/``) builds from the docstrings with warnings as errors.

Nitpicky mode is on, so a docstring's cross-reference to a name that does not exist (a renamed
function, a private module) fails here; references to other projects are not checked (no network,
no intersphinx; ``docs/conf.py`` lists them). The notebooks' pages are built here without running
them (their text and references are checked); each notebook is executed and rendered by a test of
its own in ``tests/test_notebooks.py``, so the six runs spread over the test workers.
"""

from __future__ import annotations

import ast
import os
import pathlib
import re
import subprocess
import sys

DOCS = pathlib.Path(__file__).resolve().parents[1] / "docs"


def test_the_api_reference_builds_with_warnings_as_errors(tmp_path):
    cmd = [
        sys.executable,
        "-m",
        "sphinx",
        "-E",
        "-W",
        "--keep-going",
        "-n",
        "-q",
        "-b",
        "html",
        str(DOCS),
        str(tmp_path / "html"),
    ]
    # the notebooks are not run here: tests/test_notebooks.py executes and renders each one
    env = {**os.environ, "JMESHTEX_DOCS_EXECUTE": "off"}
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=1200, env=env)
    assert run.returncode == 0, f"sphinx failed ({run.returncode}):\n{run.stdout}\n{run.stderr}"
    pages = {p.stem for p in (tmp_path / "html" / "api").glob("*.html")}
    for package in (
        "jmeshtex",
        "jmeshtex.ops",
        "jmeshtex.geometry",
        "jmeshtex.dgts",
        "jmeshtex.fl",
        "jmeshtex.fldm",
        "jmeshtex.surfacecnn",
        "jmeshtex.meshmatch",
        "jmeshtex.parallel",
        "jmeshtex.render",
        "jmeshtex.metrics",
        # each method's building blocks have their own page
        *(f"jmeshtex.{m}.core" for m in ("dgts", "fl", "fldm", "surfacecnn", "meshmatch")),
    ):
        assert package in pages, f"no API page for {package}: {sorted(pages)}"
    notebooks = {p.stem for p in (tmp_path / "html" / "_notebooks").glob("*.html")}
    expected = {p.stem for p in (DOCS.parent / "notebooks").glob("*.ipynb")}
    assert expected and expected <= notebooks, (
        f"notebooks not rendered: {sorted(expected - notebooks)}"
    )
    for guide in ("concepts", "own_model"):
        assert (tmp_path / "html" / f"{guide}.html").exists(), f"no {guide} page"
    api = (tmp_path / "html" / "api" / "jmeshtex.ops.html").read_text()
    assert "autosummary" in api and "Alias for field number" not in api


# --- docstrings state the contract; measurements and history live in benchmarks/results and git ---

ROOT = DOCS.parent
#: a lab-notebook figure or a history note in a docstring
LAB_NOTES = re.compile(r"\d+(\.\d+)? ?dB\b|previous version|\bused to\b", re.IGNORECASE)


def _docstrings(path: pathlib.Path):
    tree = ast.parse(path.read_text())
    nodes = (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)
    for node in ast.walk(tree):
        if isinstance(node, nodes):
            doc = ast.get_docstring(node, clean=False)
            if doc:
                yield getattr(node, "lineno", 1), getattr(node, "name", "<module>"), doc


def lab_notes(path: pathlib.Path) -> list[str]:
    """``file:line name: 'match'`` for every dB figure or history phrase in the docstrings of ``path``."""
    rel = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
    return [
        f"{rel}:{line} {name}: {m.group(0)!r}"
        for line, name, doc in _docstrings(path)
        for m in LAB_NOTES.finditer(doc)
    ]


def test_the_lab_note_check_can_fail(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text(
        '"""Module."""\n\n\ndef f():\n    """Does f (31.5 dB on the torus; the previous version '
        'used to be slower)."""\n'
    )
    found = lab_notes(bad)
    assert [f.split(": ", 1)[1] for f in found] == ["'31.5 dB'", "'previous version'", "'used to'"]
    good = tmp_path / "good.py"
    good.write_text('"""Module."""\n\n# a comment may say 31.5 dB\nx = "31.5 dB"\n')
    assert lab_notes(good) == []


def test_no_docstring_in_the_package_cites_db_figures_or_history():
    found = [f for path in sorted((ROOT / "jmeshtex").rglob("*.py")) for f in lab_notes(path)]
    assert not found, (
        "move these to benchmarks/results/*.md or docs/design_notes.md:\n" + "\n".join(found)
    )


#: a pointer from a docstring to a file a reader of the docs or the wheel does not have
OUTSIDE = re.compile(r"\b(DESIGN|STYLE)\.md\b|\.\./shared\b")


def test_no_docstring_points_to_a_file_outside_the_docs():
    found = [
        f"{path.relative_to(ROOT)}:{line} {name}"
        for path in sorted((ROOT / "jmeshtex").rglob("*.py"))
        for line, name, doc in _docstrings(path)
        if OUTSIDE.search(doc)
    ]
    assert not found, "point to docs/concepts.md or docs/design_notes.md instead:\n" + "\n".join(
        found
    )

"""The studies' layout (``studies/README.md``): every study is a standalone script with its own
``main``, listed in the README; no benchmark or study reads the rows of an earlier results file
(each run writes its tables from its own rows)."""

from __future__ import annotations

import ast
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
STUDIES = sorted(p for p in (ROOT / "studies").glob("*.py") if not p.name.startswith("_"))
SCRIPTS = sorted(
    p
    for p in [*(ROOT / "benchmarks").glob("*.py"), *STUDIES]
    if p.name not in ("_runner.py", "_compare.py", "suite.py", "verify_summary.py")
)
# a results file read back: ``json.loads`` of a ``RESULTS`` path, directly or through a name bound
# to one (``previous = RESULTS / "x.json"`` ... ``json.loads(previous.read_text())``)
_DIRECT = re.compile(r"json\.loads\([^\n]*\bRESULTS\b")
_BOUND = re.compile(r"^\s*(\w+) = [^\n]*\bRESULTS\b", re.MULTILINE)


def reads_results(source: str) -> str | None:
    """The first place ``source`` reads an earlier results file back, else None."""
    found = _DIRECT.search(source)
    if found:
        return found.group(0)
    for name in _BOUND.findall(source):
        found = re.search(rf"json\.loads\(\s*{name}\.read_text\(\)", source)
        if found:
            return found.group(0)
    return None


def test_there_are_studies():
    assert len(STUDIES) >= 10


@pytest.mark.parametrize("path", STUDIES, ids=lambda p: p.name)
def test_a_study_is_a_script_the_readme_lists(path):
    tree = ast.parse(path.read_text())
    assert ast.get_docstring(tree), f"{path.name}: no module docstring"
    names = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert "main" in names, f"{path.name}: no main()"
    assert any(isinstance(n, ast.If) and "__main__" in ast.unparse(n.test) for n in tree.body), (
        f"{path.name}: not runnable as a script"
    )
    assert f"`{path.name}" in (ROOT / "studies" / "README.md").read_text(), (
        f"studies/README.md does not list {path.name}"
    )


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_no_script_reads_back_a_results_file(path):
    found = reads_results(path.read_text())
    assert found is None, f"{path.name} reads an earlier results file: {found!r}"


def test_the_check_sees_a_results_file_read_back():
    carried = 'previous = RESULTS / "dgts.json"\nrows = json.loads(previous.read_text())["rows"]\n'
    assert reads_results(carried)
    assert reads_results('json.loads((RESULTS / "x.json").read_text())')
    assert not reads_results("report.write(RESULTS)\ncost = json.loads(run.read_text())")

"""The API reference (``docs/``) builds from the docstrings with warnings as errors.

Nitpicky mode is on, so a docstring's cross-reference to a name that does not exist (a renamed
function, a private module) fails here; references to other projects are not checked (no network,
no intersphinx; ``docs/conf.py`` lists them).
"""

from __future__ import annotations

import pathlib
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
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
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
    ):
        assert package in pages, f"no API page for {package}: {sorted(pages)}"
    notebooks = {p.stem for p in (tmp_path / "html" / "_notebooks").glob("*.html")}
    expected = {p.stem for p in (DOCS.parent / "notebooks").glob("*.ipynb")}
    assert expected and expected <= notebooks, (
        f"notebooks not rendered: {sorted(expected - notebooks)}"
    )

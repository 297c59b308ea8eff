"""Notebooks are committed without outputs.

They are executed top to bottom with tiny settings (JMESHTEX_NOTEBOOK_TINY=1) by the docs build
(``tests/test_docs.py``), which renders their outputs; a notebook that fails fails that build.
"""

from __future__ import annotations

import json
import pathlib

NOTEBOOKS = sorted((pathlib.Path(__file__).resolve().parent.parent / "notebooks").glob("*.ipynb"))


def test_notebooks_are_committed_without_outputs():
    for nb in NOTEBOOKS:
        cells = json.loads(nb.read_text())["cells"]
        dirty = [i for i, c in enumerate(cells) if c.get("outputs") or c.get("execution_count")]
        assert not dirty, f"{nb.name}: cells {dirty} have outputs; clear them before committing"

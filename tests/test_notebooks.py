"""The notebooks: committed without outputs, and each executes top to bottom with tiny settings
(JMESHTEX_NOTEBOOK_TINY=1) and renders its outputs.

Each notebook runs in a test of its own (so the runs spread over the test workers) as a one-page
Sphinx build with myst-nb, the extension and execution settings of ``docs/conf.py``, and warnings
as errors: a notebook that fails to run fails its build. The full docs build
(``tests/test_docs.py``) builds the notebooks' pages without running them, with nitpicky
cross-references.
"""

from __future__ import annotations

import json
import os
import pathlib
import shutil
import subprocess
import sys

import pytest

NOTEBOOKS = sorted((pathlib.Path(__file__).resolve().parent.parent / "notebooks").glob("*.ipynb"))

#: the one-page build's configuration: myst-nb's settings in ``docs/conf.py``, execution forced
_CONF = """\
extensions = ["myst_nb"]
root_doc = {name!r}
nb_execution_mode = "force"
nb_execution_timeout = 600
nb_execution_raise_on_error = True
nb_execution_in_temp = True
myst_enable_extensions = ["dollarmath"]
html_theme = "alabaster"
"""


def test_notebooks_are_committed_without_outputs():
    for nb in NOTEBOOKS:
        cells = json.loads(nb.read_text())["cells"]
        dirty = [i for i, c in enumerate(cells) if c.get("outputs") or c.get("execution_count")]
        assert not dirty, f"{nb.name}: cells {dirty} have outputs; clear them before committing"


def test_there_are_notebooks():
    assert {p.stem for p in NOTEBOOKS} >= {"dgts", "field_latents", "fldm", "meshmatch"}


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_executes_and_renders_its_outputs(path, tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    shutil.copy(path, src / path.name)
    (src / "conf.py").write_text(_CONF.format(name=path.stem))
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html"]
    cmd += [str(src), str(tmp_path / "html")]
    env = {**os.environ, "JMESHTEX_NOTEBOOK_TINY": "1"}
    env["JMESHTEX_NOTEBOOK_OUT"] = str(tmp_path / "notebook_outputs")
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=900, env=env)
    assert run.returncode == 0, (
        f"{path.name} failed ({run.returncode}):\n{run.stdout}\n{run.stderr}"
    )
    page = (tmp_path / "html" / f"{path.stem}.html").read_text()
    # executed: the page shows outputs, none an error
    assert page.count('class="cell_output') >= 2, f"{path.stem}: no outputs rendered"
    assert "output traceback" not in page and "Traceback (most recent call" not in page, path.stem

"""The notebooks: committed with their outputs (``python notebooks/run.py``), which match their code,
and each executes top to bottom with tiny settings (JMESHTEX_NOTEBOOK_TINY=1) and renders its outputs.

Each notebook runs in a test of its own (so the runs spread over the test workers) as a one-page
Sphinx build with myst-nb, the extension and execution settings of ``docs/conf.py``, and warnings
as errors: a notebook that fails to run fails its build. The full docs build
(``tests/test_docs.py``) builds the notebooks' pages without running them, with nitpicky
cross-references.
"""

from __future__ import annotations

import importlib.util
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


def _run_script():
    spec = importlib.util.spec_from_file_location("notebooks_run", NOTEBOOKS[0].parent / "run.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def stale_notebooks(paths) -> list[str]:
    """Names of notebooks whose committed outputs do not belong to their code, with the reason."""
    digest = _run_script().source_digest
    stale = []
    for path in paths:
        nb = json.loads(path.read_text())
        stamp = nb.get("metadata", {}).get("jmeshtex", {}).get("source_sha256")
        code = [c for c in nb["cells"] if c["cell_type"] == "code"]
        images = sum("image/png" in o.get("data", {}) for c in code for o in c.get("outputs", []))
        errors = [o for c in code for o in c.get("outputs", []) if o.get("output_type") == "error"]
        if stamp != digest(nb):
            stale.append(f"{path.name}: code changed since its outputs were made")
        elif not images or errors:
            stale.append(f"{path.name}: {images} figures, {len(errors)} errors in its outputs")
    return stale


def test_notebooks_are_committed_with_the_outputs_of_their_code():
    stale = stale_notebooks(NOTEBOOKS)
    assert not stale, "run `python notebooks/run.py NAME` and commit:\n" + "\n".join(stale)


def test_the_stale_check_can_fail(tmp_path):
    nb = json.loads(NOTEBOOKS[0].read_text())
    code = next(c for c in nb["cells"] if c["cell_type"] == "code")
    code["source"] = ["x = 1  # an edit after the run\n", *code["source"]]
    edited = tmp_path / NOTEBOOKS[0].name
    edited.write_text(json.dumps(nb))
    assert stale_notebooks([edited]) == [f"{edited.name}: code changed since its outputs were made"]
    for c in nb["cells"]:
        if c["cell_type"] == "code":
            c["outputs"] = []
    nb["metadata"]["jmeshtex"] = {"source_sha256": _run_script().source_digest(nb)}
    edited.write_text(json.dumps(nb))
    assert stale_notebooks([edited]) == [f"{edited.name}: 0 figures, 0 errors in its outputs"]


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

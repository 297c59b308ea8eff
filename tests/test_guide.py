"""The "write your own model" guide (docs/own_model.md) runs as written: its Python blocks, in order,
as a plain script in a fresh interpreter, without the suite's conftest (x64 off, JAX's defaults) —
build, train with optax, register in the harness, assert_equivariant, property-test."""

from __future__ import annotations

import os
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
GUIDE = ROOT / "docs" / "own_model.md"


def _blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```$", text, flags=re.S | re.M)


def test_the_guide_has_every_step():
    blocks = _blocks(GUIDE.read_text())
    joined = "\n".join(blocks)
    assert len(blocks) == 6
    for needed in (
        "complex_steepest",
        "register(",
        "check(",
        "assert_equivariant(",
        "hypothesis_profile",
        "pad_to_bucket",
    ):
        assert needed in joined, needed


def test_the_guide_runs_as_a_plain_script(tmp_path):
    script = tmp_path / "guide.py"
    script.write_text("\n\n".join(_blocks(GUIDE.read_text())))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_", "XLA_FLAGS"))}
    env["PYTHONPATH"] = str(ROOT)  # this checkout's jmeshtex; the folder holds no conftest
    run = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr[-3000:]
    # x64 is off in a fresh interpreter: the checks ran in float32 against the float32 bound
    assert "checked in float32 against 1e-05" in run.stdout, run.stdout
    assert "'rigid'" in run.stdout and "'gauge'" in run.stdout


@pytest.mark.slow
def test_verify_module_passes_the_guides_model_under_smooth_bending(tmp_path):
    # the guide's model (blocks 1-4: trained, registered) as a user's module in the working
    # directory; `jmeshtex verify --module` checks its smooth isometries in float64
    blocks = _blocks(GUIDE.read_text())
    model = next(i for i, b in enumerate(blocks) if "register(" in b)
    (tmp_path / "guide_model.py").write_text("\n\n".join(blocks[: model + 1]))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_", "XLA_FLAGS"))}
    env["PYTHONPATH"] = str(ROOT)
    argv = "verify --module guide_model --transforms cylinder cone --dtype float64 --quiet"
    code = f"from jmeshtex.cli import main; raise SystemExit(main({argv.split()!r}))"
    run = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert "2 checks: 2 passed, 0 failed" in run.stdout, run.stdout
    for transform in ("cylinder", "cone"):
        assert re.search(rf"user\.three_layer +{transform} +float64 .* pass", run.stdout), (
            run.stdout
        )

"""The "write your own model" guide (docs/own_model.md) runs as written: its Python blocks, in order,
in one namespace — build, train with optax, register in the harness, property-test."""

from __future__ import annotations

import pathlib
import re

GUIDE = pathlib.Path(__file__).resolve().parent.parent / "docs" / "own_model.md"


def _blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```$", text, flags=re.S | re.M)


def test_the_guide_has_every_step():
    blocks = _blocks(GUIDE.read_text())
    joined = "\n".join(blocks)
    assert len(blocks) == 5
    for needed in (
        "complex_steepest",
        "register(",
        "check(",
        "hypothesis_profile",
        "pad_to_bucket",
    ):
        assert needed in joined, needed


def test_the_guide_runs_as_written():
    import jax

    from jmeshtex.testing import REGISTRY

    namespace: dict = {"__name__": "guide"}
    try:
        # a user's session promotes dtypes the standard way (the suite is strict; optax's adam
        # divides a complex moment by a real one)
        with jax.numpy_dtype_promotion("standard"):
            for i, block in enumerate(_blocks(GUIDE.read_text())):
                code = compile(block, f"{GUIDE.name}[block {i + 1}]", "exec")
                exec(code, namespace)  # noqa: S102
        assert namespace["losses"][-1] < 0.7 * namespace["losses"][0]
        assert "user.three_layer" in REGISTRY
    finally:
        REGISTRY.pop("user.three_layer", None)

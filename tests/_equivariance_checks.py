"""The equivariance checks the method tests share: a registered entry passes its transforms (in
float64, and one of them in float32), and a negative control (an operator broken on purpose,
registered like a good one) is flagged by the transform it breaks."""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp

from jmeshtex.testing import Entry, check


def assert_passes(entry: Entry, transforms: tuple[str, ...], float32_transform: str) -> None:
    """``entry`` passes each of ``transforms`` in float64, and ``float32_transform`` in float32
    (its float32 bound: 1e-5)."""
    for t in transforms:
        result = check(entry, t, dtype=jnp.float64)
        assert result.passed, (t, result)
    assert check(entry, float32_transform, dtype=jnp.float32).passed


def assert_flagged(
    good: Entry,
    name: str,
    broken: Callable,
    transform: str,
    *,
    transforms: tuple[str, ...] | None = None,
) -> None:
    """``broken`` with ``good``'s inputs and initialiser (and its transforms unless ``transforms``
    says otherwise), registered as a negative control of ``transform``: the harness must flag it,
    with an error well above the bound (> 1e-3)."""
    bad = Entry(
        name,
        broken,
        good.inputs,
        good.transforms if transforms is None else transforms,
        init=good.init,
        expect_fail=(transform,),
        group="negative",
    )
    result = check(bad, transform)
    assert result.expect_fail and result.passed and result.error > 1e-3, result

"""The equivariance checks the method tests share: a registered entry passes its transforms (in
float64, and one of them in float32), the registry's own test asserts a registered entry's
transforms (so a method's tests need not prove them a second time at full cost), and a negative
control (an operator broken on purpose, registered like a good one) is flagged by the transform it
breaks."""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp

from jmeshtex.testing import Entry, asserted, check, load_entries, transforms_of


def assert_passes(entry: Entry, transforms: tuple[str, ...], float32_transform: str) -> None:
    """``entry`` passes each of ``transforms`` in float64, and ``float32_transform`` in float32
    (its float32 bound: 1e-5)."""
    for t in transforms:
        result = check(entry, t, dtype=jnp.float64)
        assert result.passed, (t, result)
    assert check(entry, float32_transform, dtype=jnp.float32).passed


def assert_registry_asserts(entry: Entry, transforms: tuple[str, ...], dtype=jnp.float64) -> None:
    """``entry`` is the registered one, and ``equivariance_tests/test_registry.py`` asserts its
    bound under each of ``transforms`` in ``dtype`` (with the same :func:`check` a method's test
    would call; in float32 on the closed sample mesh only)."""
    assert load_entries()[entry.name] is entry, entry.name
    for t in transforms:
        assert t in transforms_of(entry) and asserted(entry, t, dtype), (entry.name, t, dtype)


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

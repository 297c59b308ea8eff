"""Every registered operator under every declared transform, where a bound is asserted.

The bounds are those of ``jmeshtex verify`` (see :mod:`jmeshtex.testing._registry`): exact
transforms ≤ 1e-10 (float64) / 1e-5 (float32) relative error; smooth isometries: error ratio ≥ 3 per
halving of the spacing over three refinements (float64). Negative controls must be flagged.

Cases whose error is only reported (an entry's ``report`` transforms, re-triangulation, float32
smooth isometries: :func:`jmeshtex.testing.asserted` is False) run in ``jmeshtex verify`` and its
committed table, not here. Float32 checks the exact transforms, those of any mesh on the closed
sample mesh only (float64 carries every bound on both). One :class:`~jmeshtex.testing.CheckCache`
per worker shares compiled operators and geometry between cases, and each entry's cases run on one
xdist worker (``--dist loadgroup``), so an entry compiles once per dtype and mesh shape.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex.testing import CATALOGUE, CheckCache, asserted, check, load_entries, transforms_of

REGISTRY = load_entries()
DTYPES = (jnp.float64, jnp.float32)

CASES = [
    pytest.param(
        name,
        t,
        dt,
        id=f"{name}-{t}-{np.dtype(dt).name}",
        marks=pytest.mark.xdist_group(f"registry-{name}"),
    )
    for name, entry in REGISTRY.items()
    for t in transforms_of(entry)
    for dt in DTYPES
    if asserted(entry, t, dt)
]


@pytest.fixture(scope="module")
def cache() -> CheckCache:
    return CheckCache()


@pytest.mark.parametrize("name, transform, dtype", CASES)
def test_registered_operator(name, transform, dtype, cache):
    meshes = ("closed",) if np.dtype(dtype) == np.float32 else None
    result = check(REGISTRY[name], transform, dtype=dtype, seed=0, cache=cache, meshes=meshes)
    print(result)
    assert result.passed is not None, result
    if result.expect_fail:
        assert result.passed, f"negative control {name} was NOT flagged by {transform}: {result}"
    else:
        assert result.passed, result


def test_report_only_cases_are_left_to_verify():
    """The cases left out are exactly those whose verdict is "reported" (no bound to fail)."""
    left_out = [
        (n, t, dt)
        for n, e in REGISTRY.items()
        for t in transforms_of(e)
        for dt in DTYPES
        if not asserted(e, t, dt)
    ]
    assert len(left_out) + len(CASES) == sum(2 * len(transforms_of(e)) for e in REGISTRY.values())
    n, t, dt = next((n, t, dt) for n, t, dt in left_out if t == "cylinder" and dt == jnp.float32)
    assert check(REGISTRY[n], t, dtype=dt, seed=0).passed is None


def test_registry_is_not_empty_and_covers_the_catalogue():
    used = {t for e in REGISTRY.values() for t in e.transforms}

    assert len(REGISTRY) >= 5
    assert set(CATALOGUE) <= used | {"reflection"}, set(CATALOGUE) - used

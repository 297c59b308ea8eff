"""Every registered operator under every declared transform, in float64 and float32.

The bounds are those of ``jmeshtex verify`` (see :mod:`jmeshtex.testing._registry`): exact
transforms ≤ 1e-10 (float64) / 1e-5 (float32) relative error; smooth isometries: error ratio ≥ 3 per
halving of the spacing over three refinements (float64); re-triangulation and float32 smooth
isometries are reported, and their test asserts only that the error is finite. Negative controls
must be flagged.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex.testing import check, load_entries, transforms_of

REGISTRY = load_entries()

CASES = [
    pytest.param(name, t, dt, id=f"{name}-{t}-{np.dtype(dt).name}")
    for name, entry in REGISTRY.items()
    for t in transforms_of(entry)
    for dt in (jnp.float64, jnp.float32)
]


@pytest.mark.parametrize("name, transform, dtype", CASES)
def test_registered_operator(name, transform, dtype):
    result = check(REGISTRY[name], transform, dtype=dtype, seed=0)
    print(result)
    if result.passed is None:
        assert np.isfinite(result.error), result
    elif result.expect_fail:
        assert result.passed, f"negative control {name} was NOT flagged by {transform}: {result}"
    else:
        assert result.passed, result


def test_registry_is_not_empty_and_covers_the_catalogue():
    used = {t for e in REGISTRY.values() for t in e.transforms}
    from jmeshtex.testing import CATALOGUE

    assert len(REGISTRY) >= 5
    assert set(CATALOGUE) <= used | {"reflection"}, set(CATALOGUE) - used

"""The fan descriptor registered in the equivariance harness passes its exact checks."""

from __future__ import annotations

import jax.numpy as jnp
import pytest

from jmeshtex.testing import REGISTRY, check


@pytest.mark.parametrize("transform", ["rigid", "gauge", "permute_vertices", "fold"])
def test_fan_descriptor_is_invariant(transform):
    import jmeshtex.testing._methods.meshmatch  # noqa: F401  (registers the entry)

    result = check(REGISTRY["meshmatch.fan_descriptor"], transform, dtype=jnp.float64)
    assert result.passed, result

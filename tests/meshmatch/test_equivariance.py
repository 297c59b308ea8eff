"""The fan descriptor registered in the equivariance harness passes its exact checks."""

from __future__ import annotations

from tests._equivariance_checks import assert_registry_asserts


def test_fan_descriptor_is_invariant():
    """Rigid motions, gauge changes, relabelling and a fold: asserted by
    equivariance_tests/test_registry.py (float64 and float32), with the same ``check``."""
    from jmeshtex.testing._methods import meshmatch as _equivariance  # registers the entry

    assert_registry_asserts(_equivariance.ENTRY, ("rigid", "gauge", "permute_vertices", "fold"))

"""The FL-VAE encoder and decoder in the equivariance harness, plus a negative control."""

from __future__ import annotations

import jax.numpy as jnp
import pytest

from jmeshtex.testing import Entry, Field, check
from jmeshtex.testing._methods import fl as _equivariance


@pytest.mark.parametrize("entry", _equivariance.ENTRIES, ids=lambda e: e.name)
def test_registered_entries_pass_their_exact_transforms(entry):
    # smooth isometries (cylinder, cone) are slow convergence studies: `jmeshtex verify` runs them
    for t in _equivariance.FL_TRANSFORMS:
        result = check(entry, t, dtype=jnp.float64)
        assert result.passed, (t, result)
    assert check(entry, "gauge", dtype=jnp.float32).passed  # float32 bound 1e-5


def _frame_blind_encoder(state, params, c):
    """Broken on purpose: reads the one-ring in the intrinsic gauge, ignoring the state's frames."""
    st = state.with_(gauge=state.gauge * 0)
    return Field("vertex_tangent", _equivariance._encode(st, params, c).mu)


def test_an_encoder_blind_to_the_gauge_is_flagged():
    good = _equivariance.ENTRIES[0]
    bad = Entry("fl.negative.frame_blind", _frame_blind_encoder, good.inputs, good.transforms, init=good.init,
                expect_fail=("gauge",), group="negative")
    result = check(bad, "gauge")
    assert result.expect_fail and result.passed and result.error > 1e-3

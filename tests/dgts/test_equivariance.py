"""The DGTS generator and discriminator in the equivariance harness, plus a negative control."""

from __future__ import annotations

import jax.numpy as jnp
import pytest

from jmeshtex.testing import Entry, Field, check
from jmeshtex.testing._methods import dgts as _equivariance


@pytest.mark.parametrize("entry", _equivariance.ENTRIES, ids=lambda e: e.name)
def test_registered_entries_pass_their_transforms(entry):
    for t in entry.transforms:
        result = check(entry, t, dtype=jnp.float64)
        assert result.passed, (t, result)
    assert check(entry, "rigid", dtype=jnp.float32).passed  # float32 bound 1e-5


def _world_frame_generator(state, params, points):
    """Broken on purpose: reads the per-face coefficients as world vectors (no edge frames)."""
    from jmeshtex.ops import face_conv_stack, face_features

    nb = state.face_neighborhood()
    d = face_conv_stack(face_features(points, nb), nb, params)
    out = jnp.zeros_like(points).at[nb.faces[:, 0]].add(d)
    return Field("vertex_vector", out[:, None, :])


def test_a_world_frame_generator_is_flagged():
    gen = _equivariance.ENTRIES[0]
    bad = Entry(
        "dgts.negative.world_frame",
        _world_frame_generator,
        gen.inputs,
        gen.transforms,
        init=gen.init,
        expect_fail=("rigid",),
        group="negative",
    )
    result = check(bad, "rigid")
    assert result.expect_fail and result.passed  # the error is above the bound
    assert result.error > 1e-3

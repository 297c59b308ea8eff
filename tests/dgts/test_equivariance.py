"""The DGTS generator and discriminator in the equivariance harness, plus a negative control."""

from __future__ import annotations

import jax.numpy as jnp
import pytest

from jmeshtex.testing import Field
from jmeshtex.testing._methods import dgts as _equivariance
from tests._equivariance_checks import assert_flagged, assert_passes


@pytest.mark.parametrize("entry", _equivariance.ENTRIES, ids=lambda e: e.name)
def test_registered_entries_pass_their_transforms(entry):
    assert_passes(entry, entry.transforms, "rigid")


def _world_frame_generator(state, params, points):
    """Broken on purpose: reads the per-face coefficients as world vectors (no edge frames)."""
    from jmeshtex.ops import face_conv_stack, face_features

    nb = state.face_neighborhood()
    d = face_conv_stack(face_features(points, nb), nb, params)
    out = jnp.zeros_like(points).at[nb.faces[:, 0]].add(d)
    return Field("vertex_vector", out[:, None, :])


def test_a_world_frame_generator_is_flagged():
    gen = _equivariance.ENTRIES[0]
    assert_flagged(gen, "dgts.negative.world_frame", _world_frame_generator, "rigid")

"""Toy vertex operators with a known answer to "is it equivariant?", shared by the harness's own
tests: the distance to the centroid is invariant to rigid motions, reflections and permutations;
the z coordinate is not invariant to rotations."""

from __future__ import annotations

import jax.numpy as jnp

from jmeshtex.testing import Field


def _distance_to_centroid(state):
    p = state.points()
    return jnp.linalg.norm(p - p.mean(0), axis=1)


def centroid_distance(state, x):
    """Distance of every vertex to the centroid, times a scalar input: rigid- and label-equivariant."""
    return Field("vertex_scalar", _distance_to_centroid(state)[:, None] * x)


def height(state, x):
    """The z coordinate, times a scalar input: not rotation invariant."""
    return Field("vertex_scalar", state.points()[:, 2:3] * x)


def centroid_distance_and_height(state, x):
    """Channel 0: :func:`centroid_distance` (invariant); channel 1: :func:`height` (not)."""
    both = jnp.stack([_distance_to_centroid(state), state.points()[:, 2]], axis=1)
    return Field("vertex_scalar", both * x)

"""Hypothesis strategies for the equivariance harness: rotations, gauges, typed features.

Mesh strategies live in :mod:`jmeshtex.testing._strategies`; these draw what acts on meshes.
"""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from .._errors import InputError
from ._fields import FACE_SCALAR, VERTEX_SCALAR, VERTEX_TANGENT, VERTEX_VECTOR, Field


@st.composite
def rotations(draw, *, proper: bool = True) -> np.ndarray:
    """Haar-random 3×3 rotations (``proper=False``: improper, det −1).

    Example:
      >>> from hypothesis import given
      >>> @given(rotations())
      ... def check(R):
      ...     assert np.allclose(R @ R.T, np.eye(3))
      >>> check()
    """
    from ._transforms import random_rotation

    seed = draw(st.integers(0, 2**32 - 1))
    return random_rotation(np.random.default_rng(seed), proper=proper)


@st.composite
def gauges(draw, num_vertices: int) -> np.ndarray:
    """``[V]`` frame rotation angles in (−π, π]: one per vertex, including ±π and 0 edge cases."""
    seed = draw(st.integers(0, 2**32 - 1))
    alpha = np.random.default_rng(seed).uniform(-np.pi, np.pi, num_vertices)
    special = draw(st.sampled_from([None, 0.0, np.pi, -np.pi / 2]))
    if special is not None:
        alpha[:: max(num_vertices // 3, 1)] = special
    return alpha


@st.composite
def features(draw, kind: str, n: int, channels: int = 4, *, zero_rows: bool = True) -> Field:
    """Random typed features for ``n`` vertices/faces; some rows exactly zero (the δ/safe-norm path)."""
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    scale = draw(st.sampled_from([1e-3, 1.0, 1e3]))
    if kind in (VERTEX_SCALAR, FACE_SCALAR):
        x = rng.standard_normal((n, channels))
    elif kind == VERTEX_TANGENT:
        x = (
            rng.standard_normal((n, channels)) + 1j * rng.standard_normal((n, channels))
        ) / np.sqrt(2)
    elif kind == VERTEX_VECTOR:
        x = rng.standard_normal((n, channels, 3))
    else:
        raise InputError(
            f"no feature strategy for kind {kind!r}; use one of {VERTEX_SCALAR!r}, "
            f"{FACE_SCALAR!r}, {VERTEX_TANGENT!r}, {VERTEX_VECTOR!r}"
        )
    x = x * scale
    if zero_rows and draw(st.booleans()):
        x[:: max(n // 4, 1)] = 0
    return Field(kind, x)

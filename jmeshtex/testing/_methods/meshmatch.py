"""Registers MeshMatch's geodesic fan descriptor in the equivariance harness.

The registered operator is the pre-filtered fan of a per-vertex colour field, sampled with the
angle-0 direction given by an input tangent field ``u`` (in the state's gauge). Its sample points
are geodesics traced intrinsically, so the fan is invariant to gauge changes (``u`` turns with the
frame), rigid motions, relabelling and bending; turning ``u`` by ``2πk/A`` rolls the angle axis by
k (tested in ``tests/meshmatch``).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ...meshmatch.core import fan_descriptor
from .. import Entry, Field, register
from .._fields import VERTEX_SCALAR, VERTEX_TANGENT

#: ring radii (world units) of the registered fan: small against the harness meshes (unit size)
RADII = (0.06, 0.12)
NUM_ANGLES = 6


def _fan(state, params, x, u):
    """Fans ``[V, R·A·C]`` of colours ``x`` with angle 0 along ``u`` (state gauge → intrinsic)."""
    ref = np.asarray(u)[:, 0].astype(np.complex128) * np.exp(1j * state.gauge)
    fans = fan_descriptor(
        (state.vertices, state.faces),
        jnp.asarray(x),
        radii=RADII,
        num_angles=NUM_ANGLES,
        reference=ref,
    )
    return Field(VERTEX_SCALAR, fans.reshape(fans.shape[0], -1))


ENTRY = register(
    Entry(
        "meshmatch.fan_descriptor",
        _fan,
        {"x": (VERTEX_SCALAR, 3), "u": (VERTEX_TANGENT, 1)},
        (
            "rigid",
            "gauge",
            "permute_vertices",
            "permute_faces",
            "rotate_corners",
            "fold",
            "hinge",
            "cylinder",
        ),
        group="models",
        doc="MeshMatch geodesic fan (R=2 × A=6, exp-map tracer, pre-filtered), angle 0 along u",
    )
)

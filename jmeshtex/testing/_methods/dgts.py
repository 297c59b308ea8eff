"""Registers the DGTS generator and discriminator in the equivariance harness (:mod:`jmeshtex.testing`).

- ``dgts.generator_level``: per-vertex displacements of one generator level without noise (the noise
  is a random input, so the deterministic map is what must commute). Displacements are 3D vectors:
  they rotate with rigid motions of the mesh and follow any relabelling of vertices, faces or
  corners exactly (edge features, symmetric max over edges and neighbours, instance norm over faces).
- ``dgts.discriminator``: per-face scores, invariant to rigid motions and relabellings.

Importing this module registers both entries.
"""

from __future__ import annotations

from .. import Entry, Field, register
from .._fields import FACE_SCALAR, POINTS, VERTEX_VECTOR
from .._registry import FACE_OPS, face_conv_init


def _generator(state, params, points):
    from ...dgts.core import generator_level

    out = generator_level(params, points, state.face_neighborhood())
    return Field(VERTEX_VECTOR, out[:, None, :])


def _discriminator(state, params, points):
    from ...dgts.core import discriminator

    return Field(FACE_SCALAR, discriminator(params, points, state.face_neighborhood())[:, None])


ENTRIES = (
    Entry(
        "dgts.generator_level",
        _generator,
        {"points": (POINTS, 3)},
        FACE_OPS,
        init=face_conv_init((8, 3)),
        group="models",
        doc="DGTS generator level: displacements rotate with the mesh, follow relabelling",
    ),
    Entry(
        "dgts.discriminator",
        _discriminator,
        {"points": (POINTS, 3)},
        FACE_OPS,
        init=face_conv_init((8, 1)),
        group="models",
        doc="DGTS patch discriminator: per-face scores invariant to rigid motions and relabelling",
    ),
)

for _entry in ENTRIES:
    register(_entry)

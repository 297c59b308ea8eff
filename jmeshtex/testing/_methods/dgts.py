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

#: transforms of a face-based operator on positions: rigid motions and every relabelling
DGTS_TRANSFORMS = ("rigid", "permute_vertices", "permute_faces", "rotate_corners")


def _generator(state, params, points):
    from ...dgts.core import generator_level

    out = generator_level(params, points, state.face_neighborhood())
    return Field(VERTEX_VECTOR, out[:, None, :])


def _init_generator(key, dtype):
    from ...ops import init_face_conv_stack

    return init_face_conv_stack(key, (8, 3), dtype=dtype)


def _discriminator(state, params, points):
    from ...dgts.core import discriminator

    return Field(FACE_SCALAR, discriminator(params, points, state.face_neighborhood())[:, None])


def _init_discriminator(key, dtype):
    from ...ops import init_face_conv_stack

    return init_face_conv_stack(key, (8, 1), dtype=dtype)


ENTRIES = (
    Entry(
        "dgts.generator_level",
        _generator,
        {"points": (POINTS, 3)},
        DGTS_TRANSFORMS,
        init=_init_generator,
        group="models",
        doc="DGTS generator level: displacements rotate with the mesh, follow relabelling",
    ),
    Entry(
        "dgts.discriminator",
        _discriminator,
        {"points": (POINTS, 3)},
        DGTS_TRANSFORMS,
        init=_init_discriminator,
        group="models",
        doc="DGTS patch discriminator: per-face scores invariant to rigid motions and relabelling",
    ),
)

for _entry in ENTRIES:
    register(_entry)

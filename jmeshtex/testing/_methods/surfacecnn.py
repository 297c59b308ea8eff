"""Registers the surface CNN's first layer in the equivariance harness.

The registered operator is the surface CNN's first convolution evaluated at mesh vertices: from
every vertex p, the eight taps walk ``STEP · |(dx, dy)|`` along ``dx·t + dy·d`` with the exp-map
tracer, where ``t = u_p / |u_p|`` is an input tangent field (in the state's gauge) and
``d = -i·t`` (growing image row, as in the texel atlas); each tap reads the vertex colour field ``x``
interpolated barycentrically at its end point, and a 3×3 kernel (HWIO, as VGG's ``conv1_1``) plus
ReLU gives per-vertex features. The walk is intrinsic and ``t`` turns with the frame, so the output
is invariant to gauge changes, rigid motions, relabelling and bending (folds, hinges). Texel-level
checks (flat-sheet exactness, 90° frame rotation against the rotated exemplar) live in
``tests/surfacecnn``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ...geometry import trace_from_vertices
from ...ops import TexelNeighborhood, texel_conv
from ...surfacecnn.core import TAP_DX, TAP_DY
from .. import Entry, Field, register
from .._fields import VERTEX_SCALAR, VERTEX_TANGENT

#: world length of one tap step on the harness meshes (unit size)
STEP = 0.05
CHANNELS = 8


def vertex_taps(state, u) -> TexelNeighborhood:
    """Nine taps per vertex (``J = 3``: the end face's corners with barycentric weights)."""
    ref = np.asarray(u)[:, 0].astype(np.complex128) * np.exp(1j * state.gauge)
    t = ref / np.abs(ref)
    V = state.num_vertices
    offset = TAP_DX + 1j * TAP_DY
    direction = (offset.real[None] * t[:, None] + offset.imag[None] * (-1j * t)[:, None]).ravel()
    length = np.tile(STEP * np.abs(offset), V)
    vertex = np.repeat(np.arange(V), 9)
    result = trace_from_vertices(
        state.vertices, state.faces, vertex, np.where(length > 0, direction, 0), length
    )
    index = state.faces[result.face].reshape(V, 9, 3)
    weight = np.where(result.stopped[:, None], 0.0, result.bary).reshape(V, 9, 3)
    centre = np.arange(V)
    index[:, 4] = centre[:, None]
    weight[:, 4] = [1.0, 0.0, 0.0]
    return TexelNeighborhood(
        index=index.astype(np.int32), weight=weight, texel_mask=np.ones(V, bool)
    )


def _first_layer(state, params, x, u):
    kernel, bias = params
    taps = vertex_taps(state, u)
    taps = TexelNeighborhood(
        jnp.asarray(taps.index), jnp.asarray(taps.weight, x.dtype), jnp.asarray(taps.texel_mask)
    )
    return Field(VERTEX_SCALAR, jax.nn.relu(texel_conv(x, taps, kernel, bias)))


def _init(key, dtype):
    k1, k2 = jax.random.split(key)
    return (
        jax.random.normal(k1, (3, 3, 3, CHANNELS), dtype) / 5.0,
        jax.random.normal(k2, (CHANNELS,), dtype) / 10,
    )


ENTRIES = (
    Entry(
        "surfacecnn.first_layer",
        _first_layer,
        {"x": (VERTEX_SCALAR, 3), "u": (VERTEX_TANGENT, 1)},
        ("rigid", "gauge", "permute_vertices", "permute_faces", "rotate_corners", "fold", "hinge"),
        init=_init,
        group="models",
        doc="surface CNN first conv: 3×3 exp-map taps (tracer) along u, barycentric reads, ReLU",
    ),
)

for _entry in ENTRIES:
    register(_entry)

"""Built-in registry entries: host geometry and the pure operators of :mod:`jmeshtex.ops`.

Geometry is checked through small operators that expose it as typed fields: a transport average
(``rho``), a log-map moment (``log``), areas, heat kernel signatures. Later issues register their
models in their own modules with :func:`jmeshtex.testing.register`.
"""

from __future__ import annotations

import jax.numpy as jnp

from ._fields import VERTEX_SCALAR, VERTEX_TANGENT, VERTEX_VECTOR, Field
from ._registry import EXTRINSIC, INTRINSIC, Entry, register

# ---------------------------------------------------------------------------------------------
# geometry exposed as operators
# ---------------------------------------------------------------------------------------------


def _transport_mean(nbhd, x):
    """y_p = Σ_q w_q ρ_{q→p} x_q / Σ_q w_q: a transported average (exercises ``transport``)."""
    w = nbhd.weight * nbhd.mask
    y = jnp.einsum("vk,vk,vkc->vc", w, nbhd.transport, x[nbhd.index])
    return y / jnp.sum(w, axis=1, keepdims=True).astype(y.real.dtype)


def _log_moment(nbhd, s):
    """y_p = Σ_q w_q log_p(q) s_q: a first moment of the log map (exercises ``log``)."""
    w = (nbhd.weight * nbhd.mask).astype(nbhd.log.dtype)
    return jnp.einsum("vk,vk,vkc->vc", w, nbhd.log, s[nbhd.index].astype(nbhd.log.dtype))


def _one_ring_transport(state, params, x):
    return Field(VERTEX_TANGENT, _transport_mean(state.one_ring(), x))


def _one_ring_log(state, params, s):
    return Field(VERTEX_TANGENT, _log_moment(state.one_ring(), s))


def _knn_transport(state, params, x):
    return Field(VERTEX_TANGENT, _transport_mean(state.knn(8), x))


def _knn_log(state, params, s):
    return Field(VERTEX_TANGENT, _log_moment(state.knn(8), s))


def _vertex_area(state, params):
    return Field(VERTEX_SCALAR, state.one_ring().area)


def _hks(state, params):
    from ..geometry import heat_kernel_signature

    value = state.cached("hks", lambda: heat_kernel_signature(state.vertices, state.faces, k=24))
    return Field(VERTEX_SCALAR, jnp.asarray(value, dtype=state.dtype))


def _normal(state, params):
    from ..geometry import tangent_frames

    frames = state.cached("frames", lambda: tangent_frames(state.vertices, state.faces))
    return Field(VERTEX_VECTOR, jnp.asarray(frames.normal, dtype=state.dtype)[:, None, :])


_GEOMETRY = [
    Entry("geometry.vertex_area", _vertex_area, {}, INTRINSIC, group="geometry",
          doc="barycentric vertex areas from edge lengths"),
    Entry("geometry.one_ring.transport", _one_ring_transport, {"x": (VERTEX_TANGENT, 3)}, INTRINSIC,
          group="geometry", doc="transported one-ring average Σ w ρ x / Σ w"),
    Entry("geometry.one_ring.log", _one_ring_log, {"s": (VERTEX_SCALAR, 3)}, INTRINSIC,
          group="geometry", doc="one-ring log-map moment Σ w log_p(q) s_q"),
    Entry("geometry.knn.transport", _knn_transport, {"x": (VERTEX_TANGENT, 3)},
          tuple(t for t in INTRINSIC if t != "retriangulate"), group="geometry",
          doc="transported k-NN (k=8) average"),
    Entry("geometry.knn.log", _knn_log, {"s": (VERTEX_SCALAR, 3)},
          tuple(t for t in INTRINSIC if t != "retriangulate"), group="geometry",
          doc="k-NN (k=8) discrete exponential map moment"),
    Entry("geometry.hks", _hks, {}, ("rigid", "permute_vertices", "permute_faces", "fold", "hinge",
                                     "cylinder"), group="geometry",
          doc="heat kernel signature (robust Laplacian, 24 eigenpairs)", resolutions=(6, 12, 24, 48)),
    Entry("geometry.vertex_normal", _normal, {}, EXTRINSIC, group="geometry",
          doc="angle-weighted vertex normals (3D vectors)"),
]

for _e in _GEOMETRY:
    register(_e)

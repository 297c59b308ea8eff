"""Built-in registry entries: host geometry and the pure operators of :mod:`jmeshtex.ops`.

Geometry is checked through small operators that expose it as typed fields: a transport average
(``rho``), a log-map moment (``log``), areas, heat kernel signatures. Later issues register their
models in their own modules with :func:`jmeshtex.testing.register`.
"""

from __future__ import annotations

import jax.numpy as jnp

from ._fields import (
    FACE_EDGE,
    FACE_SCALAR,
    POINTS,
    VERTEX_SCALAR,
    VERTEX_TANGENT,
    VERTEX_VECTOR,
    Field,
)
from ._registry import EXACT, EXTRINSIC, FACE_OPS, INTRINSIC, Entry, face_conv_init, register

# ---------------------------------------------------------------------------------------------
# geometry exposed as operators
# ---------------------------------------------------------------------------------------------


def _transport_mean(nbhd, x):
    """y_p = Σ_q w_q ρ_{q→p} x_q / Σ_q w_q: a transported average (exercises ``transport``)."""
    w = nbhd.weight * nbhd.mask.astype(nbhd.weight.dtype)
    y = jnp.einsum("vk,vk,vkc->vc", w.astype(x.dtype), nbhd.transport, x[nbhd.index])
    return y / jnp.sum(w, axis=1, keepdims=True).astype(y.dtype)


def _log_moment(nbhd, s):
    """y_p = Σ_q w_q log_p(q) s_q: a first moment of the log map (exercises ``log``)."""
    w = (nbhd.weight * nbhd.mask.astype(nbhd.weight.dtype)).astype(nbhd.log.dtype)
    return jnp.einsum("vk,vk,vkc->vc", w, nbhd.log, s[nbhd.index].astype(nbhd.log.dtype))


def _one_ring_transport(state, params, x):
    return Field(VERTEX_TANGENT, _transport_mean(state.one_ring(), x))


def _one_ring_log(state, params, s):
    return Field(VERTEX_TANGENT, _log_moment(state.one_ring(), s))


def _knn_transport(state, params, x):
    return Field(VERTEX_TANGENT, _transport_mean(state.knn(8), x))


def _knn_log(state, params, s):
    return Field(VERTEX_TANGENT, _log_moment(state.knn(8), s))


def _knn_selection(state):
    """Which k nearest vertices each vertex selected (sorted): the operator's discrete choice."""
    import numpy as np

    return np.sort(np.asarray(state.host_knn(8).index), axis=1)


def _vertex_area(state, params):
    return Field(VERTEX_SCALAR, state.one_ring().area)


def _hks(state, params):
    from ..geometry import heat_kernel_signature

    # 8 eigenpairs: the truncation and the eigenvalue-derived times are then well resolved even on
    # the coarsest mesh of a convergence study (with 24 of ~50 eigenpairs the top of the spectrum
    # converges slowly and the observed order wobbles between 1.3 and 2.2)
    value = state.cached("hks", lambda: heat_kernel_signature(state.vertices, state.faces, k=8))
    return Field(VERTEX_SCALAR, jnp.asarray(value, dtype=state.dtype))


def _normal(state, params):
    from ..geometry import tangent_frames

    frames = state.cached("frames", lambda: tangent_frames(state.vertices, state.faces))
    return Field(VERTEX_VECTOR, jnp.asarray(frames.normal, dtype=state.dtype)[:, None, :])


_GEOMETRY = [
    Entry(
        "geometry.vertex_area",
        _vertex_area,
        {},
        INTRINSIC,
        group="geometry",
        doc="barycentric vertex areas from edge lengths",
    ),
    Entry(
        "geometry.one_ring.transport",
        _one_ring_transport,
        {"x": (VERTEX_TANGENT, 3)},
        INTRINSIC,
        group="geometry",
        doc="transported one-ring average Σ w ρ x / Σ w",
    ),
    Entry(
        "geometry.one_ring.log",
        _one_ring_log,
        {"s": (VERTEX_SCALAR, 3)},
        INTRINSIC,
        group="geometry",
        doc="one-ring log-map moment Σ w log_p(q) s_q",
    ),
    Entry(
        "geometry.knn.transport",
        _knn_transport,
        {"x": (VERTEX_TANGENT, 3)},
        tuple(t for t in INTRINSIC if t != "retriangulate"),
        group="geometry",
        doc="transported k-NN (k=8) average",
        selection=_knn_selection,
    ),
    Entry(
        "geometry.knn.log",
        _knn_log,
        {"s": (VERTEX_SCALAR, 3)},
        tuple(t for t in INTRINSIC if t != "retriangulate"),
        group="geometry",
        doc="k-NN (k=8) discrete exponential map moment",
        selection=_knn_selection,
    ),
    Entry(
        "geometry.hks",
        _hks,
        {},
        ("rigid", "permute_vertices", "permute_faces", "fold", "hinge", "cylinder"),
        group="geometry",
        doc="heat kernel signature (robust Laplacian, 8 eigenpairs)",
        resolutions=(6, 12, 24, 48),
    ),
    Entry(
        "geometry.vertex_normal",
        _normal,
        {},
        EXTRINSIC,
        group="geometry",
        doc="angle-weighted vertex normals (3D vectors)",
    ),
]

for _e in _GEOMETRY:
    register(_e)


# ---------------------------------------------------------------------------------------------
# face convolutions (DGTS)
# ---------------------------------------------------------------------------------------------


def _face_features(state, params, points):
    from .. import ops

    return Field(FACE_EDGE, ops.face_features(points, state.face_neighborhood()))


def _face_conv_stack(state, params, points):
    from .. import ops

    nb = state.face_neighborhood()
    return Field(FACE_SCALAR, ops.face_conv_stack(ops.face_features(points, nb), nb, params))


def _face_to_vertex(state, params, points, d):
    from .. import ops

    out = ops.face_to_vertex_displacement(d, points, state.face_neighborhood())
    return Field(VERTEX_VECTOR, out[:, None, :])


_FACE = [
    Entry(
        "ops.face_features",
        _face_features,
        {"points": (POINTS, 3)},
        FACE_OPS,
        doc="DGTS edge features [F,3,4]: invariant to rigid motions, edges roll with corners",
    ),
    Entry(
        "ops.face_conv_stack",
        _face_conv_stack,
        {"points": (POINTS, 3)},
        FACE_OPS,
        init=face_conv_init((8, 8, 8, 4)),
        doc="embedding + 3 face convolutions (instance norm, leaky ReLU)",
    ),
    Entry(
        "ops.face_to_vertex_displacement",
        _face_to_vertex,
        {"points": (POINTS, 3), "d": (FACE_SCALAR, 3)},
        FACE_OPS,
        doc="per-face coefficients in edge frames averaged to vertices: rotates with the mesh",
    ),
]

for _e in _FACE:
    register(_e)


# ---------------------------------------------------------------------------------------------
# complex tangent-feature layers, field convolutions, tangent pooling (Mitchel et al.)
# ---------------------------------------------------------------------------------------------

#: a pointwise layer needs no geometry: gauge, relabelling and an isometry cover it
POINTWISE = ("rigid", "gauge", "permute_vertices", "fold")
#: transforms of operators on k-NN neighbourhoods (re-triangulation changes them: reported only)
KNN_OPS = INTRINSIC


def _ops():
    from .. import ops

    return ops


def _cdtype(dtype):
    return jnp.complex128 if jnp.dtype(dtype) == jnp.float64 else jnp.complex64


def _complex_linear(state, params, x):
    from .. import ops

    return Field(VERTEX_TANGENT, ops.complex_linear(x, params))


def _vn(state, params, x):
    from .. import ops

    return Field(VERTEX_TANGENT, ops.vn_nonlinearity(x, params))


def _frn(state, params, x):
    from .. import ops

    nb = state.one_ring()
    return Field(
        VERTEX_TANGENT,
        ops.filter_response_norm(x, params, area=nb.area, vertex_mask=nb.vertex_mask),
    )


def _transported_set(state, x):
    """Per vertex, the set {ρ_{q→p} x_q} over its k-NN neighbourhood, all in p's frame."""
    nb = state.knn(8)
    return nb.transport[..., None] * x[nb.index], nb.mask


def _attention(state, params, x):
    from .. import ops

    xs, mask = _transported_set(state, x)
    y = ops.complex_attention(xs, params, mask=mask)
    return Field(VERTEX_TANGENT, y[:, 0])  # the vertex's own slot (slot 0 of a k-NN set)


def _vn_transformer(state, params, x):
    from .. import ops

    xs, mask = _transported_set(state, x)
    return Field(VERTEX_TANGENT, ops.vn_transformer_block(xs, params, mask=mask)[:, 0])


def _field_conv(state, params, x):
    from .. import ops

    return Field(VERTEX_TANGENT, ops.field_conv(x, state.knn(8), params))


def _field_conv_emb(state, params, x, e):
    from .. import ops

    return Field(VERTEX_TANGENT, ops.field_conv(x, state.knn(8), params, embedding=e))


def _pooling_maps(state):
    """The first pooling map of the state's hierarchy, re-expressed in the state's fine gauge.

    Coarse frames keep their intrinsic gauge (any coarse gauge cancels in pool → unpool).
    """
    import numpy as np

    from ..geometry import mesh_hierarchy, to_jax

    def build():
        h = mesh_hierarchy(state.vertices, state.faces, levels=2, min_vertices=16)
        pm = h.pooling[0]
        a = state.gauge
        turn_child = np.exp(1j * a)
        pm = pm._replace(
            to_parent=pm.to_parent * turn_child,
            children_transport=np.where(
                pm.children_mask,
                pm.children_transport * turn_child[pm.children],
                pm.children_transport,
            ),
        )
        return to_jax(pm, state.dtype)

    return state.cached("pooling", build)


def _pool_unpool(state, params, x):
    from .. import ops

    pm = _pooling_maps(state)
    return Field(VERTEX_TANGENT, ops.tangent_unpool(ops.tangent_pool(x, pm), pm))


def _init(make):
    def init(key, dtype):
        return make(key, _cdtype(dtype), dtype)

    return init


_COMPLEX = [
    Entry(
        "ops.complex_linear",
        _complex_linear,
        {"x": (VERTEX_TANGENT, 4)},
        POINTWISE,
        init=_init(lambda k, c, r: _ops().init_complex_linear(k, 4, 3, dtype=c)),
        doc="complex linear layer, no bias (supplement §9)",
    ),
    Entry(
        "ops.vn_nonlinearity",
        _vn,
        {"x": (VERTEX_TANGENT, 4)},
        POINTWISE,
        init=_init(lambda k, c, r: _ops().init_vn(k, 4, 3, dtype=c)),
        doc="vector-neuron nonlinearity (eq. 19)",
    ),
    Entry(
        "ops.filter_response_norm",
        _frn,
        {"x": (VERTEX_TANGENT, 4)},
        INTRINSIC,
        init=_init(lambda k, c, r: _ops().init_frn(4, dtype=r)),
        doc="area-weighted filter response normalisation (eq. 20)",
    ),
    Entry(
        "ops.complex_attention",
        _attention,
        {"x": (VERTEX_TANGENT, 4)},
        KNN_OPS,
        init=_init(lambda k, c, r: _ops().init_complex_attention(k, 4, num_heads=2, dtype=c)),
        doc="complex attention over each vertex's transported k-NN set",
        selection=_knn_selection,
    ),
    Entry(
        "ops.vn_transformer_block",
        _vn_transformer,
        {"x": (VERTEX_TANGENT, 4)},
        KNN_OPS,
        init=_init(lambda k, c, r: _ops().init_vn_transformer_block(k, 4, num_heads=2, dtype=c)),
        doc="VN-Transformer block over each vertex's transported k-NN set",
        selection=_knn_selection,
    ),
    Entry(
        "ops.field_conv",
        _field_conv,
        {"x": (VERTEX_TANGENT, 4)},
        KNN_OPS,
        init=_init(lambda k, c, r: _ops().init_field_conv(k, 4, 3, hdim=8, dtype=c)),
        doc="field convolution on k-NN (k=8) neighbourhoods (eq. 34, gauge-invariant form)",
        selection=_knn_selection,
    ),
    Entry(
        "ops.field_conv_emb",
        _field_conv_emb,
        {"x": (VERTEX_TANGENT, 4), "e": (VERTEX_SCALAR, 2)},
        KNN_OPS,
        init=_init(
            lambda k, c, r: _ops().init_field_conv(k, 4, 3, hdim=8, embedding_features=2, dtype=c)
        ),
        doc="field convolution with a per-vertex scalar embedding in the filters (eq. 35)",
        selection=_knn_selection,
    ),
    # The decimation is a greedy sequence of intrinsic edge collapses: exactly reproducible under
    # relabelling and exact isometries, but not a continuous function of the metric (a smooth
    # bending reorders the collapses and picks other coarse vertices: O(1) error at every
    # resolution). The smooth family is measured and reported, not asserted.
    Entry(
        "ops.tangent_pool_unpool",
        _pool_unpool,
        {"x": (VERTEX_TANGENT, 3)},
        EXACT,
        doc="transported mean pooling to a decimated level, then nearest unpooling",
        report=("cylinder",),
    ),
]

for _e in _COMPLEX:
    register(_e)


# ---------------------------------------------------------------------------------------------
# negative controls: deliberately broken operators the harness must flag
# ---------------------------------------------------------------------------------------------


def _biased_linear(state, params, x):
    """:func:`jmeshtex.ops.complex_linear` *plus a bias*: x ↦ x W + b. The bias does not rotate
    with the frame, which is why the real layer has none."""
    w, b = params
    return Field(VERTEX_TANGENT, _ops().complex_linear(x, w) + b.astype(x.dtype))


def _init_biased_linear(key, dtype):
    import jax

    cdt = jnp.complex128 if dtype == jnp.float64 else jnp.complex64
    k1, k2 = jax.random.split(key)
    w = jax.random.normal(k1, (3, 3), dtype=cdt)
    b = jax.random.normal(k2, (3,), dtype=cdt)
    return w, b


def _extrinsic_log_moment(state, params, s):
    """The one-ring log-map moment with *extrinsic* angles (offsets projected on the tangent plane).

    Angles measured by projection change when the surface bends (the vertex normal tilts at a fold),
    although edge lengths do not: an isometry must flag it.
    """
    import numpy as np

    from ..geometry import one_rings

    def build():
        v, f = state.vertices, state.faces
        rings = one_rings(f, len(v))
        fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        n = np.zeros_like(v)
        for k in range(3):
            np.add.at(n, f[:, k], fn)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        d = v[rings.ring] - v[:, None, :]
        d = d - np.einsum("vkd,vd->vk", d, n)[..., None] * n[:, None, :]
        x = d[:, 0] / np.linalg.norm(d[:, 0], axis=1, keepdims=True)
        y = np.cross(n, x)
        ang = np.arctan2(np.einsum("vkd,vd->vk", d, y), np.einsum("vkd,vd->vk", d, x))
        r = np.linalg.norm(v[rings.ring] - v[:, None, :], axis=-1)
        return rings.ring, (r * np.exp(1j * ang)) * rings.mask

    ring, log = state.cached("extrinsic_log", build)
    log = jnp.asarray(log, dtype=state.complex_dtype)
    return Field(VERTEX_TANGENT, jnp.einsum("vk,vkc->vc", log, s[ring].astype(log.dtype)))


def _first_edge_features(state, params, points):
    """DGTS edge features of each face's *first* edge only, where the real first layer takes a
    symmetric max over the three edges: the result depends on the order of the face's vertices."""
    from .. import ops

    return Field(FACE_SCALAR, ops.face_features(points, state.face_neighborhood())[:, 0, :])


_NEGATIVE = [
    Entry(
        "negative.complex_bias",
        _biased_linear,
        {"x": (VERTEX_TANGENT, 3)},
        ("permute_vertices", "fold"),
        init=_init_biased_linear,
        expect_fail=("gauge",),
        group="negative",
        doc="complex linear layer with a bias: breaks gauge equivariance",
    ),
    Entry(
        "negative.extrinsic_log",
        _extrinsic_log_moment,
        {"s": (VERTEX_SCALAR, 3)},
        ("rigid",),
        expect_fail=("fold", "hinge"),
        group="negative",
        doc="log map from projected (extrinsic) angles: breaks isometry invariance",
    ),
    Entry(
        "negative.face_vertex_order",
        _first_edge_features,
        {"points": (POINTS, 3)},
        ("rigid", "permute_faces"),
        expect_fail=("rotate_corners",),
        group="negative",
        doc="face features of the first edge only (no max over edges): depends on vertex order",
    ),
]

for _e in _NEGATIVE:
    register(_e)

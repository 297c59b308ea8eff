"""DGTS face operators: exact cases, slow loop references, invariances, padding, batching, dtypes, grads."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jmeshtex import InputError
from jmeshtex.data import grid, icosahedron
from jmeshtex.geometry import face_neighborhood, pad_to
from jmeshtex.ops import (
    FaceConvParams,
    FaceEmbedParams,
    edge_frames,
    face_conv,
    face_conv_stack,
    face_edge_embed,
    face_features,
    face_to_vertex_displacement,
    init_face_conv_stack,
    instance_norm,
)

# Every op runs under jax.jit here (the eager path is compared once, in the jit test): with
# jax_debug_nans on, eager op-by-op dispatch is ~20x slower than one compiled call.
_frames = jax.jit(edge_frames)
_features = jax.jit(face_features)
_embed = jax.jit(face_edge_embed)
_conv = jax.jit(face_conv)
_disp = jax.jit(face_to_vertex_displacement)
_norm = jax.jit(instance_norm)
_stack = jax.jit(face_conv_stack)
WIDTHS = (5, 4, 3)  # one stack shape everywhere: fewer compilations

# ----------------------------------------------------------------------------- fixtures / helpers


def _open_mesh(rng, n=2):
    """A bumpy open grid plus one isolated triangle (boundary faces and a face with no neighbour)."""
    v, f = grid(n)
    v = v + np.concatenate([np.zeros((len(v), 2)), 0.2 * rng.standard_normal((len(v), 1))], 1)
    iso_v = np.array([[2.0, 0.0, 0.3], [3.0, 0.1, 0.0], [2.2, 1.0, -0.2]])
    iso_f = np.array([[0, 1, 2]]) + len(v)
    return np.concatenate([v, iso_v]), np.concatenate([f, iso_f])


def _closed_mesh(rng):
    v, f = icosahedron()
    return v * (1 + 0.1 * rng.standard_normal((len(v), 1))), f


def _to_jax(nb):
    # a FaceNeighborhood holds only integers and booleans: no float dtype to choose
    return jax.tree.map(jnp.asarray, nb)


def _rotation(rng):
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _params(rng, c_in, c_out, cls=FaceConvParams):
    return cls(rng.standard_normal((c_in, c_out)), rng.standard_normal(c_out))


def _frames_ref(v, f):
    """Per face and edge: origin, x, y, z with plain NumPy loops."""
    F = len(f)
    out = np.zeros((4, F, 3, 3))
    for i in range(F):
        a, b, c = v[f[i]]
        n = np.cross(b - a, c - a)
        n = n / np.linalg.norm(n)
        for k in range(3):
            p, q = v[f[i, k]], v[f[i, (k + 1) % 3]]
            x = (q - p) / np.linalg.norm(q - p)
            out[:, i, k] = [(p + q) / 2, x, np.cross(n, x), n]
    return out


def _features_ref(v, f):
    """Features by loops, finding the neighbour across each edge by brute force."""
    origin, x, y, z = _frames_ref(v, f)
    feats = np.zeros((len(f), 3, 4))
    for i in range(len(f)):
        for k in range(3):
            a, b = f[i, k], f[i, (k + 1) % 3]
            opp = f[i, (k + 2) % 3]  # boundary substitute: the face's own opposite vertex
            for g in range(len(f)):
                for m in range(3):
                    if f[g, m] == b and f[g, (m + 1) % 3] == a:
                        opp = f[g, (m + 2) % 3]
            rel = v[opp] - origin[i, k]
            feats[i, k] = [np.linalg.norm(v[b] - v[a]), rel @ x[i, k], rel @ y[i, k], rel @ z[i, k]]
    return feats


def _conv_ref(x, f, params):
    """Face convolution by loops: max over faces sharing an edge of W^T [x_j; x_f] + b."""
    w, b = np.asarray(params.weight), np.asarray(params.bias)
    C = x.shape[1]
    out = np.zeros((len(f), w.shape[1]))
    for i in range(len(f)):
        cands = []
        for k in range(3):
            a, bb = f[i, k], f[i, (k + 1) % 3]
            for g in range(len(f)):
                for m in range(3):
                    if f[g, m] == bb and f[g, (m + 1) % 3] == a:
                        cands.append(np.concatenate([x[g], x[i]]) @ w + b)
        out[i] = np.max(cands, axis=0) if cands else x[i] @ w[C:] + b
    return out


def _displacement_ref(d, v, f):
    _, x, y, z = _frames_ref(v, f)
    acc = np.zeros((len(v), 3))
    count = np.zeros(len(v))
    for i in range(len(f)):
        for k in range(3):
            acc[f[i, k]] += d[i, 0] * x[i, k] + d[i, 1] * y[i, k] + d[i, 2] * z[i, k]
            count[f[i, k]] += 1
    return acc / np.maximum(count, 1)[:, None]


def _instance_norm_ref(x, eps):
    mu = x.mean(0)
    return (x - mu) / np.sqrt(((x - mu) ** 2).mean(0) + eps)


# ----------------------------------------------------------------------------- exact cases


def test_frames_single_triangle_exact():
    v = jnp.array([[0.0, 0, 0], [2, 0, 0], [0, 2, 0]])
    fr = _frames(v, face_neighborhood(np.array([[0, 1, 2]])))
    s = 1 / np.sqrt(2)
    np.testing.assert_allclose(fr.origin[0], [[1, 0, 0], [1, 1, 0], [0, 1, 0]], atol=1e-15)
    np.testing.assert_allclose(fr.x[0], [[1, 0, 0], [-s, s, 0], [0, -1, 0]], atol=1e-15)
    np.testing.assert_allclose(fr.y[0], [[0, 1, 0], [-s, -s, 0], [1, 0, 0]], atol=1e-15)
    np.testing.assert_allclose(fr.z[0], np.tile([0, 0, 1.0], (3, 1)), atol=1e-15)


def test_features_two_triangles_exact():
    # face 0 = (0,1,2) in z=0, face 1 = (2,1,3) with vertex 3 = (1,1,1) across the shared edge 1->2
    v = jnp.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 1]])
    feats = np.asarray(_features(v, face_neighborhood(np.array([[0, 1, 2], [2, 1, 3]]))))
    s = np.sqrt(2)
    # edge 0 (0->1, boundary): opposite is the face's own vertex 2 = (0,1,0), origin (.5,0,0)
    np.testing.assert_allclose(feats[0, 0], [1, -0.5, 1, 0], atol=1e-15)
    np.testing.assert_allclose(feats[0, 1], [s, 0, -1 / s, 1], atol=1e-15)
    # edge 2 (2->0, boundary): own opposite vertex 1 = (1,0,0), origin (0,.5,0), x=(0,-1,0), y=(1,0,0)
    np.testing.assert_allclose(feats[0, 2], [1, 0.5, 1, 0], atol=1e-15)
    # face 1, edge 0 (2->1) is shared: opposite vertex 0
    assert feats[1, 0, 0] == pytest.approx(s)
    np.testing.assert_allclose(
        feats, _features_ref(np.asarray(v), np.array([[0, 1, 2], [2, 1, 3]])), atol=1e-14
    )


def test_conv_and_embed_exact():
    nb = face_neighborhood(np.array([[0, 1, 2], [2, 1, 3], [4, 5, 6]]))  # face 2 is isolated
    p = FaceConvParams(jnp.array([[1.0, -1.0], [10.0, 0.0]]), jnp.array([0.5, 0.0]))
    y = _conv(jnp.array([[1.0], [2.0], [3.0]]), nb, p)
    # y_f = max_j (x_j, -x_j) + (10 x_f, 0) + b; isolated face: neighbour term 0
    np.testing.assert_array_equal(y, [[12.5, -2.0], [21.5, -1.0], [30.5, 0.0]])
    e = FaceEmbedParams(jnp.array([[1.0], [0.0], [-1.0], [0.0]]), jnp.array([1.0]))
    feats = jnp.array([[[1.0, 0, 5, 0], [2, 0, 0, 0], [0, 9, 1, 9]]])
    np.testing.assert_array_equal(_embed(feats, e), [[3.0]])  # max(1-5, 2-0, 0-1) + 1


def test_displacement_exact_single_triangle():
    v = jnp.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    nb = face_neighborhood(np.array([[0, 1, 2]]))
    out = _disp(jnp.array([[0.0, 1.0, 2.0]]), v, nb)
    s = 1 / np.sqrt(2)
    # d_y along y_k = z × x_k, d_z along the normal
    np.testing.assert_allclose(out, [[0, 1, 2], [-s, -s, 2], [1, 0, 2]], atol=1e-15)


def test_instance_norm_exact_and_masked(rng):
    x = rng.standard_normal((7, 3))
    y = _norm(jnp.asarray(x), jnp.ones(7, bool), eps=1e-5)
    np.testing.assert_allclose(y, _instance_norm_ref(x, 1e-5), rtol=1e-12)
    garbage = np.concatenate([x, 1e3 * rng.standard_normal((4, 3))])
    mask = np.arange(11) < 7
    yp = _norm(jnp.asarray(garbage), jnp.asarray(mask), eps=1e-5)
    np.testing.assert_allclose(yp[:7], y, rtol=1e-12)
    np.testing.assert_array_equal(yp[7:], 0)


# ----------------------------------------------------------------------------- slow references


@pytest.mark.parametrize("kind", ["open", "closed"])
def test_against_loop_references(kind, rng):
    v, f = _open_mesh(rng) if kind == "open" else _closed_mesh(rng)
    nb = face_neighborhood(f)
    vj = jnp.asarray(v)
    fr = _frames(vj, nb)
    for got, want in zip(fr, _frames_ref(v, f), strict=True):
        np.testing.assert_allclose(got, want, atol=1e-12)
    np.testing.assert_allclose(_features(vj, nb), _features_ref(v, f), atol=1e-12)

    feats = rng.standard_normal((len(f), 3, 4))
    e = _params(rng, 4, 5, FaceEmbedParams)
    want = np.max(feats @ e.weight + e.bias, axis=1)
    np.testing.assert_allclose(_embed(jnp.asarray(feats), e), want, rtol=1e-12)

    x = rng.standard_normal((len(f), 4))
    p = _params(rng, 8, 6)
    np.testing.assert_allclose(
        _conv(jnp.asarray(x), nb, p), _conv_ref(x, f, p), rtol=1e-12, atol=1e-12
    )

    d = rng.standard_normal((len(f), 3))
    np.testing.assert_allclose(
        _disp(jnp.asarray(d), vj, nb), _displacement_ref(d, v, f), atol=1e-12
    )


def test_stack_against_loop_reference(rng):
    v, f = _open_mesh(rng)
    nb = face_neighborhood(f)
    params = init_face_conv_stack(jax.random.key(1), WIDTHS, dtype=jnp.float64)
    feats = _features_ref(v, f)
    h = np.max(feats @ np.asarray(params.embed.weight) + np.asarray(params.embed.bias), axis=1)
    for conv in params.convs:
        h = _instance_norm_ref(h, 1e-5)
        h = np.where(h > 0, h, 0.2 * h)
        h = _conv_ref(h, f, conv)
    got = _stack(_features(jnp.asarray(v), nb), nb, params)
    np.testing.assert_allclose(got, h, rtol=1e-10, atol=1e-12)


# ----------------------------------------------------------------------------- invariances


def test_rigid_motion_invariance_and_equivariance(rng):
    v, f = _closed_mesh(rng)
    nb = face_neighborhood(f)
    R, t = _rotation(rng), rng.standard_normal(3)
    v2 = v @ R.T + t
    feats = _features(jnp.asarray(v), nb)
    np.testing.assert_allclose(_features(jnp.asarray(v2), nb), feats, atol=1e-12)
    d = jnp.asarray(rng.standard_normal((len(f), 3)))
    out = _disp(d, jnp.asarray(v), nb)
    out2 = _disp(d, jnp.asarray(v2), nb)
    np.testing.assert_allclose(out2, np.asarray(out) @ R.T, atol=1e-12)
    # a reflection flips the orientation: the y axis and normal then disagree (the frame is chiral)
    Rm = R @ np.diag([1.0, 1.0, -1.0])
    assert not np.allclose(_features(jnp.asarray(v @ Rm.T), nb), feats, atol=1e-3)


def test_cyclic_vertex_order_invariance(rng):
    v, f = _open_mesh(rng)
    f_rolled = np.roll(f, 1, axis=1)  # (v2, v0, v1): new edge k is old edge k+2
    vj = jnp.asarray(v)
    nb, nb_r = face_neighborhood(f), face_neighborhood(f_rolled)
    feats, feats_r = _features(vj, nb), _features(vj, nb_r)
    np.testing.assert_allclose(feats_r, np.roll(feats, 1, axis=1), atol=1e-12)
    e = _params(rng, 4, 5, FaceEmbedParams)  # the shapes of the loop-reference test
    np.testing.assert_allclose(_embed(feats_r, e), _embed(feats, e), atol=1e-12)
    x = jnp.asarray(rng.standard_normal((len(f), 4)))
    p = _params(rng, 8, 6)
    np.testing.assert_allclose(_conv(x, nb_r, p), _conv(x, nb, p), atol=1e-12)
    d = jnp.asarray(rng.standard_normal((len(f), 3)))
    # displacements use the edge starting at each corner, which rotates with the vertex order
    np.testing.assert_allclose(_disp(d, vj, nb_r), _disp(d, vj, nb), atol=1e-12)


# ----------------------------------------------------------------------------- jit / padding / vmap


@jax.jit
def _pipeline(v, nb, params, d):
    feats = face_features(v, nb)
    h = face_conv_stack(feats, nb, params)
    return feats, h, face_to_vertex_displacement(d, v, nb)


def test_jit_matches_eager_and_compiles_once(rng):
    v, f = _open_mesh(rng)
    nb = _to_jax(face_neighborhood(f))
    F = len(f)
    e = FaceEmbedParams(*(jnp.asarray(a) for a in _params(rng, 4, 5, FaceEmbedParams)))
    p = FaceConvParams(*(jnp.asarray(a) for a in _params(rng, 10, 3)))
    d = jnp.asarray(rng.standard_normal((F, 3)))
    traces = []

    def raw(v, nb, e, p, d):  # every op once, un-jitted
        traces.append(1)
        feats = face_features(v, nb)
        h = instance_norm(face_edge_embed(feats, e), nb.face_mask)
        y = face_conv(h, nb, p)
        return (
            feats,
            h,
            y,
            face_to_vertex_displacement(y, v, nb) + face_to_vertex_displacement(d, v, nb),
        )

    jitted = jax.jit(raw)
    eager = raw(jnp.asarray(v), nb, e, p, d)
    for got, want in zip(jitted(jnp.asarray(v), nb, e, p, d), eager, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-13)
    jitted(jnp.asarray(v + 0.01), nb, e, p, d + 1)
    assert len(traces) == 2  # once eagerly, once for the compilation; the second call reuses it


def test_padding_invariance(rng):
    v, f = _open_mesh(rng)
    nb = face_neighborhood(f)
    F, V, M = len(f), len(v), nb.vertex_faces.shape[1]
    nb_pad = pad_to(nb, {"F": F + 5, "V": V + 3, "M": M + 2})
    v_pad = np.concatenate([v, 100 * rng.standard_normal((3, 3))])  # padded vertices: garbage
    params = init_face_conv_stack(jax.random.key(2), WIDTHS, dtype=jnp.float64)
    d = rng.standard_normal((F, 3))
    d_pad = np.concatenate([d, 100 * rng.standard_normal((5, 3))])
    feats, h, disp = _pipeline(jnp.asarray(v), nb, params, jnp.asarray(d))
    feats_p, h_p, disp_p = _pipeline(jnp.asarray(v_pad), nb_pad, params, jnp.asarray(d_pad))
    np.testing.assert_allclose(feats_p[:F], feats, rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(feats_p[F:], 0)
    np.testing.assert_allclose(h_p[:F], h, rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(h_p[F:], 0)
    np.testing.assert_allclose(disp_p[:V], disp, rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(disp_p[V:], 0)
    # face_conv alone with garbage features on padded faces
    x = rng.standard_normal((F, 4))
    x_pad = np.concatenate([x, 1e6 * rng.standard_normal((5, 4))])
    p = _params(rng, 8, 6)
    np.testing.assert_allclose(
        _conv(jnp.asarray(x_pad), nb_pad, p)[:F], _conv(jnp.asarray(x), nb, p), rtol=1e-12
    )


def test_vmap_over_two_padded_meshes(rng):
    meshes = [_open_mesh(rng, 1), _open_mesh(rng)]  # 3 and 9 faces
    nbs = [face_neighborhood(f) for _, f in meshes]
    F = max(len(f) for _, f in meshes)
    V = max(len(v) for v, _ in meshes)
    M = max(nb.vertex_faces.shape[1] for nb in nbs)
    padded = [pad_to(nb, {"F": F, "V": V, "M": M}) for nb in nbs]
    batch_nb = jax.tree.map(lambda *a: jnp.stack(a), *padded)
    batch_v = jnp.stack([jnp.pad(jnp.asarray(v), ((0, V - len(v)), (0, 0))) for v, _ in meshes])
    ds = [rng.standard_normal((len(f), 3)) for _, f in meshes]
    batch_d = jnp.stack([jnp.pad(jnp.asarray(d), ((0, F - len(d)), (0, 0))) for d in ds])
    params = init_face_conv_stack(jax.random.key(3), WIDTHS, dtype=jnp.float64)
    out = jax.vmap(_pipeline, in_axes=(0, 0, None, 0))(batch_v, batch_nb, params, batch_d)
    for b, ((v, f), nb, d) in enumerate(zip(meshes, nbs, ds, strict=True)):
        single = _pipeline(jnp.asarray(v), nb, params, jnp.asarray(d))
        np.testing.assert_allclose(out[0][b, : len(f)], single[0], rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(out[1][b, : len(f)], single[1], rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(out[2][b, : len(v)], single[2], rtol=1e-12, atol=1e-14)


# ----------------------------------------------------------------------------- dtypes / grads


def test_dtype_follows_input(rng):
    v, f = _open_mesh(rng)
    nb = _to_jax(face_neighborhood(f))
    params = init_face_conv_stack(jax.random.key(0), WIDTHS, dtype=jnp.float32)  # cast inside
    d = rng.standard_normal((len(f), 3))
    outs = {
        dt: _pipeline(jnp.asarray(v, dt), nb, params, jnp.asarray(d, dt))
        for dt in (jnp.float32, jnp.float64)
    }
    for dt, out in outs.items():
        assert all(o.dtype == dt for o in out)
    for got, want in zip(outs[jnp.float32], outs[jnp.float64], strict=True):
        # float32 agrees with float64 to float32 precision, relative to the array's norm (instance
        # norm divides by per-channel spreads)
        err = np.linalg.norm(np.asarray(got, np.float64) - want) / np.linalg.norm(want)
        assert err < 1e-5


def test_degenerate_geometry_finite_values_and_grads():
    # face 0 is collinear, face 1 has two coincident corners, face 2 is fine, face 3 collapses to a
    # point (built by hand: repeated indices are no valid half-edges); every value and gradient must
    # be finite (jax_debug_nans is on)
    v = jnp.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [0, 1, 0], [3, 3, 3], [0, 0, 1]])
    nb = face_neighborhood(np.array([[0, 1, 2], [1, 3, 4], [0, 6, 1]]), num_vertices=7)
    nb = nb._replace(
        faces=np.concatenate([nb.faces, [[5, 5, 5]]]).astype(np.int32),
        neighbors=np.concatenate([nb.neighbors, [[0, 0, 0]]]).astype(np.int32),
        opposite=np.concatenate([nb.opposite, [[5, 5, 5]]]).astype(np.int32),
        mask=np.concatenate([nb.mask, [[False] * 3]]),
        face_mask=np.ones(4, bool),
    )
    params = init_face_conv_stack(jax.random.key(0), WIDTHS, dtype=jnp.float64)

    def loss(v, zero_feats):
        feats = face_features(v, nb)
        h = face_conv_stack(feats, nb, params)
        h0 = face_conv_stack(zero_feats, nb, params)  # exactly-zero features into the stack
        return (
            jnp.sum(feats**2)
            + jnp.sum(h**2)
            + jnp.sum(h0**2)
            + jnp.sum(face_to_vertex_displacement(h, v, nb) ** 2)
        )

    feats = _features(v, nb)
    assert np.isfinite(np.asarray(feats)).all()
    np.testing.assert_array_equal(feats[3], 0)  # a point: zero length, zero frame
    np.testing.assert_array_equal(feats[0, :, 3], 0)  # collinear: no normal, z coordinates 0
    # gradients w.r.t. the degenerate vertices and w.r.t. exactly-zero features into the stack
    gv, gz = jax.jit(jax.grad(loss, argnums=(0, 1)))(v, jnp.zeros((4, 3, 4)))
    assert np.isfinite(np.asarray(gv)).all() and np.isfinite(np.asarray(gz)).all()


def test_check_grads(rng):
    v, f = _open_mesh(rng)
    nb = _to_jax(face_neighborhood(f))
    F = len(f)
    shapes = [v.shape, (F, 3), (F, 3), (6, 4), (4,), (4, 5), (5,)]
    sizes = [int(np.prod(s)) for s in shapes]
    flat = jnp.asarray(np.concatenate([v.ravel(), rng.standard_normal(sum(sizes[1:]))]))

    @jax.jit
    def all_ops(flat):
        # one flat vector in and out: check_grads' eager pytree arithmetic then stays cheap
        parts = jnp.split(flat, np.cumsum(sizes)[:-1])
        v, d, x, pw, pb, ew, eb = (a.reshape(s) for a, s in zip(parts, shapes, strict=True))
        feats = face_features(v, nb)
        outs = (
            feats,
            face_edge_embed(feats, FaceEmbedParams(ew, eb)),
            face_conv(x, nb, FaceConvParams(pw, pb)),
            instance_norm(x, nb.face_mask),
            face_to_vertex_displacement(d, v, nb),
        )
        return jnp.concatenate([o.ravel() for o in outs])

    # the edge embedding and the leaky ReLUs are piecewise linear: a finite difference of step eps
    # crosses a kink when a pre-activation lies within eps of 0. With the default eps = 1e-4 that
    # happened in CI (seed 1202288285, ~1 run in 20); at 1e-6 (float64: truncation and rounding
    # errors both far below the tolerance) it is ~100x rarer.
    check_grads(all_ops, (flat,), order=1, modes=["fwd", "rev"], eps=1e-6)


def test_elementwise_max_derivative_goes_to_the_first_maximum(rng):
    from jmeshtex.ops import elementwise_max

    a, b, c = jnp.array([1.0, 2.0, 3.0]), jnp.array([1.0, 5.0, 3.0]), jnp.array([0.0, 5.0, 3.0])
    np.testing.assert_array_equal(elementwise_max((a, b, c)), [1.0, 5.0, 3.0])
    ga, gb, gc = jax.jit(
        jax.grad(lambda xs: jnp.sum(elementwise_max(xs) * jnp.array([1.0, 2.0, 3.0])))
    )((a, b, c))
    np.testing.assert_array_equal(ga, [1, 0, 3])  # ties: the first input attaining the max
    np.testing.assert_array_equal(gb, [0, 2, 0])
    np.testing.assert_array_equal(gc, [0, 0, 0])
    _, tangent = jax.jvp(elementwise_max, ((a, b, c),), ((a * 0 + 1, a * 0 + 2, a * 0 + 3),))
    np.testing.assert_array_equal(tangent, [1, 2, 1])
    # finite differences must not cross a kink: at every position the largest of the four inputs
    # leads the runner-up by at least 0.25 (random levels 0, 0.5, 1, 1.5 per position plus noise
    # below 0.125; plain normals put two within check_grads' step for 1 seed in 100)
    levels = np.stack([rng.permutation(4) for _ in range(5)], axis=1) * 0.5
    xs = tuple(jnp.asarray(x + rng.uniform(-0.125, 0.125, 5)) for x in levels)
    check_grads(jax.jit(elementwise_max), (xs,), order=1, modes=["fwd", "rev"])


# ----------------------------------------------------------------------------- errors


@pytest.mark.unchecked  # ill-typed arguments on purpose: the function's own typed errors
def test_bad_input_raises_typed_errors(rng):
    v, f = _closed_mesh(rng)
    nb = face_neighborhood(f)
    with pytest.raises(InputError, match=r"\[V, 3\]"):
        _features(jnp.ones((len(v), 2)), nb)
    with pytest.raises(InputError, match="pad the vertices"):
        _features(jnp.ones((len(v) - 1, 3)), nb)
    with pytest.raises(InputError, match="2C"):
        _conv(jnp.ones((len(f), 3)), nb, FaceConvParams(jnp.ones((3, 2)), jnp.ones(2)))
    with pytest.raises(InputError, match="F ="):
        _conv(jnp.ones((len(f) + 1, 3)), nb, FaceConvParams(jnp.ones((6, 2)), jnp.ones(2)))
    with pytest.raises(InputError, match="edge features"):
        _embed(jnp.ones((len(f), 3, 4)), FaceEmbedParams(jnp.ones((3, 2)), jnp.ones(2)))
    with pytest.raises(InputError, match=r"\[F, 3\]"):
        _disp(jnp.ones((len(f), 2)), jnp.asarray(v), nb)
    with pytest.raises(InputError, match="positive widths"):
        init_face_conv_stack(jax.random.key(0), ())


def test_one_layer_init_is_the_stacks_layer_and_checks_its_widths():
    import jax
    import pytest

    from jmeshtex import InputError
    from jmeshtex.data import icosphere
    from jmeshtex.geometry import face_neighborhood
    from jmeshtex.ops import face_conv, init_face_conv

    mesh = icosphere(1)
    params = init_face_conv(jax.random.key(0), 5, 3)
    x = jax.random.normal(jax.random.key(1), (mesh.num_faces, 5))
    assert face_conv(x, face_neighborhood(mesh), params).shape == (mesh.num_faces, 3)
    bound = 1 / (2 * 5) ** 0.5  # Conv1d's default on [x_j ; x_f]
    assert 0.5 * bound < float(abs(params.weight).max()) <= bound
    with pytest.raises(InputError, match="out_features must be an integer >= 1"):
        init_face_conv(jax.random.key(0), 5, 0)

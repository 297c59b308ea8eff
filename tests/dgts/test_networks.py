"""Generator / discriminator levels: exact analytic cases, hierarchy structure, gradient penalty."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex.data import grid, icosahedron
from jmeshtex.dgts import Config
from jmeshtex.dgts.core import (
    Discriminator,
    Generator,
    discriminator,
    generate,
    generator_level,
    gradient_penalty,
    hierarchy_geometry,
    init_level,
    upsample,
)
from jmeshtex.geometry import face_neighborhood, subdivide_midpoint
from jmeshtex.ops import FaceConvParams, face_features, init_face_conv_stack


def _constant_output(params, b):
    """Replace the last layer by weight 0 and bias b: every face emits b."""
    last = params.convs[-1]
    convs = params.convs[:-1] + (
        FaceConvParams(jnp.zeros_like(last.weight), jnp.asarray(b, last.bias.dtype)),
    )
    return params._replace(convs=convs)


def test_constant_normal_coefficient_moves_a_flat_sheet_along_its_normal():
    v, f = grid(4)
    p = _constant_output(
        init_face_conv_stack(jax.random.key(0), (8, 8, 3), dtype=jnp.float64), [0.0, 0.0, 0.25]
    )
    d = generator_level(p, jnp.asarray(v), face_neighborhood(f), jnp.ones((len(v), 3)) * 0.3)
    np.testing.assert_allclose(np.asarray(d), np.tile([0.0, 0.0, 0.25], (len(v), 1)), atol=1e-14)


def test_noise_changes_features_not_the_frames():
    """With constant output the noise cannot matter; with a real network it must."""
    v, f = icosahedron()
    nb = face_neighborhood(f)
    x = jnp.asarray(v)
    z = 0.1 * jax.random.normal(jax.random.key(1), x.shape, jnp.float64)
    p = init_face_conv_stack(jax.random.key(0), (8, 8, 3), dtype=jnp.float64)
    assert not np.allclose(generator_level(p, x, nb, z), generator_level(p, x, nb))
    pc = _constant_output(p, [0.1, 0.2, 0.3])
    np.testing.assert_allclose(
        generator_level(pc, x, nb, z), generator_level(pc, x, nb), atol=1e-14
    )


def test_upsample_matches_subdivide_midpoint():
    v, f = icosahedron()
    sub = subdivide_midpoint(v, f)
    out = upsample(jnp.asarray(v), jnp.asarray(sub.edge_vertices), scale=2.0)
    np.testing.assert_allclose(np.asarray(out), 2.0 * sub.vertices, atol=1e-14)


def test_hierarchy_geometry_and_generate_shapes():
    v, f = icosahedron()
    geos, faces = hierarchy_geometry(f, 12, 3)
    assert [len(x) for x in faces] == [20, 80, 320]
    ps = [init_face_conv_stack(jax.random.key(i), (8, 3), dtype=jnp.float64) for i in range(3)]
    zero = [_constant_output(p, [0.0, 0.0, 0.0]) for p in ps]
    out = generate(zero, jnp.asarray(v), geos, [0.0] * 3)
    # zero displacement: pure subdivision ×2 twice
    ref = v
    for _ in range(2):
        s = subdivide_midpoint(ref, faces[0] if len(ref) == 12 else faces[1])
        ref = 2 * s.vertices
    np.testing.assert_allclose(np.asarray(out), ref, atol=1e-12)
    with pytest.raises(Exception, match="one of each per level"):
        generate(ps, jnp.asarray(v), geos[:2], [0.0] * 3)


def test_gradient_penalty_of_a_linear_critic_is_exact():
    """One embedding layer: D_f = max_k w·φ_fk + b, so ∇_φf Σ D = w at the arg-max edge: (|w| − 1)²."""
    v, f = icosahedron()
    v = v + 0.05 * np.random.default_rng(0).standard_normal(
        v.shape
    )  # no ties in the max over edges
    nb = face_neighborhood(f)
    w = jnp.array([[0.3], [-0.4], [1.2], [0.5]])
    from jmeshtex.ops import FaceConvStackParams, FaceEmbedParams

    p = FaceConvStackParams(FaceEmbedParams(w, jnp.zeros(1)), ())
    phi = face_features(jnp.asarray(v), nb)
    gp = gradient_penalty(p, phi, phi * 1.1, nb, jnp.asarray(0.3), negative_slope=0.2, eps=1e-5)
    assert float(gp) == pytest.approx((float(jnp.linalg.norm(w)) - 1) ** 2, rel=1e-12)


def test_init_level_widths_and_flax_wrappers_agree():
    c = Config(num_layers=4, start_features=8, min_features=4, max_features=16)
    g = init_level(c, 1, generator=True, key=jax.random.key(0))
    assert [g.embed.weight.shape[1]] + [x.weight.shape[1] for x in g.convs] == list(
        c.level_features(1, generator=True)
    )
    v, f = icosahedron()
    nb, x = face_neighborhood(f), jnp.asarray(v, jnp.float32)
    gm = Generator(c.level_features(1, generator=True))
    variables = gm.init(jax.random.key(0), x, nb)
    np.testing.assert_allclose(
        gm.apply(variables, x, nb), generator_level(variables["params"]["stack"], x, nb)
    )
    dm = Discriminator(c.level_features(1, generator=False))
    dv = dm.init(jax.random.key(0), x, nb)
    np.testing.assert_allclose(dm.apply(dv, x, nb), discriminator(dv["params"]["stack"], x, nb))

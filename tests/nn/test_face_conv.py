"""FaceConvStack: a thin wrapper whose parameters drive the pure op unchanged."""

from __future__ import annotations

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex.data import grid
from jmeshtex.geometry import face_neighborhood, pad_to
from jmeshtex.nn import FaceConvStack
from jmeshtex.ops import FaceConvStackParams, face_conv_stack, face_features

_features = jax.jit(face_features)  # eager dispatch is slow under jax_debug_nans


@pytest.fixture
def mesh(rng):
    v, f = grid(2)
    v = v + np.concatenate([np.zeros((len(v), 2)), 0.2 * rng.standard_normal((len(v), 1))], 1)
    return v, f, face_neighborhood(f)


def test_module_is_the_op_with_its_parameters(mesh):
    v, f, nb = mesh
    x = _features(jnp.asarray(v), nb)
    model = FaceConvStack((6, 5, 3))
    variables = jax.jit(model.init)(jax.random.key(0), x, nb)
    params = variables["params"]["stack"]
    assert isinstance(params, FaceConvStackParams)
    assert params.embed.weight.shape == (4, 6) and [c.weight.shape for c in params.convs] == [
        (12, 5),
        (10, 3),
    ]
    assert params.embed.weight.dtype == jnp.float32
    # PyTorch Conv1d default init: U(-1/sqrt(fan_in), 1/sqrt(fan_in))
    assert float(jnp.max(jnp.abs(params.convs[0].weight))) <= 1 / np.sqrt(12)
    apply = jax.jit(model.apply)
    out = apply(variables, x, nb)
    np.testing.assert_allclose(out, jax.jit(face_conv_stack)(x, nb, params), rtol=1e-13, atol=1e-14)
    assert out.shape == (len(f), 3) and out.dtype == jnp.float64  # follows the float64 input


def test_padding_and_gradients_through_the_module(mesh, rng):
    v, f, nb = mesh
    F, V = len(f), len(v)
    model = FaceConvStack((4, 3), negative_slope=0.1)
    x = _features(jnp.asarray(v), nb)
    variables = jax.jit(model.init)(jax.random.key(1), x, nb)
    nb_pad = pad_to(nb, {"F": F + 3, "V": V + 2, "M": nb.vertex_faces.shape[1] + 1})
    x_pad = _features(jnp.pad(jnp.asarray(v), ((0, 2), (0, 0))), nb_pad)
    apply = jax.jit(model.apply)
    np.testing.assert_allclose(
        apply(variables, x_pad, nb_pad)[:F], apply(variables, x, nb), rtol=1e-12
    )

    def loss(variables):
        return jnp.sum(model.apply(variables, x, nb) ** 2)

    grads = jax.jit(jax.grad(loss))(variables)
    for leaf in jax.tree.leaves(grads):
        assert np.isfinite(np.asarray(leaf)).all() and np.any(np.asarray(leaf) != 0)


def test_module_composes_inside_a_larger_flax_model(mesh):
    v, f, nb = mesh

    class Head(nn.Module):
        @nn.compact
        def __call__(self, x, nb):
            return jnp.mean(FaceConvStack((4, 2))(x, nb), axis=0)

    x = _features(jnp.asarray(v, jnp.float32), nb)
    variables = jax.jit(Head().init)(jax.random.key(0), x, nb)
    out = jax.jit(Head().apply)(variables, x, nb)
    assert out.shape == (2,) and out.dtype == jnp.float32
    assert "stack" in variables["params"]["FaceConvStack_0"]

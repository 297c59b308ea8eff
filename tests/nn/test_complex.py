"""Flax complex layers: parameters are the ops' NamedTuple fields, apply == op, init statistics,
equivariance smoke tests, dtypes, and a training step with conjugated gradients."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from jmeshtex.nn import FRN, ComplexAttention, ComplexDense, VNNonlinearity, VNTransformerBlock
from jmeshtex.ops import (
    ComplexAttentionParams,
    FRNParams,
    VNParams,
    VNTransformerParams,
    complex_attention,
    complex_linear,
    conjugate_complex_grads,
    filter_response_norm,
    vn_nonlinearity,
    vn_transformer_block,
)
from tests._random_fields import crandn, rel_err

C = 4
AREA = np.array([1.0, 2.0, 0.5, 1.5, 1.0])
MASK = np.array([True, True, False, True, True])


def nested(flat, cls):
    """Rebuild an ops NamedTuple from a module's flat parameter dict (names joined with '_')."""
    subtypes = {"attention": ComplexAttentionParams, "mlp_in": VNParams, "mlp_out": VNParams}
    out = {}
    for name in cls._fields:
        if cls is VNTransformerParams and name in subtypes:
            sub = {k[len(name) + 1 :]: v for k, v in flat.items() if k.startswith(name + "_")}
            out[name] = nested(sub, subtypes[name])
        else:
            out[name] = flat.get(name)
    return cls(**out)


MODULES = {  # name -> (module, call kwargs, op(x, params), params NamedTuple type or None for a bare kernel)
    "dense": (ComplexDense(3), {}, complex_linear, None),
    "vn": (VNNonlinearity(), {}, vn_nonlinearity, VNParams),
    "vn_dense": (VNNonlinearity(3), {}, vn_nonlinearity, VNParams),
    "frn": (
        FRN(),
        {"area": AREA, "vertex_mask": MASK},
        lambda x, p: filter_response_norm(x, p, area=AREA, vertex_mask=MASK),
        FRNParams,
    ),
    "attention": (
        ComplexAttention(num_heads=2),
        {"mask": MASK},
        lambda x, p: complex_attention(x, p, mask=MASK),
        ComplexAttentionParams,
    ),
    "block": (
        VNTransformerBlock(num_heads=2, mlp_features=6),
        {"mask": MASK},
        lambda x, p: vn_transformer_block(x, p, mask=MASK),
        VNTransformerParams,
    ),
}


def shapes(name):
    module, kwargs, _, _ = MODULES[name]
    return jax.eval_shape(
        lambda key: module.init(key, jnp.zeros((5, C), jnp.complex64), **kwargs), jax.random.key(0)
    )


@functools.cache
def variables(name):
    """Random values in the module's variable structure (the real init is tested separately)."""
    rng = np.random.default_rng(0)

    def fill(s):
        v = rng.standard_normal(s.shape) + (
            1j * rng.standard_normal(s.shape) if np.iscomplexobj(np.zeros(0, s.dtype)) else 0
        )
        return jnp.asarray(0.5 * v, s.dtype)

    return jax.tree.map(fill, shapes(name))


@pytest.mark.parametrize("name", MODULES)
def test_apply_equals_op_with_the_module_parameters(rng, name):
    module, kwargs, op, cls = MODULES[name]
    rot = complex(np.exp(0.7j))  # a Python scalar: weakly typed, keeps complex64

    @jax.jit
    def run(v, x):
        params = v["params"]["kernel"] if cls is None else nested(dict(v["params"]), cls)
        return module.apply(v, x, **kwargs), op(x, params), module.apply(v, x * rot, **kwargs)

    y, want, y_rot = run(variables(name), jnp.asarray(crandn(rng, 5, C), jnp.complex64))
    assert rel_err(y, want) < 1e-6
    # equivariance smoke test: a common rotation of all channels (and set elements) rotates the output
    assert rel_err(y_rot, y * rot) < 1e-5


@pytest.mark.parametrize("name", MODULES)
def test_complex128_input_gives_complex128_output(name):
    module, kwargs, _, _ = MODULES[name]
    out = jax.eval_shape(
        lambda v, x: module.apply(v, x, **kwargs),
        variables(name),
        jnp.zeros((5, C), jnp.complex128),
    )
    assert out.dtype == jnp.complex128


def test_parameter_names_and_init():
    assert set(shapes("vn")["params"]) == {"direction"}
    assert set(shapes("vn_dense")["params"]) == {"weight", "direction"}
    frn = FRN().init(jax.random.key(0), jnp.zeros((5, C), jnp.complex64), area=AREA)["params"]
    np.testing.assert_array_equal(frn["scale"], 1)
    np.testing.assert_allclose(frn["eps"], 1e-3)
    block = shapes("block")["params"]
    assert {
        "attention_norm",
        "attention_query",
        "mlp_norm",
        "mlp_in_weight",
        "mlp_out_direction",
    } <= set(block)
    # complex LeCun normal: circular, E|w|^2 = 1/fan_in
    big = jax.jit(ComplexDense(512).init)(jax.random.key(1), jnp.zeros((1, 256), jnp.complex64))[
        "params"
    ]["kernel"]
    w = np.asarray(big, np.complex128)
    assert abs(np.mean(np.abs(w) ** 2) * 256 - 1) < 0.02
    assert abs(np.mean(w)) < 0.01 and abs(np.mean(w**2)) * 256 < 0.02  # no preferred phase


def test_adam_with_conjugated_gradients_trains_a_complex_dense_layer(rng):
    module = ComplexDense(2)
    x = jnp.asarray(crandn(rng, 32, 3), jnp.complex64)
    target = x @ jnp.asarray(crandn(rng, 3, 2), jnp.complex64)
    v = jax.jit(module.init)(jax.random.key(2), x)
    loss = jax.jit(lambda v: jnp.mean(jnp.abs(module.apply(v, x) - target) ** 2))
    opt = optax.adam(0.05)
    with jax.numpy_dtype_promotion("standard"):  # optax mixes complex and real moments
        state = opt.init(v)
        step = jax.jit(lambda v, s: opt.update(conjugate_complex_grads(jax.grad(loss)(v)), s, v))
        before = loss(v)
        for _ in range(100):
            updates, state = step(v, state)
            v = optax.apply_updates(v, updates)
    assert loss(v) < 0.05 * before

"""The one-call check a user runs on an operator of their own, and the multi-hop selection that lets
a stacked k-NN network be judged under smooth isometries."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from equivariance_tests._toy_operators import centroid_distance, centroid_distance_and_height
from jmeshtex import InputError, MeshError
from jmeshtex.data import icosphere
from jmeshtex.testing import (
    CATALOGUE,
    Field,
    MeshState,
    assert_equivariant,
    convergence,
    random_inputs,
)


def test_an_equivariant_operator_passes_every_named_transform_in_one_call():
    errors = assert_equivariant(
        centroid_distance,
        jax.random.key(3),
        {"x": ("vertex_scalar", 2)},
        transforms=("rigid", "reflection", "permute_vertices", "permute_faces"),
    )
    assert set(errors) == {"rigid", "reflection", "permute_vertices", "permute_faces"}
    assert max(errors.values()) < 1e-10


def test_a_failure_names_the_transform_and_the_broken_output_channel():
    v, f = icosphere(1)
    state = MeshState(v, f)
    real = CATALOGUE["rigid"].draw(np.random.default_rng(1), state)
    with pytest.raises(AssertionError) as info:
        assert_equivariant(
            centroid_distance_and_height, 0, {"x": ("vertex_scalar", 1)}, transforms=[real]
        )
    message = str(info.value)
    assert "rigid: relative error" in message
    # channel 1 (the height) is the broken one: listed first, channel 0 at round-off
    per_channel = message.split("per output channel: ")[1]
    first, second = per_channel.split(", ")
    assert first.startswith("1: ") and second.startswith("0: ")
    assert float(second.split(": ")[1]) < 1e-12 < 1e-3 < float(first.split(": ")[1])


def test_bad_arguments_are_typed_errors():
    v, f = icosphere(1)
    fixed = {"x": Field("vertex_scalar", np.ones((len(v), 1)))}
    with pytest.raises(InputError, match="fixed Fields on one mesh"):
        assert_equivariant(centroid_distance, 0, fixed, transforms=("rigid",))
    with pytest.raises(InputError, match="unknown transforms"):
        assert_equivariant(centroid_distance, 0, {"x": ("vertex_scalar", 1)}, transforms=("shear",))
    with pytest.raises(InputError, match="key must be"):
        assert_equivariant(centroid_distance, "seed", {"x": ("vertex_scalar", 1)})


def _selected(state):
    nb = state.host_knn(8)
    return np.sort(np.where(nb.mask, nb.index, -1), axis=1)


def _knn_mean(nb, h):
    w = jnp.where(nb.mask, nb.weight, 0.0)
    return jnp.sum(w[..., None] * h[nb.index], axis=1) / jnp.sum(w, axis=1)[:, None]


def _two_knn_layers(state, x):
    nb = state.knn(8)
    return Field("vertex_scalar", _knn_mean(nb, jnp.tanh(_knn_mean(nb, x))))


def test_two_stacked_knn_layers_converge_only_with_a_two_hop_selection():
    """A flipped k-NN choice at q changes every output whose two-layer receptive field holds q:
    a one-hop mask leaves those in, and the error stops falling; two hops leave them out."""

    def conv(hops):
        return convergence(
            _two_knn_layers,
            CATALOGUE["cylinder"],
            lambda s, rng: random_inputs({"x": ("vertex_scalar", 2)}, s, rng),
            selection=_selected,
            hops=hops,
        )

    one, two = conv(1), conv(2)
    assert min(one.ratios) < 1.0, one  # the error grows on a refinement: flips leak through
    assert min(two.ratios) > 2.5 and two.errors[-1] < one.errors[-1] / 100, two
    assert all(b >= a for a, b in zip(one.excluded, two.excluded, strict=True))
    with pytest.raises(ValueError, match="hops must be an integer"):
        convergence(_two_knn_layers, CATALOGUE["cylinder"], lambda s, r: {}, hops=0)


def _two_field_convs(params, x, nb):
    from jmeshtex import ops

    h = ops.field_conv(x, nb, params[0])
    return ops.field_conv(h * jax.nn.sigmoid(jnp.abs(h)).astype(h.dtype), nb, params[1])


def test_a_model_is_checked_on_its_own_mesh_and_the_catalogue_with_a_one_line_adapter():
    from jmeshtex import ops

    keys = jax.random.split(jax.random.key(0), 2)
    params = [
        ops.init_field_conv(keys[0], 2, 4, hdim=4),
        ops.init_field_conv(keys[1], 4, 2, hdim=4),
    ]
    v, f = icosphere(1)
    # the mesh units (edges of ~5); jittered: exact ties in path lengths would make the
    # k-NN selection follow the vertex labels, and permute_vertices rightly fail
    v = 11.7 * (v + 0.03 * np.random.default_rng(0).standard_normal(v.shape))
    errors = assert_equivariant(
        lambda state, x: _two_field_convs(params, x, state.knn(8)),  # the whole adapter
        jax.random.key(1),
        {"x": ("vertex_tangent", 2)},
        output="vertex_tangent",
        mesh=(v, f),
        transforms=("rigid", "gauge", "permute_vertices", "fold"),
    )
    assert set(errors) == {"rigid", "gauge", "permute_vertices", "fold"}
    bound = 1e-10 if jax.config.jax_enable_x64 else 1e-5
    assert max(errors.values()) < bound


def test_a_failure_on_your_own_mesh_says_so():
    v, f = icosphere(1)
    v = v + 0.03 * np.random.default_rng(0).standard_normal(v.shape)

    def frozen(state, x):  # a tangent output that ignores the frame: not gauge-equivariant
        return jnp.ones_like(x) + 0 * state.knn(6).log[:, :1]

    with pytest.raises(AssertionError) as info:
        assert_equivariant(
            frozen,
            0,
            {"x": ("vertex_tangent", 1)},
            output="vertex_tangent",
            mesh=(v, f),
            transforms=("gauge", "permute_vertices"),
        )
    message = str(info.value)
    assert "gauge on your mesh: relative error" in message and "\n  gauge: relative" in message


def test_the_short_path_refuses_what_it_cannot_read():
    v, f = icosphere(1)
    spec = {"x": ("vertex_scalar", 1)}
    with pytest.raises(TypeError, match="output='vertex_tangent'"):
        assert_equivariant(lambda s, x: 2 * x, 0, spec, transforms=("rigid",))
    with pytest.raises(InputError, match="output must be one of"):
        assert_equivariant(lambda s, x: 2 * x, 0, spec, output="vector", transforms=("rigid",))
    with pytest.raises(InputError, match="mesh must be"):
        assert_equivariant(lambda s, x: 2 * x, 0, spec, output="vertex_scalar", mesh="cow.obj")
    with pytest.raises(MeshError, match="out of range"):  # as the loaders name it
        assert_equivariant(
            lambda s, x: 2 * x, 0, spec, output="vertex_scalar", mesh=(v, f + len(v))
        )

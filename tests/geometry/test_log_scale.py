"""Log maps at unit scale: the builders' ``scale=``, the recorded ``log_unit``, padding and
``field_conv``'s check."""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jmeshtex._neighborhoods as neighborhoods
from jmeshtex import (
    InputError,
    LogScaleWarning,
    VertexNeighborhood,
    check_log_scale,
    scale_log_maps,
)
from jmeshtex._neighborhoods import LOG_SCALE_RANGE
from jmeshtex.data import grid, icosphere
from jmeshtex.geometry import (
    geodesic_knn_neighborhood,
    mean_edge_length,
    one_ring_neighborhood,
    pad_to,
    to_jax,
)
from jmeshtex.ops import field_conv, init_field_conv


def _small(mesh, factor):
    return mesh.vertices * factor, mesh.faces


@pytest.mark.parametrize("builder", [one_ring_neighborhood, geodesic_knn_neighborhood])
def test_mean_edge_scale_divides_by_the_mean_edge_and_records_it(builder):
    v, f = _small(icosphere(1), 0.01)
    raw = builder(v, f, scale=None)
    unit = builder(v, f, scale="mean_edge")
    edge = mean_edge_length(v, f)
    assert raw.log_unit is None
    default = builder(v, f)  # the default is the mean edge, recorded
    np.testing.assert_array_equal(default.log, unit.log)
    assert float(default.log_unit) == float(unit.log_unit)
    np.testing.assert_allclose(float(unit.log_unit), edge, rtol=1e-12)
    np.testing.assert_allclose(unit.log * edge, raw.log, rtol=1e-12, atol=1e-15)
    for name in ("index", "mask", "transport", "weight", "area", "vertex_mask"):
        np.testing.assert_array_equal(getattr(unit, name), getattr(raw, name))
    r = np.abs(unit.log[unit.mask & (np.abs(unit.log) > 0)])
    assert 0.5 < np.median(r) < 2.0  # one edge ~ 1, on a mesh whose edges are ~0.006


def test_scale_is_invariant_to_the_mesh_size():
    mesh = icosphere(1)
    a = geodesic_knn_neighborhood(*_small(mesh, 1.0), k=6, scale="mean_edge")
    b = geodesic_knn_neighborhood(*_small(mesh, 0.001), k=6, scale="mean_edge")
    np.testing.assert_allclose(a.log, b.log, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(float(b.log_unit), 0.001 * float(a.log_unit), rtol=1e-12)


def test_a_float_scale_and_scale_log_maps_compose():
    v, f = grid(3)
    nb = one_ring_neighborhood(v, f, scale=0.5)
    np.testing.assert_allclose(
        nb.log, one_ring_neighborhood(v, f, scale=None).log / 0.5, rtol=1e-12
    )
    assert float(scale_log_maps(nb, 4.0).log_unit) == 2.0


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), "mean", True])
def test_bad_scales_raise(bad):
    v, f = grid(2)
    with pytest.raises(InputError):
        geodesic_knn_neighborhood(v, f, k=3, scale=bad)


def test_pad_to_and_to_jax_keep_the_unit():
    nb = geodesic_knn_neighborhood(*grid(3), k=4, scale="mean_edge")
    padded = pad_to(to_jax(nb), {"V": 20, "K": 6})
    assert padded.index.shape == (20, 6) and padded.log_unit.shape == ()
    np.testing.assert_allclose(float(padded.log_unit), float(nb.log_unit), rtol=1e-6)
    old = pad_to(geodesic_knn_neighborhood(*grid(3), k=4, scale=None), {"V": 20})
    assert old.log_unit is None  # unrecorded neighbourhoods keep their pytree structure


def _conv_inputs(nb):
    p = init_field_conv(jax.random.key(0), 2, 3, hdim=4, dtype=jnp.complex128)
    x = jnp.ones((nb.index.shape[0], 2), jnp.complex128)
    return x, p


def test_check_log_scale_warns_on_tiny_log_maps_and_not_at_unit_scale(monkeypatch):
    v, f = _small(icosphere(1), 0.01)
    raw = to_jax(geodesic_knn_neighborhood(v, f, k=5, scale=None), jnp.float64)
    with pytest.warns(LogScaleWarning, match="mean_edge"):
        check_log_scale(raw)
    unit = to_jax(geodesic_knn_neighborhood(v, f, k=5), jnp.float64)
    x, p = _conv_inputs(unit)
    monkeypatch.setattr(neighborhoods, "_WARNED", set())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_log_scale(unit)
        check_log_scale(unit._replace(log_unit=None))  # unit scale, unrecorded: silent too
        jax.jit(check_log_scale)(raw)  # traced: nothing to read, no warning
        jax.jit(field_conv)(x, raw, p)  # traced: silent
    with pytest.warns(LogScaleWarning, match="said once"):
        field_conv(x, raw, p)  # unrecorded and tiny: warns, once
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        y = field_conv(x, raw, p)  # not again
        field_conv(x, raw._replace(log=raw.log * 1e5), p)  # huge: also not again (once)
    assert y.shape == (x.shape[0], 3)


@pytest.mark.parametrize("factor", [1e-3, 50.0])
def test_field_conv_warns_on_unrecorded_units_far_from_one_and_not_near_one(monkeypatch, factor):
    v, f = icosphere(1).vertices, icosphere(1).faces
    unit = geodesic_knn_neighborhood(v, f, k=5)
    x, p = _conv_inputs(unit)
    monkeypatch.setattr(neighborhoods, "_WARNED", set())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for near in (0.3, 1.0, 4.0):  # unrecorded, but a typical edge of 0.3 to 4 is fine
            field_conv(x, to_jax(unit._replace(log=unit.log * near, log_unit=None)), p)
    far = to_jax(unit._replace(log=unit.log * factor, log_unit=None))
    assert not LOG_SCALE_RANGE[0] <= neighborhoods.typical_edge(far) <= LOG_SCALE_RANGE[1]
    with pytest.warns(LogScaleWarning, match="no recorded unit"):
        field_conv(x, far, p)


def test_field_conv_refuses_a_bad_recorded_unit():
    nb = geodesic_knn_neighborhood(*grid(3), k=4, scale="mean_edge")._replace(
        log_unit=np.asarray(-1.0)
    )
    x, p = _conv_inputs(nb)
    with pytest.raises(InputError, match="log_unit"):
        field_conv(x, to_jax(nb, jnp.float64), p)


def test_the_unit_changes_what_the_filters_see():
    """The issue's symptom: on a small mesh, zeroing the log maps hardly changes the output in mesh
    units, and changes it by order 1 at unit scale."""
    v, f = _small(icosphere(1), 0.01)
    x = jnp.asarray(np.random.default_rng(0).standard_normal((len(v), 2)) + 0j)
    p = init_field_conv(jax.random.key(1), 2, 3, hdim=8, dtype=jnp.complex128)
    conv = jax.jit(field_conv)

    def sensitivity(nb):
        nb = to_jax(nb, jnp.float64)
        y = conv(x, nb, p)
        y0 = conv(x, nb._replace(log=jnp.zeros_like(nb.log)), p)
        return float(jnp.linalg.norm(y - y0) / jnp.linalg.norm(y))

    assert sensitivity(geodesic_knn_neighborhood(v, f, k=6, scale=None)) < 0.1
    assert sensitivity(geodesic_knn_neighborhood(v, f, k=6, scale="mean_edge")) > 0.3


def test_vertex_neighborhood_still_builds_positionally():
    nb = VertexNeighborhood(
        np.zeros((1, 1), np.int32),
        np.ones((1, 1), bool),
        np.zeros((1, 1), complex),
        np.ones((1, 1), complex),
        np.ones((1, 1)),
        np.ones(1),
        np.ones(1, bool),
    )
    assert nb.log_unit is None and len(jax.tree.leaves(nb)) == 7

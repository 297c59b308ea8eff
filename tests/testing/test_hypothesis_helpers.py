"""Property tests of jitted ops that reuse compiled code: shape buckets and the shipped profile."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings

from jmeshtex import InputError
from jmeshtex.data import grid
from jmeshtex.geometry import one_ring_neighborhood
from jmeshtex.ops import field_conv, init_field_conv
from jmeshtex.testing import bucket, hypothesis_profile, pad_rows, pad_to_bucket, valid_meshes

_PARAMS = init_field_conv(jax.random.key(0), 2, 3, hdim=4)


@jax.jit
def _conv(x, nbhd):
    return field_conv(x, nbhd, _PARAMS)


@settings(hypothesis_profile(max_examples=6, load=False))
@given(mesh=valid_meshes(kinds=("grid", "delaunay"), min_vertices=33, max_vertices=64))
def test_meshes_of_one_bucket_share_one_compilation_and_match_a_wider_bucket(mesh):
    nb = one_ring_neighborhood(mesh.vertices, mesh.faces)
    V = len(mesh.vertices)
    x = np.random.default_rng(V).standard_normal((V, 2)) * (1 + 1j)
    x = x.astype(np.complex64)
    padded = pad_to_bucket(nb)
    assert padded.index.shape[0] == 64 and padded.index.shape[1] == bucket(nb.index.shape[1])
    before = _conv._cache_size()
    out = _conv(pad_rows(x, 64), padded)[:V]
    # one compilation per slot bucket at most: vertex counts 33–64 all land in the 64-row bucket
    assert _conv._cache_size() - before <= 1
    # the padded slots are inert: a larger bucket gives the same rows
    wider = _conv(pad_rows(x, 128), pad_to_bucket(nb, minimum=128))[:V]
    np.testing.assert_allclose(out, wider, rtol=2e-5, atol=2e-5)


def test_meshes_of_different_sizes_in_one_bucket_compile_once():
    @jax.jit
    def conv(x, nbhd):
        return field_conv(x, nbhd, _PARAMS)

    shapes = set()
    for n in (5, 6, 7):  # grids of 36, 49 and 64 vertices, one-ring slots 6–7: one bucket each
        v, f = grid(n, n)
        nb = pad_to_bucket(one_ring_neighborhood(v, f))
        shapes.add(nb.index.shape)
        conv(pad_rows(np.ones((len(v), 2), np.complex64), 64), nb).block_until_ready()
    assert shapes == {(64, 8)} and conv._cache_size() == 1


def test_bad_sizes_are_typed_errors():
    with pytest.raises(InputError, match="non-negative integer"):
        bucket(-1)
    with pytest.raises(InputError, match="cannot shrink"):
        pad_rows(jnp.ones((5, 2)), 4)
    with pytest.raises(InputError, match="not a neighbourhood pytree"):
        pad_to_bucket(np.ones(3))
    with pytest.raises(InputError, match="max_examples must be ≥ 1"):
        hypothesis_profile(max_examples=0, load=False)

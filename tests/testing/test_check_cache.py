"""The registry runner's cache: one compilation per entry, dtype and mesh shape, the same results
as the operator run eagerly, geometry shared between states of the same mesh."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from jmeshtex.data import icosahedron
from jmeshtex.testing import (
    CATALOGUE,
    CheckCache,
    Entry,
    Field,
    MeshState,
    check,
    load_entries,
    random_inputs,
)

REGISTRY = load_entries()


def test_every_exact_transform_of_a_mesh_reuses_one_compilation():
    cache = CheckCache()
    entry = REGISTRY["ops.field_conv"]
    for t in ("rigid", "gauge", "permute_vertices", "permute_faces", "rotate_corners"):
        assert check(entry, t, dtype=jnp.float64, cache=cache).passed, t
    assert cache.eager == {}
    # one trace per sample mesh (closed and open), shared by the source and target of every draw
    assert len(cache._kinds) == 2, list(cache._kinds)
    # and the geometry it reads was found once: every later state had it built without a trace
    assert cache.probes == 1


def test_compiled_operator_matches_the_eager_one():
    entry = REGISTRY["ops.field_conv_emb"]
    state = MeshState(*icosahedron())
    rng = np.random.default_rng(0)
    inputs = {k: jnp.asarray(f.value) for k, f in random_inputs(entry.inputs, state, rng).items()}
    cache = CheckCache()
    params = cache.params(entry, jnp.float64, 0)
    compiled = cache.apply(entry, state, params, inputs)
    eager = entry.apply(MeshState(*icosahedron()), params, **inputs)
    assert cache.eager == {} and compiled.kind == eager.kind
    np.testing.assert_allclose(np.asarray(compiled.value), np.asarray(eager.value), rtol=1e-12)


def test_an_operator_with_host_code_on_its_inputs_runs_eagerly():
    entry = REGISTRY["surfacecnn.first_layer"]  # traces taps from the input direction on the host
    result = check(entry, "rigid", dtype=jnp.float64, cache=(cache := CheckCache()))
    assert result.passed and "surfacecnn.first_layer" in cache.eager


def test_states_of_one_mesh_share_geometry_and_host_geometry_is_shared_across_dtypes():
    cache = CheckCache()
    v, f = icosahedron()
    a = cache.share(MeshState(v, f))
    knn = a.knn(8)
    b = cache.share(MeshState(v.copy(), f.copy()))
    assert b.knn(8) is knn
    c = cache.share(MeshState(v, f, dtype=jnp.float32))
    assert c.host_knn(8) is a.host_knn(8) and c.knn(8).log.dtype == jnp.complex64
    moved = CATALOGUE["gauge"].draw(np.random.default_rng(0), a).target
    assert cache.share(moved).host_knn(8) is not a.host_knn(8)  # another gauge, other log maps


def _size_dependent(state, params, x):
    """Reads k = 6 neighbours on meshes of over 100 vertices, 8 on smaller ones."""
    nb = state.knn(6 if state.num_vertices > 100 else 8)
    w = jnp.where(nb.mask, nb.transport, 0).astype(x.dtype)  # real zero on padding, strict dtypes
    return Field("vertex_tangent", jnp.sum(w[..., None] * x[nb.index], axis=1))


def test_an_operator_that_reads_other_geometry_on_another_mesh_is_traced_again_not_run_eagerly():
    entry = Entry("test.size_dependent", _size_dependent, {"x": ("vertex_tangent", 2)}, ("rigid",))
    cache = CheckCache()
    result = check(entry, "rigid", dtype=jnp.float64, cache=cache)  # the closed (162) and open mesh
    assert result.passed and cache.eager == {}
    assert cache.probes == 2  # the second mesh's replayed keys were missing: traced once more

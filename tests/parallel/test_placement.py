"""jmeshtex.parallel: meshes, placement and the data-parallel step. Multi-device checks run in a
subprocess with 4 forced host devices (the suite keeps one device)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import jax
import numpy as np
import pytest

from jmeshtex import ConfigError, InputError, parallel

FOUR_DEVICES = textwrap.dedent("""
    import jax, jax.numpy as jnp, numpy as np
    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_numpy_dtype_promotion", "strict")
    from jmeshtex import parallel

    assert len(jax.devices()) == 4
    mesh = parallel.data_mesh()
    rng = np.random.default_rng(0)
    w, x, y = rng.normal(size=(3, 2)), rng.normal(size=(8, 3)), rng.normal(size=(8, 2))

    def loss(w, batch):
        return jnp.mean((batch["x"] @ w - batch["y"]) ** 2)

    batch = parallel.shard_batch({"x": x, "y": y}, mesh)
    # each device holds 2 of the 8 rows, in order
    assert [s.data.shape for s in batch["x"].addressable_shards] == [(2, 3)] * 4
    np.testing.assert_array_equal(batch["x"].addressable_shards[1].data, x[2:4])
    step = parallel.data_parallel(jax.value_and_grad(loss), mesh, batch_argnums=(1,))
    value, grad = step(w, batch)
    assert grad.sharding.is_fully_replicated and len(grad.sharding.device_set) == 4
    want_value, want_grad = jax.value_and_grad(loss)(w, {"x": x, "y": y})
    np.testing.assert_allclose(value, want_value, rtol=1e-12)
    np.testing.assert_allclose(grad, want_grad, rtol=1e-12)
    # XLA put a cross-device reduction in the program: no hand-written collective anywhere
    hlo = step.jitted.lower(parallel.replicate(w, mesh), batch).compile().as_text()
    assert "all-reduce" in hlo, hlo[:2000]
    # replicate leaves placed leaves alone; keys are replicated as keys
    rw = parallel.replicate(w, mesh)
    assert parallel.replicate(rw, mesh) is rw
    key = parallel.replicate(jax.random.key(3), mesh)
    assert jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key) and key.sharding.is_fully_replicated
    assert parallel.fetch(batch)["x"].tolist() == x.tolist()
    from jmeshtex import InputError
    try:
        parallel.shard_batch(np.zeros((6, 3)), mesh)  # 6 rows cannot be cut into 4 equal slices
    except InputError as err:
        assert "equal slices" in str(err)
    else:
        raise AssertionError("6 rows split over 4 devices")
    print("ok")
""")


def test_four_devices_split_the_batch_and_xla_reduces_the_gradient():
    env = dict(
        os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4", JAX_PLATFORMS="cpu"
    )
    run = subprocess.run(
        [sys.executable, "-c", FOUR_DEVICES], env=env, capture_output=True, text=True, timeout=300
    )
    assert run.returncode == 0 and run.stdout.strip().endswith("ok"), run.stderr[-4000:]


def test_one_device_mesh_and_errors():
    mesh = parallel.data_mesh()
    assert mesh.axis_names == (parallel.DATA_AXIS,) and parallel.batch_multiple(mesh) == len(
        jax.devices()
    )
    assert parallel.resolve_mesh(mesh) is mesh
    with pytest.raises(ConfigError):
        parallel.data_mesh([])
    with pytest.raises(ConfigError):
        parallel.data_mesh([jax.devices()[0]] * 2)
    with pytest.raises(ConfigError):
        parallel.resolve_mesh(mesh, jax.devices())
    with pytest.raises(ConfigError):
        parallel.resolve_mesh(jax.sharding.Mesh(np.array(jax.devices()), ("model",)))
    with pytest.raises(InputError):
        parallel.shard_batch({"x": np.float32(1.0)}, mesh)  # no leading axis
    with pytest.raises(ConfigError):
        parallel.initialize("127.0.0.1:1", 1, 0, cpu_collectives="nccl-on-cpu")
    assert not parallel.is_multiprocess()


def test_a_step_fed_its_own_outputs_compiles_once():
    """An array already on the mesh's one device is relabelled with the mesh's sharding: the
    sharding is part of jit's cache key, and without it the second call of a data-parallel step
    (fed the replicated outputs of the first) traced and compiled the step again (it doubled every
    FLDM training's compile time)."""
    import jax.numpy as jnp

    mesh = parallel.data_mesh(jax.devices()[:1])
    w = jnp.ones(3)  # a plain one-device array, as initialisers return
    placed = parallel.replicate({"w": w}, mesh)["w"]
    assert placed.sharding == parallel.replicated(mesh)
    assert parallel.replicate(placed, mesh) is placed  # already so: no copy
    step = parallel.data_parallel(lambda w, x: w - x.mean(0), mesh, batch_argnums=(1,))
    x = np.ones((1, 3))
    w = step(step(w, x), x)
    np.testing.assert_allclose(np.asarray(w), -1.0)
    assert step.jitted._cache_size() == 1

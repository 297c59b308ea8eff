"""Placing pytrees on a data mesh (batch split, everything else replicated) and the jitted step."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding

from .._errors import InputError
from .._jit import loop_options
from ._mesh import DATA_AXIS, batch_multiple, batch_sharding, replicated


def _place(x: Any, sharding: NamedSharding) -> Any:
    """One leaf as a (global) :class:`jax.Array` with ``sharding``; Python scalars stay as they are."""
    if isinstance(x, (bool, int, float, complex)):
        return x
    if isinstance(x, jax.Array) and jnp.issubdtype(x.dtype, jax.dtypes.prng_key):
        return jax.random.wrap_key_data(
            _place(jax.random.key_data(x), sharding), impl=jax.random.key_impl(x)
        )
    if isinstance(x, jax.Array):
        if x.sharding == sharding:
            return x
        # XLA moves a global array laid out differently, and relabels one of the same layout but
        # another sharding (a one-device array on a one-device mesh): the sharding is part of
        # jit's cache key, so a step fed its own outputs would otherwise compile a second time
        if not x.is_fully_addressable or x.sharding.is_equivalent_to(sharding, x.ndim):
            return jax.device_put(x, sharding)
    host = np.asarray(x)
    # every process holds the whole (global) value; each device takes its slice of it
    return jax.make_array_from_callback(host.shape, sharding, lambda index: host[index])


def shard_batch(batch: Any, mesh: Mesh) -> Any:
    """Split every leaf of ``batch`` along its leading axis over the mesh's ``"data"`` axis.

    Every process passes the same global batch (host arrays); each device receives only its
    contiguous slice ``[i·N/D, (i+1)·N/D)``.

    Args:
      batch: pytree of arrays with a common leading size ``N`` (NumPy or JAX).
      mesh: from :func:`~jmeshtex.parallel.data_mesh`.

    Returns:
      The same pytree of global :class:`jax.Array` with
      :func:`~jmeshtex.parallel.batch_sharding`.

    Raises:
      InputError: a leaf without a leading axis, or ``N`` not a multiple of the device count.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.parallel import data_mesh
      >>> shard_batch(np.zeros((4 * len(jax.devices()), 3)), data_mesh()).sharding.spec
      P('data',)
    """
    d = batch_multiple(mesh)
    sharding = batch_sharding(mesh)

    def leaf(x):
        shape = np.shape(x)
        if not shape or shape[0] % d:
            raise InputError(
                f"shard_batch: a leaf of shape {shape} cannot be split into {d} equal slices "
                f"along its leading axis (pad the batch to a multiple of {d})"
            )
        return _place(x, sharding)

    return jax.tree.map(leaf, batch)


def replicate(tree: Any, mesh: Mesh) -> Any:
    """A full copy of every leaf on every device of ``mesh`` (parameters, optimiser state, keys).

    Leaves already laid out so are returned unchanged (no copy), so calling this every step is cheap.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.parallel import data_mesh
      >>> replicate({"w": np.ones(3)}, data_mesh())["w"].sharding.is_fully_replicated
      True
    """
    sharding = replicated(mesh)
    return jax.tree.map(lambda x: _place(x, sharding), tree)


def fetch(tree: Any) -> Any:
    """Host NumPy copies of (replicated or sharded) arrays, on every process.

    Example:
      >>> import jax.numpy as jnp
      >>> fetch({"w": jnp.ones(2)})["w"].tolist()
      [1.0, 1.0]
    """

    def leaf(x):
        if not isinstance(x, jax.Array) or x.is_fully_addressable:
            return np.asarray(x)
        if x.is_fully_replicated:
            return np.asarray(x.addressable_data(0))
        from jax.experimental import multihost_utils

        return np.asarray(multihost_utils.process_allgather(x, tiled=True))

    return jax.tree.map(leaf, tree)


def data_parallel(
    fn: Callable,
    mesh: Mesh,
    *,
    batch_argnums: Sequence[int],
    donate_argnums: Sequence[int] = (),
    out_shardings: Any = None,
) -> Callable:
    """``jax.jit(fn)`` as a data-parallel step: batch arguments split, the rest replicated.

    The arguments at ``batch_argnums`` are placed with :func:`shard_batch`, every other array
    argument with :func:`replicate`; the outputs are replicated (``out_shardings`` overrides).
    With parameters in and out replicated and the batch split, XLA's partitioner computes the
    per-device gradients and all-reduces them over ``"data"`` where ``fn`` sums over the batch;
    the result equals the one-device step up to the order of floating-point sums.

    Args:
      fn: the step, a pure function of arrays (pytrees).
      mesh: from :func:`~jmeshtex.parallel.data_mesh` (any mesh with a ``"data"`` axis).
      batch_argnums: positions of the batch arguments (leading axis split over ``"data"``).
      donate_argnums: passed to :func:`jax.jit` (e.g. parameters and optimiser state).
      out_shardings: None (all outputs replicated) or :func:`jax.jit`'s ``out_shardings``.

    Returns:
      A callable with ``fn``'s signature; arguments may be host arrays or placed arrays.

    Example:
      >>> import jax.numpy as jnp, numpy as np
      >>> from jmeshtex.parallel import data_mesh
      >>> mesh = data_mesh()
      >>> grad = data_parallel(jax.grad(lambda w, x: jnp.sum((x @ w) ** 2)), mesh, batch_argnums=(1,))
      >>> x = np.ones((2 * mesh.size, 3))
      >>> bool(np.allclose(grad(np.ones(3), x), jax.grad(lambda w: jnp.sum((x @ w) ** 2))(np.ones(3))))
      True
    """
    if DATA_AXIS not in mesh.axis_names:
        raise InputError(
            f"data_parallel needs a mesh with a {DATA_AXIS!r} axis, got {mesh.axis_names}"
        )
    batch_argnums = tuple(int(i) for i in batch_argnums)
    jitted = jax.jit(  # a step runs in a loop: the process's loop options (`jmeshtex._jit`)
        fn,
        compiler_options=loop_options(),
        out_shardings=replicated(mesh) if out_shardings is None else out_shardings,
        donate_argnums=tuple(donate_argnums),
    )

    def step(*args):
        placed = [
            shard_batch(a, mesh) if i in batch_argnums else replicate(a, mesh)
            for i, a in enumerate(args)
        ]
        return jitted(*placed)

    step.jitted = jitted
    return step

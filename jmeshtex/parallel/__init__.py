"""Data parallelism on :mod:`jax.sharding`: one device, many devices, many processes, the same code.

A training loop takes a :class:`jax.sharding.Mesh` with one axis, ``"data"`` (default
:func:`data_mesh`: every device JAX sees). Its batch arrays are split along their leading axis over
that axis (:func:`batch_sharding`, :func:`shard_batch`); parameters and optimiser state are
replicated on every device (:func:`replicated`, :func:`replicate`). The step is one
:func:`jax.jit` with those shardings as ``in_shardings``/``out_shardings``
(:func:`data_parallel`): XLA partitions the computation and inserts the reduction of the gradients
(an all-reduce over the mesh) itself; there is no hand-written collective.

Many processes (the multi-host path of JAX): start one process per host (or per group of local
devices) with the same script and call :func:`initialize` first, before anything touches a device.
:func:`data_mesh` then spans the devices of all processes; every process builds the same *global*
batch on the host (from the same key) and :func:`shard_batch` hands each process's devices their
slices. On CPU the collectives go through gloo (``jax_cpu_collectives_implementation``).

Example (two processes on one machine; run each with its ``process_id``)::

    from jmeshtex import parallel, fl
    parallel.initialize("127.0.0.1:12355", num_processes=2, process_id=PID)
    result = fl.train(None, config, key=jax.random.key(0))   # the batch is split over both processes

Example:
  >>> import jax, numpy as np
  >>> mesh = data_mesh()
  >>> mesh.axis_names, mesh.size == len(jax.devices())
  (('data',), True)
  >>> batch = shard_batch({"x": np.ones(4 * mesh.size)}, mesh)
  >>> step = data_parallel(lambda w, b: (w * b["x"]).sum(), mesh, batch_argnums=(1,))
  >>> batch["x"].sharding.spec, float(step(2.0, batch)) == 8.0 * mesh.size
  (P('data',), True)
"""

from ._distributed import initialize as initialize
from ._distributed import is_multiprocess as is_multiprocess
from ._mesh import DATA_AXIS as DATA_AXIS
from ._mesh import batch_multiple as batch_multiple
from ._mesh import batch_sharding as batch_sharding
from ._mesh import data_mesh as data_mesh
from ._mesh import local_mesh as local_mesh
from ._mesh import replicated as replicated
from ._mesh import resolve_mesh as resolve_mesh
from ._placement import data_parallel as data_parallel
from ._placement import fetch as fetch
from ._placement import replicate as replicate
from ._placement import shard_batch as shard_batch

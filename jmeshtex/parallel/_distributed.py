"""Many processes: :func:`initialize` wraps :func:`jax.distributed.initialize` (CPU collectives: gloo)."""

from __future__ import annotations

import jax

from .._errors import ConfigError

#: CPU collective back-ends of jaxlib (``jax_cpu_collectives_implementation``)
CPU_COLLECTIVES = ("gloo", "mpi")


def initialize(
    coordinator_address: str | None = None,
    num_processes: int | None = None,
    process_id: int | None = None,
    *,
    local_device_ids=None,
    cpu_collectives: str | None = "gloo",
    **kwargs,
) -> None:
    """Join a multi-process JAX run; call it first in every process, before any device is used.

    After it, :func:`jax.devices` (and so :func:`~jmeshtex.parallel.data_mesh`, the default of
    every ``train(..., device_mesh=None)``) spans the devices of every process, and a jitted step over a
    :func:`~jmeshtex.parallel.batch_sharding` runs as one program whose gradient all-reduce
    crosses processes. On a cluster manager that JAX detects (SLURM, Open MPI, Cloud TPU) the
    three arguments may be left out.

    Args:
      coordinator_address: ``"host:port"`` of process 0's coordination service.
      num_processes: how many processes take part.
      process_id: this process's rank, ``0 .. num_processes-1``.
      local_device_ids: the local devices this process uses (default: all).
      cpu_collectives: the collective back-end for CPU devices (``"gloo"``, or ``"mpi"`` with an
        MPI library); None leaves JAX's setting alone. CPU devices have no cross-process
        collectives without one.
      kwargs: passed on to :func:`jax.distributed.initialize` (e.g. ``initialization_timeout``).

    Raises:
      ConfigError: an unknown ``cpu_collectives``, or this jaxlib has no such back-end (the
        message quotes JAX's error).

    Example (two processes on one machine; the second runs with ``process_id=1``)::

        from jmeshtex import parallel
        parallel.initialize("127.0.0.1:12355", num_processes=2, process_id=0)
    """
    if cpu_collectives is not None:
        if cpu_collectives not in CPU_COLLECTIVES:
            raise ConfigError(
                f"cpu_collectives must be one of {CPU_COLLECTIVES} or None, got {cpu_collectives!r}"
            )
        try:
            jax.config.update("jax_cpu_collectives_implementation", cpu_collectives)
        except (AttributeError, ValueError) as err:
            raise ConfigError(
                f"this jax {jax.__version__} has no CPU collectives {cpu_collectives!r}: {err}"
            ) from err
    jax.distributed.initialize(
        coordinator_address, num_processes, process_id, local_device_ids=local_device_ids, **kwargs
    )


def is_multiprocess() -> bool:
    """True when this process is one of several (:func:`initialize` was called with ``num_processes > 1``).

    Example:
      >>> is_multiprocess()
      False
    """
    return jax.process_count() > 1

"""Device meshes with one ``"data"`` axis and the two shardings a data-parallel loop needs."""

from __future__ import annotations

from collections.abc import Sequence

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from .._errors import ConfigError

#: the name of the batch axis of every mesh made here
DATA_AXIS = "data"


def data_mesh(devices: Sequence[jax.Device] | None = None) -> Mesh:
    """A one-axis mesh (``"data"``) over ``devices``; by default every device of every process.

    In one process :func:`jax.devices` are the local devices (one CPU, or every local GPU); after
    :func:`~jmeshtex.parallel.initialize` they are the devices of all processes, ordered by process.

    Args:
      devices: the devices to split the batch over (None: :func:`jax.devices`).

    Returns:
      :class:`jax.sharding.Mesh` with axis names ``("data",)``.

    Raises:
      ConfigError: an empty device list, or repeated devices.

    Example:
      >>> import jax
      >>> dict(data_mesh(jax.devices()[:1]).shape)
      {'data': 1}
    """
    devices = list(jax.devices() if devices is None else devices)
    if not devices:
        raise ConfigError("data_mesh needs at least one device")
    if len({d.id for d in devices}) != len(devices):
        raise ConfigError(f"data_mesh: repeated devices in {devices}")
    return Mesh(np.array(devices, dtype=object), (DATA_AXIS,))


def local_mesh() -> Mesh:
    """A one-axis mesh over this process's own devices (:func:`jax.local_devices`) only.

    Example:
      >>> local_mesh().size == len(jax.local_devices())
      True
    """
    return data_mesh(jax.local_devices())


def resolve_mesh(mesh: Mesh | None = None, devices: Sequence[jax.Device] | None = None) -> Mesh:
    """The mesh a training loop runs on: ``mesh``, else :func:`data_mesh` over ``devices``.

    Args:
      mesh: a :class:`jax.sharding.Mesh` with a ``"data"`` axis (other axes, if any, replicate).
      devices: used when ``mesh`` is None (None: every device).

    Raises:
      ConfigError: both given, or a mesh without a ``"data"`` axis.

    Example:
      >>> resolve_mesh().axis_names
      ('data',)
    """
    if mesh is not None and devices is not None:
        raise ConfigError("give a mesh or devices, not both")
    if mesh is None:
        return data_mesh(devices)
    if not isinstance(mesh, Mesh) or DATA_AXIS not in mesh.axis_names:
        raise ConfigError(
            f"mesh must be a jax.sharding.Mesh with a {DATA_AXIS!r} axis, got {mesh!r}"
        )
    return mesh


def batch_multiple(mesh: Mesh) -> int:
    """How many slices the batch axis is cut into: the batch's leading size must be a multiple of it.

    Example:
      >>> batch_multiple(data_mesh()) == len(jax.devices())
      True
    """
    return int(mesh.shape[DATA_AXIS])


def batch_sharding(mesh: Mesh) -> NamedSharding:
    """Split the leading (batch) axis of an array over the mesh's ``"data"`` axis; other axes whole.

    Example:
      >>> batch_sharding(data_mesh()).spec
      P('data',)
    """
    return NamedSharding(mesh, PartitionSpec(DATA_AXIS))


def replicated(mesh: Mesh) -> NamedSharding:
    """A full copy on every device of the mesh (parameters, optimiser state, keys, scalars).

    Example:
      >>> replicated(data_mesh()).spec
      P()
    """
    return NamedSharding(mesh, PartitionSpec())

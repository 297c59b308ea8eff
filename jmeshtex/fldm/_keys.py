"""Host-side randomness from a JAX key: the NumPy seeds of re-triangulations and batch draws.

Every random choice of FLDM derives from the ``key`` its function is given. Device-side draws use
:mod:`jax.random` directly; host-side ones (which copies form a batch, the seed of
:func:`jmeshtex.geometry.remesh`) use a NumPy generator seeded from the key's data and a few integers,
so they are reproducible and independent across keys without a device round trip per draw.
"""

from __future__ import annotations

import jax
import numpy as np


def key_ints(key: jax.Array) -> list[int]:
    """The words of a PRNG key (typed ``jax.random.key`` or raw ``uint32`` key data) as Python ints.

    Example:
      >>> key_ints(jax.random.key(7))
      [0, 7]
    """
    if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key):
        key = jax.random.key_data(key)
    return [int(x) for x in np.asarray(key).reshape(-1)]


def host_seed(key: jax.Array, *ints: int) -> int:
    """A 32-bit NumPy seed that is a function of ``key`` and ``ints`` (e.g. a copy index).

    Example:
      >>> k = jax.random.key(0)
      >>> host_seed(k, 1) == host_seed(k, 1) != host_seed(k, 2)
      True
    """
    return int(np.random.SeedSequence([*key_ints(key), *(int(i) for i in ints)]).generate_state(1)[0])


def host_rng(key: jax.Array, *ints: int) -> np.random.Generator:
    """A NumPy generator seeded from ``key`` and ``ints`` (e.g. a training step)."""
    return np.random.default_rng([*key_ints(key), *(int(i) for i in ints)])

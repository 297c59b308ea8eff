"""Host-side randomness from a JAX key: one rule for every NumPy draw in the library.

Every random choice in jmeshtex derives from the ``key`` (a :func:`jax.random.key`) its function is
given; no function takes an integer seed. Device-side draws use :mod:`jax.random` directly;
host-side ones (the split positions of :func:`jmeshtex.geometry.remesh`, surface samples, which
copies form a batch) use a NumPy generator seeded from the key's data and a few integers, so they are
reproducible and independent across keys without a device round trip per draw.
"""

from __future__ import annotations

import jax
import numpy as np

from ._config import is_int


def check_key(key, what: str = "key") -> jax.Array:
    """``key`` if it is a JAX PRNG key (typed, or raw ``uint32[2]`` key data); else a typed error.

    Example:
      >>> check_key(7)
      Traceback (most recent call last):
      ...
      jmeshtex._errors.InputError: key must be a JAX PRNG key such as jax.random.key(7), got int
    """
    from ._errors import InputError

    ok = isinstance(key, jax.Array) and (
        jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key)
        or (key.dtype == np.uint32 and key.shape[-1:] == (2,))
    )
    if not ok:
        hint = f"jax.random.key({key})" if is_int(key) else "jax.random.key(0)"
        raise InputError(f"{what} must be a JAX PRNG key such as {hint}, got {type(key).__name__}")
    return key


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
    return int(
        np.random.SeedSequence([*key_ints(key), *(int(i) for i in ints)]).generate_state(1)[0]
    )


def host_rng(key: jax.Array, *ints: int) -> np.random.Generator:
    """A NumPy generator seeded from ``key`` and ``ints`` (e.g. a training step)."""
    return np.random.default_rng([*key_ints(key), *(int(i) for i in ints)])

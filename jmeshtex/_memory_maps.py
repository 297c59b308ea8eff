"""Keep a long-running process clear of the kernel's memory-mapping limit.

Every executable XLA:CPU compiles holds about 3 memory mappings (its JIT-linked code and data)
until JAX drops it from its caches. A process that compiles tens of thousands of programs — a test
worker, ``jmeshtex verify`` over the whole registry — passes the kernel's per-process limit
(``vm.max_map_count``, 65530 by default); LLVM's next mmap then fails ("LLVM compilation error:
Cannot allocate memory") and the compile crashes the process. :func:`release_if_near_limit` clears
JAX's compilation caches once the process nears that limit; callers run it between units of work.
On systems without ``/proc`` it does nothing.

Clearing the caches is process-wide, so only processes that own their whole lifetime call it: the
``jmeshtex verify`` command (``cli/_verify.py``, between two checks) and the test suite's workers
(``conftest.py``, after a test). No library function does.
"""

from __future__ import annotations

import gc
import pathlib

#: fraction of ``vm.max_map_count`` above which the caches are cleared
NEAR_LIMIT = 0.6


def max_memory_maps() -> int:
    """The kernel's per-process mapping limit (``vm.max_map_count``), 0 where it cannot be read."""
    try:
        return int(pathlib.Path("/proc/sys/vm/max_map_count").read_text())
    except (OSError, ValueError):
        return 0


def memory_maps() -> int:
    """How many memory mappings this process holds now, 0 where it cannot be read."""
    try:
        with open("/proc/self/maps", "rb") as f:
            return sum(1 for _ in f)
    except OSError:
        return 0


def release_if_near_limit(fraction: float = NEAR_LIMIT, *, limit: int | None = None) -> bool:
    """Clear JAX's compilation caches if this process holds over ``fraction · limit`` mappings.

    Args:
      fraction: the threshold, a fraction of the limit.
      limit: the mapping limit; default :func:`max_memory_maps` (nothing is done where it is 0).

    Returns:
      Whether the caches were cleared. Compiled functions recompile on their next call.

    Example:
      >>> release_if_near_limit(limit=0)
      False
      >>> release_if_near_limit(fraction=0.0, limit=1) == (memory_maps() > 0)
      True
    """
    limit = max_memory_maps() if limit is None else limit
    if not limit or memory_maps() <= fraction * limit:
        return False
    import jax

    jax.clear_caches()
    gc.collect()
    return True

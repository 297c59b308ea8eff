"""The test process itself stays healthy over a long run.

XLA:CPU keeps about three memory mappings per compiled executable (its JIT-linked code and data)
until JAX drops the executable from its caches. A test worker compiles tens of thousands of them; at
the kernel's per-process limit (``vm.max_map_count``) LLVM's next allocation fails ("LLVM compilation
error: Cannot allocate memory") and the compile segfaults, taking the worker down. The root
``conftest.py`` clears JAX's caches when a worker nears the limit; these tests check the two facts
that guard relies on.
"""

from __future__ import annotations

import gc
import pathlib

import jax
import jax.numpy as jnp
import pytest

_MAPS = pathlib.Path("/proc/self/maps")


def _maps() -> int:
    return len(_MAPS.read_bytes().splitlines())


pytestmark = pytest.mark.skipif(not _MAPS.exists(), reason="no /proc/self/maps (not Linux)")


def test_clearing_jax_caches_releases_the_mappings_of_compiled_executables():
    before = _maps()
    fns = [jax.jit(lambda x, i=i: jnp.sin(x) * i) for i in range(60)]
    for i, fn in enumerate(fns):
        fn(jnp.ones(i + 1)).block_until_ready()
    grown = _maps()
    assert grown - before >= 60, (before, grown)  # at least one mapping per executable
    jax.clear_caches()
    gc.collect()
    assert _maps() <= before + (grown - before) // 2, (before, grown, _maps())


def test_this_worker_is_below_the_guard_threshold():
    limit = pathlib.Path("/proc/sys/vm/max_map_count")
    if not limit.exists():
        pytest.skip("vm.max_map_count is not readable here")
    # the autouse fixture clears after any test that ends above 60 % of the limit, so no test starts
    # far above it: a worker this close to the kernel limit would crash on its next large compile
    assert _maps() < 0.9 * int(limit.read_text())

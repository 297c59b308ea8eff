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
    # earlier tests' executables are released first, and the collector stays off while this test's
    # compile: else collecting their garbage mid-loop can unmap more than the loop maps (a worker
    # once went from 23,864 mappings down to 23,513 while compiling 60 programs)
    jax.clear_caches()
    gc.collect()
    before = _maps()
    fns = [jax.jit(lambda x, i=i: jnp.sin(x) * i) for i in range(60)]
    gc.disable()
    try:
        for i, fn in enumerate(fns):
            fn(jnp.ones(i + 1)).block_until_ready()
        grown = _maps()
    finally:
        gc.enable()
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


def test_a_program_another_process_compiled_is_read_from_the_shared_cache():
    """One cache folder for every worker, with JAX's file lock on (a size limit turns it on): a
    program a second process compiles and writes is a cache hit here, not a second compilation."""
    import os
    import subprocess
    import sys
    import time

    import jax.monitoring

    if os.environ.get("JMESHTEX_TEST_JAX_CACHE", "").strip() == "0":
        pytest.skip("JMESHTEX_TEST_JAX_CACHE=0 turned the cache off for this run")
    folder = pathlib.Path(jax.config.jax_compilation_cache_dir)
    assert jax.config.jax_compilation_cache_max_size > 0  # eviction on: entries read under the lock
    unique = time.time_ns() % 10**9  # a program no run has compiled before
    program = f"jax.jit(lambda x: jnp.sin(x) * {unique}.0)(jnp.ones(3, jnp.float64))"
    other = (
        "import jax, jax.numpy as jnp; jax.config.update('jax_enable_x64', True); "
        f"jax.config.update('jax_compilation_cache_dir', {str(folder)!r}); "
        "jax.config.update('jax_compilation_cache_max_size', 8 << 30); "
        "jax.config.update('jax_persistent_cache_min_compile_time_secs', 0.0); "
        "jax.config.update('jax_persistent_cache_min_entry_size_bytes', 0); "
        f"{program}.block_until_ready()"
    )
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    subprocess.run([sys.executable, "-c", other], check=True, env=env, timeout=300)
    hits: list[str] = []
    listener = lambda event, **_: hits.append(event)  # noqa: E731
    jax.monitoring.register_event_listener(listener)
    threshold = jax.config.jax_persistent_cache_min_compile_time_secs
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    try:
        eval(program, {"jax": jax, "jnp": jnp}).block_until_ready()
    finally:
        jax.config.update("jax_persistent_cache_min_compile_time_secs", threshold)
        jax.monitoring.unregister_event_listener(listener)
    assert "/jax/compilation_cache/cache_hits" in hits, hits


def test_compiled_programs_are_written_to_the_shared_cache():
    import os
    import time

    if os.environ.get("JMESHTEX_TEST_JAX_CACHE", "").strip() == "0":
        pytest.skip("JMESHTEX_TEST_JAX_CACHE=0 turned the cache off for this run")
    folder = pathlib.Path(jax.config.jax_compilation_cache_dir)
    before = set(folder.iterdir())
    threshold = jax.config.jax_persistent_cache_min_compile_time_secs
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    try:
        unique = float(time.time_ns() % 10**9)  # a program this run has not compiled before
        jax.jit(lambda x: jnp.sin(x) * unique)(jnp.ones(3)).block_until_ready()
    finally:
        jax.config.update("jax_persistent_cache_min_compile_time_secs", threshold)
    assert set(folder.iterdir()) - before, f"nothing written to {folder}"


@pytest.fixture(scope="module")
def _built_once() -> int:
    return 1


def test_a_module_fixture_keeps_its_tests_on_one_worker(request, _built_once):
    marker = request.node.get_closest_marker("xdist_group")
    assert marker is not None and marker.args == ("tests/test_suite_health.py",), marker
    assert "loadgroup" in request.config.getini("addopts")  # pyproject: --dist loadgroup
    if getattr(request.config.option, "loadgroup", False):  # on an xdist worker: it schedules by
        # the node id's suffix (under pytest 9 the marker alone was ignored: conftest.py)
        assert request.node.nodeid.endswith("@tests/test_suite_health.py"), request.node.nodeid


def test_the_suite_budget_sums_cpu_time_per_folder():
    from benchmarks.suite import markdown, summarise

    records = [
        {"nodeid": "tests/io/test_a.py::t", "cpu_s": 1.5, "wall_s": 2.0, "compile_s": 1.25},
        {"nodeid": "tests/io/test_b.py::t", "cpu_s": 0.5, "wall_s": 1.0},  # an older record
        {"nodeid": "jmeshtex/ops/_x.py::jmeshtex.ops._x.f", "cpu_s": 3.0, "wall_s": 3.0},
    ]
    doc = summarise(records, wall_s=7.0, cpu_s=6.0, outcome={"tests": 3})
    assert doc["folders"]["tests/io"] == {
        "tests": 2,
        "cpu_s": 2.0,
        "wall_s": 3.0,
        "compile_s": 1.25,
    }
    assert list(doc["folders"]) == ["jmeshtex (doctests)", "tests/io"]  # by CPU time
    md = markdown(doc)
    assert "| tests/io | 2 | 2.0 | 3.0 | 1.2 |" in md
    assert "(tracing, lowering, XLA; wall s inside the tests): 1 s in all" in md

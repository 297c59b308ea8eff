"""Test configuration shared by `tests/`, `equivariance_tests/` and the doctests in `jmeshtex/`.

- numerics are strict: float64 is available (x64 on) so that float32 *and* float64 paths are tested,
  dtype promotion is strict (no silent float32 -> float64 upcasts), and NaNs raise at their source;
- every warning is an error (pyproject's ``filterwarnings``);
- signatures are checked at run time: jaxtyping + beartype instrument ``jmeshtex.ops`` and
  ``jmeshtex.geometry`` as they are imported (below, before anything imports jmeshtex), so a wrong
  shape, dtype or pytree between functions fails at the call, naming the argument. ``int`` passes
  for ``float`` (PEP 484's numeric tower). Tests marked ``unchecked`` switch the checks off, because
  they pass ill-typed arguments on purpose to test the typed errors the functions raise themselves;
  ``JMESHTEX_TYPECHECK=0`` switches them off for a whole run;
- BLAS runs one thread per test worker (the workers already use every core);
- XLA compiles at a quick optimisation level (``XLA_FLAGS`` level 1, not 0: see below); the programs
  that run once (``jmeshtex._jit.jit_once``) at the quickest (level 0, given per compilation); the
  programs that run in a loop (``jmeshtex._jit.jit_loop``, the training driver's steps,
  ``parallel.data_parallel``) at XLA's full level (``jmeshtex._jit.set_compiler_options``; the
  library alone leaves ``XLA_FLAGS`` in charge); ``JMESHTEX_TEST_XLA_FULL=1`` compiles everything
  fully. A test marked ``few_steps`` (its trainings run a handful of steps, so compiling them fully
  costs more than it saves) compiles the training steps it builds as the programs that run once;
- JAX's persistent compilation cache is on, in one folder all xdist workers share under a file
  lock (``.pytest_cache/jax``, ``JMESHTEX_TEST_JAX_CACHE`` moves it, ``0`` turns it off): a program
  is compiled once per run, not once per worker, and a second run skips most compilation;
- the tests of a session fixture that trains a model run on one xdist worker (``xdist_group`` set
  below, ``--dist loadgroup`` in pyproject), so each trained fixture is built once per run;
- a worker's JAX compilation caches are cleared when its memory mappings near the kernel's limit
  (``_bounded_memory_maps``, counted at most every 2 s; XLA:CPU segfaults compiling past it);
- the ``key`` fixture prints its seed; pin it with ``JMESHTEX_SEED=<int>`` to replay a failure;
- hypothesis has a reproducible ``ci`` profile (fixed example count, derandomised), selected when
  ``CI`` is set, and a longer ``dev`` profile otherwise (``HYPOTHESIS_PROFILE`` overrides both).
"""

from __future__ import annotations

import contextlib
import os
import pathlib
import random
import sys
import time

# XLA compiles every program at a quick optimisation level (read when JAX's backend starts, so set
# before anything runs; subprocesses inherit it): most of the suite's programs run once, and its
# compile-bound tests cost about 25 % less CPU (tests/ops: 148 -> 107 s, measured at level 0).
# Level 1, not 0: with ``XLA_FLAGS`` at level 0 jaxlib 0.10.2 computes wrong gradients
# (``jmeshtex._jit.FAST_COMPILE`` says what was measured). Programs that run in a loop (training steps, samplers:
# ``jmeshtex._jit.jit_loop`` and the training driver) get XLA's full optimisation back below (at
# level 0 an FLDM training step ran about 2.5x slower).
# ``JMESHTEX_TEST_XLA_FULL=1`` compiles everything fully.
if os.environ.get("JMESHTEX_TEST_XLA_FULL") != "1":
    os.environ["XLA_FLAGS"] = " ".join(
        [
            os.environ.get("XLA_FLAGS", ""),
            "--xla_backend_optimization_level=1",
            "--xla_llvm_disable_expensive_passes=true",
        ]
    ).strip()

if os.environ.get("JMESHTEX_TYPECHECK", "1") != "0":
    from jaxtyping import install_import_hook

    _CHECKED = ["jmeshtex.ops", "jmeshtex.geometry"]
    if any(
        name in sys.modules for name in _CHECKED
    ):  # the hook only sees modules imported after it
        raise RuntimeError(f"conftest.py: {_CHECKED} were imported before their type-check hook")
    install_import_hook(
        _CHECKED, "beartype.beartype(conf=beartype.BeartypeConf(is_pep484_tower=True))"
    )

import jax
import numpy as np
import pytest
from hypothesis import HealthCheck, settings
from threadpoolctl import threadpool_limits

jax.config.update("jax_enable_x64", True)

# the suite's trade-off, set before any module applies ``jit_loop`` / ``jit_once``: loops compile
# fully whatever ``XLA_FLAGS`` above say; programs that run once (``jit_once``: initialisers, the
# equivariance harness's checks) and the loops of ``few_steps`` tests compile at level 0, given per
# compilation. Level 0 per compilation is not the process-wide level 0 above: it computes DGTS's
# official gradients right (tests/dgts/test_official_training.py passes with every program at it)
# and costs about a third less compile CPU than level 1, which saves little over XLA's full level
# (an FLDM training step: 7.6 / 11.9 / 13.3 CPU-s at levels 0 / 1 / 3).
from jmeshtex._jit import FAST_COMPILE, FULL_OPTIMISATION, set_compiler_options  # noqa: E402

if os.environ.get("JMESHTEX_TEST_XLA_FULL") != "1":
    set_compiler_options(once=FAST_COMPILE, loop=FULL_OPTIMISATION)
jax.config.update("jax_numpy_dtype_promotion", "strict")
jax.config.update("jax_debug_nans", True)
# CPU unless JMESHTEX_TEST_PLATFORMS says otherwise (benchmarks/gpu_check.sh runs a subset on "cuda")
jax.config.update("jax_platforms", os.environ.get("JMESHTEX_TEST_PLATFORMS", "cpu"))

# pytest-xdist runs one worker per core; a multi-threaded BLAS in every worker oversubscribes the
# cores and slows sparse eigensolves (HKS) 8-20x. One BLAS thread per worker.
threadpool_limits(1)

# The CLI turns on JAX's persistent compilation cache in ~/.cache/jmeshtex/jax; tests that call the
# CLI in-process keep the suite's cache (below) and leave the user's folder alone.
os.environ["JMESHTEX_JAX_CACHE"] = "0"


def _cache_folder() -> pathlib.Path | None:
    """The persistent compilation cache folder every worker of every run shares (None: cache off).

    ``$JMESHTEX_TEST_JAX_CACHE`` (default ``.pytest_cache/jax`` under the repository; ``0`` turns it
    off). One folder for all processes: a program one xdist worker compiled is read by the other
    (JAX's cache key includes the folder, so separate folders never share an entry). A size limit
    turns on JAX's least-recently-used eviction, which reads and writes every entry under a file
    lock (``filelock``): a worker never reads an entry another is still writing.
    """
    env = os.environ.get("JMESHTEX_TEST_JAX_CACHE")
    if env is not None and env.strip() in ("", "0"):
        return None
    if env:
        return pathlib.Path(env)
    return pathlib.Path(__file__).resolve().parent / ".pytest_cache" / "jax"


_JAX_CACHE = _cache_folder()
if _JAX_CACHE is None:
    jax.config.update("jax_enable_compilation_cache", False)
else:
    import filelock  # noqa: F401  (jmeshtex[methods]'s; JAX locks the shared folder with it)

    _JAX_CACHE.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(_JAX_CACHE))
    jax.config.update("jax_compilation_cache_max_size", 8 << 30)  # bytes; turns the lock on
    # every program is kept, however quick to compile: the suite's thousands of small eager-op and
    # check programs are most of a warm run's compilation (two test files: warm 58 s with a 0.2 s
    # threshold, 23 s without). JAX's eviction would rescan the whole folder on every write, a cost
    # that grows with the entry count; the suite's folder stays far below the limit (about 0.2 GB),
    # so the rescan is replaced by nothing while the lock stays (a private JAX hook: fails loudly
    # at import if it moves).
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    from jax._src import lru_cache as _lru_cache

    _lru_cache.LRUCache._evict_if_needed = lambda self, additional_size=0: None

settings.register_profile(
    "ci",
    max_examples=20,
    derandomize=True,
    deadline=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.register_profile(
    "dev",
    max_examples=60,
    deadline=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci" if os.environ.get("CI") else "dev"))

_SEED_ENV = "JMESHTEX_SEED"


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "few_steps: its trainings run a few steps: the training steps it builds compile at the"
        " suite's quickest XLA level, not the loops' full one (conftest.py)",
    )


@contextlib.contextmanager
def _quick_level_loops():
    """Loop programs built inside compile as the suite's programs that run once."""
    before = set_compiler_options(loop=None)  # (sets both kinds: ``once`` is put back next)
    set_compiler_options(once=before["once"], loop=before["once"])
    try:
        yield
    finally:
        set_compiler_options(**before)


def _quick_level_if_marked(request: pytest.FixtureRequest):
    """The body of both ``few_steps`` fixtures: :func:`_quick_level_loops` around the marked."""
    if request.node.get_closest_marker("few_steps") is None:
        yield
        return
    with _quick_level_loops():
        yield


@pytest.fixture(autouse=True, scope="module")
def _few_step_module(request: pytest.FixtureRequest):
    """A module marked ``few_steps`` (``pytestmark``) builds its loop programs at the quickest level,
    its module fixtures' included (autouse: set up before them; session fixtures come first and
    keep the loops' full level). See :func:`_few_step_loops`."""
    yield from _quick_level_if_marked(request)


@pytest.fixture(autouse=True)
def _few_step_loops(request: pytest.FixtureRequest):
    """Tests marked ``few_steps`` build their loop programs as the programs that run once (level 0).

    The suite gives loop programs XLA's full optimisation because a training step at the quick
    level runs about 2.5x slower; a test whose trainings run a handful of steps pays the full
    level's longer compile and never earns it back. What such a test checks (a resumed run equals an
    uninterrupted one, a cache is keyed right, a flag reaches the step) compares programs compiled
    alike within the test. Only programs built during the test follow: the training driver's steps
    (``fit`` and ``parallel.data_parallel`` read the options when they compile), not the functions
    ``jit_loop`` decorated at import, nor a session fixture, nor a module fixture of an unmarked
    module.
    """
    yield from _quick_level_if_marked(request)


@pytest.fixture(autouse=True)
def _runtime_type_checks(request: pytest.FixtureRequest):
    """jaxtyping's run-time checks stay on, except for tests marked ``unchecked``."""
    if request.node.get_closest_marker("unchecked") is None:
        yield
        return
    import jaxtyping

    before = jaxtyping.config.jaxtyping_disable
    jaxtyping.config.update("jaxtyping_disable", True)
    try:
        yield
    finally:
        jaxtyping.config.update("jaxtyping_disable", before)


# Every executable XLA:CPU compiles holds ~3 memory mappings (its JIT-linked code and data) until
# JAX drops it from its caches. A test worker compiles tens of thousands of executables in one run;
# past the kernel's per-process limit (vm.max_map_count, 65530 by default) LLVM's next mmap fails
# and the compile segfaults (measured: a worker at ~60K mappings after ~18 min crashed compiling the
# FLDM sampler's scan; the count grows ~1K per 20 s). The caches are cleared once a worker nears it.
# (`jmeshtex._memory_maps`, which `jmeshtex verify` uses too).
#
# Doctest collection imports each module from its file. A submodule collected before its package
# was imported is executed twice (once by the package's own imports, once from the file), and state
# the package bound at import (``jmeshtex.testing.REGISTRY``) parts from the module's. Importing the
# packages that hold such state first makes collection find every module already imported.
import jmeshtex.testing  # noqa: E402, F401
from jmeshtex._memory_maps import release_if_near_limit  # noqa: E402

#: seconds between two counts of the worker's mappings: counting reads ``/proc/self/maps`` (measured
#: 3 ms of CPU at 5K mappings, 11 ms at 20K, 20 ms at 39K: over a minute of a run's 5,484 tests if
#: counted after each), while a worker adds about 1K mappings per 20 s, far below the ~26K between
#: the clearing threshold and the kernel's limit
_MAPS_CHECK_EVERY_S = 2.0
_maps_checked_at = [-float("inf")]


@pytest.fixture(autouse=True)
def _bounded_memory_maps():
    """Clear JAX's compilation caches after a test that leaves the worker near the mapping limit
    (counted at most every :data:`_MAPS_CHECK_EVERY_S` seconds)."""
    yield
    now = time.monotonic()
    if now - _maps_checked_at[0] >= _MAPS_CHECK_EVERY_S:
        _maps_checked_at[0] = now
        release_if_near_limit()


@pytest.fixture
def seed(request: pytest.FixtureRequest) -> int:
    """An integer seed, random per test unless ``JMESHTEX_SEED`` pins it; printed for replay."""
    value = int(os.environ.get(_SEED_ENV, random.SystemRandom().randrange(2**31)))
    print(f"[jmeshtex] {request.node.nodeid}: seed={value} (replay with {_SEED_ENV}={value})")
    request.node.user_properties.append(("seed", value))
    return value


@pytest.fixture
def key(seed: int) -> jax.Array:
    """A JAX PRNG key from the printed ``seed``."""
    return jax.random.key(seed)


@pytest.fixture
def rng(seed: int) -> np.random.Generator:
    """A NumPy generator from the printed ``seed`` (host-side geometry tests)."""
    return np.random.default_rng(seed)


def _shared_data_dir() -> pathlib.Path | None:
    env = os.environ.get("JMESHTEX_SHARED_DATA")
    candidates = [pathlib.Path(env)] if env else []
    here = pathlib.Path(__file__).resolve().parent
    candidates += [here.parent / "shared" / "data", here / ".." / "shared" / "data"]
    for c in candidates:
        if c.is_dir():
            return c.resolve()
    return None


@pytest.fixture(scope="session")
def shared_data() -> pathlib.Path:
    """``../shared/data`` (or ``$JMESHTEX_SHARED_DATA``); skips the test, with the reason, if absent."""
    path = _shared_data_dir()
    if path is None:
        pytest.skip("../shared/data is absent (set JMESHTEX_SHARED_DATA to point at it)")
    return path


def _fixture_group(item: pytest.Item) -> str | None:
    """The xdist group of a test that takes a session or module fixture defined under ``tests/``.

    A session fixture (a trained model in ``tests/<method>/conftest.py``) groups its tests by the
    folder that defines it, a module fixture by the module: with ``--dist loadgroup`` each is built
    on one worker only.
    """
    info = getattr(item, "_fixtureinfo", None)
    if info is None:
        return None
    group = None
    for name in item.fixturenames:
        defs = info.name2fixturedefs.get(name)
        if not defs or not defs[-1].baseid:
            continue
        scope = defs[-1].scope
        if scope == "session":
            return defs[-1].baseid.rstrip("/")
        if scope == "module":
            group = item.nodeid.split("::")[0]
    return group


def _carry_groups_into_node_ids(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Append ``@<group>`` to each grouped test's node id, as xdist does, where pytest 9 reads it.

    ``--dist loadgroup`` schedules by the suffix of the node ids a worker reports. xdist 3.8 writes
    it to ``item._nodeid``, which pytest 9 no longer reads (the id is ``item._id``), so every group
    was ignored and each session or module fixture was built on both workers (measured: the FLDM
    striped model trained twice, 50 s each). Under an older pytest xdist's own suffix works.
    """
    if not getattr(config.option, "loadgroup", False):  # set on xdist workers with loadgroup
        return
    try:
        from _pytest.nodeid import coerce_node_id
    except ImportError:  # pytest < 9: the node id is ``_nodeid``, which xdist suffixes itself
        return
    for item in items:
        names = {
            str(m.args[0] if m.args else m.kwargs.get("name", "default"))
            for m in item.iter_markers("xdist_group")
        }
        if names and "@" not in item.nodeid:
            item._id = coerce_node_id(f"{item.nodeid}@{'_'.join(sorted(names))}")


@pytest.hookimpl(tryfirst=True)  # before xdist's hook, which reads the groups
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if item.get_closest_marker("xdist_group") is None:
            group = _fixture_group(item)
            if group is not None:
                item.add_marker(pytest.mark.xdist_group(group))
    _carry_groups_into_node_ids(config, items)

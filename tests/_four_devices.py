"""The two halves of a data-parallel training test over 4 forced host devices: the parent starts a
fresh worker process (the rest of the suite keeps one device) and the worker compiles each program
once. Shared by ``tests/fl/test_train_sharded.py`` and ``tests/fldm/test_train_sharded.py``.
"""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import jax


def run_worker(worker: pathlib.Path, work: pathlib.Path) -> None:
    """Run the script ``worker`` on the work folder ``work`` in a fresh process with 4 forced host
    devices (the suite's ``XLA_FLAGS`` inherited) and fail with its stderr when it fails."""
    flags = f"{os.environ.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count=4"
    env = dict(os.environ, XLA_FLAGS=flags.strip(), JAX_PLATFORMS="cpu")
    run = subprocess.run(
        [sys.executable, str(worker), str(work)],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr[-4000:]


def compile_once(work: pathlib.Path) -> None:
    """A persistent compilation cache in the work folder: each ``train`` call jits its step afresh,
    so the worker's four trainings on four devices compile the step once, not four times (the same
    programs, read back: the same numbers)."""
    jax.config.update("jax_compilation_cache_dir", str(work / "jax_cache"))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)

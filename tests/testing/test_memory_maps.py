"""``jmeshtex verify`` keeps clear of vm.max_map_count: it releases JAX's compiled programs between
checks once the process nears the limit (a 16-entry run crashed with "LLVM
compilation error: Cannot allocate memory" before)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jmeshtex import _memory_maps
from jmeshtex.testing import run_registry


def test_verify_checks_the_limit_before_every_check(monkeypatch, capsys):
    from jmeshtex.cli import main

    calls = []
    monkeypatch.setattr(_memory_maps, "release_if_near_limit", lambda: calls.append(1) or False)
    argv = ["verify", "--only", "ops.complex_linear", "--transforms", "rigid", "gauge"]
    assert main([*argv, "--dtype", "float64", "--quiet"]) == 0
    assert len(calls) == 2 and "2 checks: 2 passed" in capsys.readouterr().out


def test_the_library_runner_leaves_process_state_alone(monkeypatch):
    """The guard belongs to long-running callers (``jmeshtex verify``, the test workers' conftest),
    not to the public runner: a user's process keeps its compiled programs."""
    cleared = []
    monkeypatch.setattr(jax, "clear_caches", lambda: cleared.append(1))
    monkeypatch.setattr(_memory_maps, "memory_maps", lambda: 10**9)
    results = run_registry(["ops.complex_linear"], transforms=["rigid"], dtypes=(jnp.float64,))
    assert len(results) == 1 and not cleared


def test_release_clears_the_caches_only_past_the_threshold(monkeypatch):
    cleared = []
    monkeypatch.setattr(jax, "clear_caches", lambda: cleared.append(1))
    monkeypatch.setattr(_memory_maps, "memory_maps", lambda: 700)
    assert (
        _memory_maps.release_if_near_limit(0.6, limit=2000) is False and not cleared
    )  # 700 <= 1200
    assert _memory_maps.release_if_near_limit(0.6, limit=1000) is True and cleared == [
        1
    ]  # 700 > 600
    assert _memory_maps.release_if_near_limit(0.6, limit=0) is False and cleared == [
        1
    ]  # limit unknown

"""The library's jit: plain :func:`jax.jit`, marked by how often a program runs.

:func:`jit_once` marks programs that run once or a few times on small inputs (parameter
initialisers, the equivariance harness's checks); :func:`jit_loop` marks programs that run in a
loop (training steps, samplers, texture optimisation; the training driver ``jmeshtex._training.fit``
compiles its steps as such). By default both *are* ``jax.jit(fun, **kwargs)``: the user's
``XLA_FLAGS`` and JAX settings decide how everything compiles, and nothing is checked per call.

A process that owns its compilation trade-off may give each kind its own XLA options with
:func:`set_compiler_options` *before* the modules that use these decorators are imported (they
decide when they are applied). The test suite does (``conftest.py``: it lowers XLA's optimisation
level for everything and keeps the loops at XLA's full level); the library itself never does.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping

import jax

#: XLA options that compile fast, given per compilation (both are plain ``DebugOptions``, valid on
#: every backend): level 0, about a third less compile CPU than level 1, which saves little over the
#: full level (an FLDM training step: 7.6 / 11.9 / 13.3 CPU-s at levels 0 / 1 / 3). Per compilation
#: only: with ``XLA_FLAGS`` at level 0, jaxlib 0.10.2's CPU backend computes wrong gradients (DGTS's
#: generator update: per-face cotangents 2-7 % off a float64 evaluation, where levels 1 and 3 agree
#: to 1e-6; ``tests/dgts/test_official_training.py`` caught it), while these options passed to
#: every program compute them right (that test passes)
FAST_COMPILE = {"xla_backend_optimization_level": 0, "xla_llvm_disable_expensive_passes": True}
#: XLA's own default, full optimisation (jaxlib 0.10), stated so that it can win over ``XLA_FLAGS``
FULL_OPTIMISATION = {
    "xla_backend_optimization_level": 3,
    "xla_llvm_disable_expensive_passes": False,
}

#: the process's XLA options per kind of program; None: plain ``jax.jit`` (the default)
_OPTIONS: dict[str, dict | None] = {"once": None, "loop": None}


def set_compiler_options(
    *, once: Mapping | None = None, loop: Mapping | None = None
) -> dict[str, dict | None]:
    """Give :func:`jit_once` / :func:`jit_loop` programs their own XLA options in this process.

    For a process owner (a test suite, a benchmark), never called by the library. Applies to
    functions decorated after the call; None restores plain ``jax.jit`` for that kind.

    Returns:
      The options before the call (to restore them).

    Example:
      >>> before = set_compiler_options(loop=FULL_OPTIMISATION)
      >>> loop_options() == FULL_OPTIMISATION
      True
      >>> _ = set_compiler_options(**before)
    """
    before = dict(_OPTIONS)
    _OPTIONS.update(once=None if once is None else dict(once))
    _OPTIONS.update(loop=None if loop is None else dict(loop))
    return before


def loop_options() -> dict | None:
    """The XLA options of loop programs in this process (None: ``XLA_FLAGS`` decide); the training
    driver passes them to its ahead-of-time compiles."""
    return _OPTIONS["loop"]


def _jit(kind: str, fun, kwargs: dict):
    """``jax.jit(fun, **kwargs)``; with options set for ``kind``, compiled with them when called at
    top level (JAX takes compiler options on a top-level call only: called with traced arguments,
    inside another ``jit``, ``grad`` or ``vmap``, it is the plain ``jax.jit`` one)."""
    options = _OPTIONS[kind]
    plain = jax.jit(fun, **kwargs)
    if options is None:
        return plain
    tuned = jax.jit(fun, compiler_options=options, **kwargs)

    @functools.wraps(fun)
    def call(*args, **kw):
        traced = any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves((args, kw)))
        return (plain if traced else tuned)(*args, **kw)

    call.lower = tuned.lower  # type: ignore[attr-defined]
    return call


def jit_once(fun=None, /, **kwargs):
    """:func:`jax.jit` of a program that runs once or a few times; use as ``jit_once(f, ...)`` or a
    decorator (``@jit_once`` or ``@jit_once(static_argnums=...)``)."""
    if fun is None:
        return functools.partial(jit_once, **kwargs)
    return _jit("once", fun, kwargs)


def jit_loop(fun=None, /, **kwargs):
    """:func:`jax.jit` of a program that runs in a loop; use as ``jit_loop(f, ...)`` or a decorator
    (``@jit_loop`` or ``@jit_loop(static_argnames=...)``)."""
    if fun is None:
        return functools.partial(jit_loop, **kwargs)
    return _jit("loop", fun, kwargs)

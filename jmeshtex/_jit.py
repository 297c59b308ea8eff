"""How long XLA may spend optimising a program: by how often it runs.

- :func:`jit_once`: programs that run once or a few times on small inputs (parameter initialisers,
  the equivariance harness's checks) compile at XLA's lowest optimisation level, where its passes
  cost more than they save: an FLDM denoiser's initialiser (64 random draws) compiles in about half
  the time (measured: 9.2 → 3.8 s on a loaded 2-core machine) and still runs in milliseconds.
- :func:`jit_loop`: programs that run in a loop (training steps, samplers, texture optimisation)
  compile at XLA's default, full optimisation (:data:`FULL_OPTIMISATION`) *whatever* ``XLA_FLAGS``
  say, so a process that lowers XLA's level for everything else (the test suite does) keeps its
  loops fast: at the lowest level an FLDM training step runs about 2.5× slower. The one training
  driver (``jmeshtex._training.fit``) compiles every method's step with the same options.

Everything else keeps plain :func:`jax.jit`, so ``XLA_FLAGS`` decide.
"""

from __future__ import annotations

import functools

import jax

#: XLA options of :func:`jit_once` (both are plain ``DebugOptions``, valid on every backend)
FAST_COMPILE = {"xla_backend_optimization_level": 0, "xla_llvm_disable_expensive_passes": True}
#: XLA options of :func:`jit_loop`: XLA's own defaults (jaxlib 0.10), stated so that they win over
#: ``XLA_FLAGS``
FULL_OPTIMISATION = {
    "xla_backend_optimization_level": 3,
    "xla_llvm_disable_expensive_passes": False,
}


def _jit_with(options: dict, fun, kwargs: dict):
    """``jax.jit(fun, **kwargs)`` compiled with ``options`` when called at top level.

    JAX takes compiler options on a top-level call only: called with traced arguments (inside
    another ``jit``, ``grad`` or ``vmap``) the function is the plain ``jax.jit`` one, compiled with
    its caller.
    """
    tuned = jax.jit(fun, compiler_options=options, **kwargs)
    plain = jax.jit(fun, **kwargs)

    @functools.wraps(fun)
    def call(*args, **kw):
        traced = any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves((args, kw)))
        return (plain if traced else tuned)(*args, **kw)

    call.lower = tuned.lower  # type: ignore[attr-defined]
    return call


def jit_once(fun=None, /, **kwargs):
    """:func:`jax.jit` with :data:`FAST_COMPILE`; use as ``jit_once(f, ...)`` or a decorator
    (``@jit_once`` or ``@jit_once(static_argnums=...)``). Traced arguments: plain ``jax.jit``."""
    if fun is None:
        return functools.partial(jit_once, **kwargs)
    return _jit_with(FAST_COMPILE, fun, kwargs)


def jit_loop(fun=None, /, **kwargs):
    """:func:`jax.jit` with :data:`FULL_OPTIMISATION`; use as ``jit_loop(f, ...)`` or a decorator
    (``@jit_loop`` or ``@jit_loop(static_argnames=...)``). Traced arguments: plain ``jax.jit``."""
    if fun is None:
        return functools.partial(jit_loop, **kwargs)
    return _jit_with(FULL_OPTIMISATION, fun, kwargs)

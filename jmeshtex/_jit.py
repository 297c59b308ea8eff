"""``jit_once``: :func:`jax.jit` for programs that run once or a few times on small inputs.

Parameter initialisers and the equivariance harness's checks run a compiled program once, so XLA's
optimisation passes cost more than they save: an FLDM denoiser's initialiser (64 random draws)
compiles in about half the time at XLA's lowest optimisation level (measured: 9.2 → 3.8 s on a
loaded 2-core machine), its run stays in milliseconds. Training steps, samplers and everything
else that runs many times keep plain :func:`jax.jit`.
"""

from __future__ import annotations

import functools

import jax

#: XLA options of :func:`jit_once` (both are plain ``DebugOptions``, valid on every backend)
FAST_COMPILE = {"xla_backend_optimization_level": 0, "xla_llvm_disable_expensive_passes": True}


def jit_once(fun=None, /, **kwargs):
    """:func:`jax.jit` with :data:`FAST_COMPILE`; use as ``jit_once(f, ...)`` or a decorator
    (``@jit_once`` or ``@jit_once(static_argnums=...)``).

    JAX takes compiler options on a top-level call only: called with traced arguments (inside
    another ``jit``, ``grad`` or ``vmap``) the function is the plain ``jax.jit`` one, compiled with
    its caller.
    """
    if fun is None:
        return functools.partial(jit_once, **kwargs)
    fast = jax.jit(fun, compiler_options=FAST_COMPILE, **kwargs)
    plain = jax.jit(fun, **kwargs)

    @functools.wraps(fun)
    def call(*args, **kw):
        traced = any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves((args, kw)))
        return (plain if traced else fast)(*args, **kw)

    call.lower = fast.lower  # type: ignore[attr-defined]
    return call

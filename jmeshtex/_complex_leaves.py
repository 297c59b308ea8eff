"""The conjugation of a pytree's complex leaves, shared by :func:`jmeshtex.ops.conjugate_complex_grads`
and :func:`jmeshtex.optim.complex_steepest` (ops and optim import neither each other)."""

from __future__ import annotations

import jax
import jax.numpy as jnp


def conjugate_complex_leaves(tree):
    """``tree`` with every complex array leaf conjugated; real and non-array leaves unchanged.

    Example:
      >>> out = conjugate_complex_leaves({"w": jnp.array(1 + 2j), "b": jnp.array(3.0), "n": None})
      >>> complex(out["w"]), float(out["b"]), out["n"]
      ((1-2j), 3.0, None)
    """

    def conj(g):
        if hasattr(g, "dtype") and jnp.issubdtype(g.dtype, jnp.complexfloating):
            return jnp.conj(g)
        return g

    return jax.tree.map(conj, tree)

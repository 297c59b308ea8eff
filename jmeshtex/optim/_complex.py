"""Complex parameters under optax: turn ``jax.grad``'s output into the steepest-ascent direction."""

from __future__ import annotations

import optax

from .._complex_leaves import conjugate_complex_leaves


def complex_steepest() -> optax.GradientTransformation:
    """Conjugate the complex leaves of the gradients, so that the optax chain after it descends.

    For a real loss ``L`` of a complex parameter ``w = a + ib``, ``jax.grad`` returns

    .. math:: g = \\frac{\\partial L}{\\partial a} - i\\,\\frac{\\partial L}{\\partial b},

    the *conjugate* of the steepest-ascent direction. optax treats complex leaves as plain numbers,
    so ``optax.adam`` (or ``sgd``) fed ``g`` moves the imaginary parts uphill and the loss can rise.
    Put this transformation first in ``optax.chain``: it replaces every complex leaf ``g`` by
    ``conj(g)`` and passes real leaves (and ``None``) through, so every later transformation sees
    steepest-ascent directions. It keeps no state. It is the optax form of
    :func:`jmeshtex.ops.conjugate_complex_grads`; the two give equal updates.

    Returns:
      An ``optax.GradientTransformation`` (stateless).

    Example:
      >>> import jax, jax.numpy as jnp, optax
      >>> target = 1.0 + 2.0j
      >>> loss = lambda w: jnp.abs(w - target) ** 2
      >>> opt = optax.chain(complex_steepest(), optax.sgd(0.25))
      >>> w = jnp.array(0j)
      >>> state = opt.init(w)
      >>> for _ in range(2):
      ...     updates, state = opt.update(jax.grad(loss)(w), state, w)
      ...     w = optax.apply_updates(w, updates)
      >>> complex(w)  # each step halves the distance to 1+2j
      (0.75+1.5j)
    """

    def init_fn(params):
        del params
        return optax.EmptyState()

    def update_fn(updates, state, params=None):
        del params
        return conjugate_complex_leaves(updates), state

    return optax.GradientTransformation(init_fn, update_fn)

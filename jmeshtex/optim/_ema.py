"""An exponential moving average of the weights: the model a noisy optimiser is evaluated with."""

from __future__ import annotations

import jax
import jax.numpy as jnp


def ema_update(ema, params, step, *, decay: float):
    """One step of a weight EMA: ``ema ← d·ema + (1 − d)·params`` with ``d = min(decay, (1 + step) / (10 + step))``.

    The step-dependent ``d`` is the usual warm-up: early on the average follows the weights closely
    (a window of about ``step / 10`` steps) instead of dragging the initialisation along, and from
    ``step ≈ 10 / (1 − decay)`` on it averages over about ``1 / (1 − decay)`` steps. Each leaf keeps
    its dtype (complex leaves included). Pure and jit-able; start with ``ema = params``.

    Args:
      ema: the running average (a pytree shaped like ``params``).
      params: the weights after this step.
      step: the step index (0 for the first update), an int or a scalar array.
      decay: the average's decay in [0, 1) (0.999: about 1,000 steps).

    Returns:
      The updated average.

    Example:
      >>> import jax.numpy as jnp
      >>> zero, one = {"w": jnp.zeros(())}, {"w": jnp.ones(())}
      >>> round(float(ema_update(zero, one, 0, decay=0.999)["w"]), 6)  # d = 0.1 at step 0
      0.9
      >>> round(float(ema_update(zero, one, 100_000, decay=0.999)["w"]), 6)  # d = decay
      0.001
    """
    t = jnp.asarray(step, jnp.float32)
    d = jnp.minimum(decay, (1.0 + t) / (10.0 + t))
    return jax.tree.map(
        lambda e, p: d.astype(p.dtype) * e + (1 - d).astype(p.dtype) * p, ema, params
    )

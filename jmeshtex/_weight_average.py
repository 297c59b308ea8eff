"""Training states that carry a weight average beside the weights: the FL-VAE's and FLDM's.

A state is ``{"params", "opt_state"}`` plus ``"ema"`` (the exponential moving average of the
weights, :func:`jmeshtex.optim.ema_update`) when the decay is positive; the driver step updates the
average after each optimiser step, and the trained model is the average when there is one.

Example:
  >>> import jax.numpy as jnp
  >>> from jmeshtex.parallel import data_mesh
  >>> update = lambda p, o, batch: (p + batch, o, {"loss": jnp.sum(p)}, 0)
  >>> step = averaged_step(update, decay=0.9, device_mesh=data_mesh())
  >>> state, metrics = step(averaged_state(jnp.zeros(()), (), decay=0.9), jnp.ones(()))
  >>> float(state["params"]), round(float(averaged_params(state)), 6)  # d = 0.1 at step 0
  (1.0, 0.9)
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax

from .optim import ema_update
from .parallel import data_parallel


def averaged_state(params, opt_state, *, decay: float) -> dict:
    """The initial state: the weights, the optimiser's state and, with ``decay > 0``, the average
    (which starts at the weights)."""
    state = {"params": params, "opt_state": opt_state}
    if decay > 0:
        state["ema"] = params
    return state


def averaged_step(update: Callable, *, decay: float, device_mesh: jax.sharding.Mesh) -> Callable:
    """The driver step ``(state, batch) -> (state, metrics)`` of an optimiser step ``update``.

    Args:
      update: ``update(params, opt_state, batch) -> (params, opt_state, metrics, step_index)``.
      decay: the average's decay (0: no average).
      device_mesh: the mesh the average's update is placed on (replicated).

    Returns:
      The step :func:`jmeshtex._training.fit` runs.
    """
    ema_step = data_parallel(
        functools.partial(ema_update, decay=float(decay)), device_mesh, batch_argnums=()
    )

    def step(state, batch):
        params, opt_state, metrics, index = update(state["params"], state["opt_state"], batch)
        new = {"params": params, "opt_state": opt_state}
        if decay > 0:
            new["ema"] = ema_step(state["ema"], params, index)
        return new, metrics

    return step


def averaged_params(state: dict):
    """The weights a trained model keeps: the average when the state has one."""
    return state["ema"] if "ema" in state else state["params"]

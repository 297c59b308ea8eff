"""The texel-colour optimisation: Adam with the halving schedule, clipped to [0, 1], resumable.

One jitted step run by the library's training driver (:func:`jmeshtex._training.fit`: resume,
checkpoints, loss history, finiteness check, progress, timing); the arrays the loss needs (taps,
groups, weights, targets) travel in ``aux`` as the step's batch, never as constants baked into the
compiled program (hundreds of MB at 1024², and XLA would try to constant-fold through them).
Checkpoints go through :class:`jmeshtex.io.Checkpoints`: the colours and the Adam state as arrays,
the loss curve as JSON.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._errors import InputError
from .._training import CheckpointPolicy, Progress, fit, optimizer_update
from ..io import Checkpoints
from ._config import Config


def optimize_colors(
    x0: jax.Array,
    loss_fn: Callable[[jax.Array, Any], jax.Array],
    aux: Any,
    config: Config,
    *,
    progress: bool,
    desc: str,
    checkpoint: str | os.PathLike | None = None,
    checkpoint_every: int = 50,
    fingerprint: dict | None = None,
) -> tuple[jax.Array, np.ndarray, float, dict]:
    """Minimise ``loss_fn(x, aux)`` over the colours ``x`` from ``x0``.

    Adam, learning rate ``config.learning_rate`` halved every ``config.halve_every`` steps,
    ``config.steps`` steps, ``x`` clipped to [0, 1] after every step.

    With ``checkpoint`` (a folder) the colours, the Adam state and the loss curve are saved there
    every ``checkpoint_every`` steps and at the end; a folder that already holds this run (same
    ``fingerprint``) is resumed from its newest step, and continuing reproduces an uninterrupted run.

    Returns:
      ``(x, losses [steps] float64 (loss before each step's update), final loss, stats)``.

    Raises:
      CheckpointMismatchError: the folder holds a different run.
      InputError: the folder's newest step is past ``config.steps``.
      TrainingDivergedError: a loss or the colours are not finite (nothing non-finite is saved).
    """
    if checkpoint_every < 1:
        raise InputError(f"checkpoint_every must be >= 1, got {checkpoint_every}")
    step, state = _adam_step(loss_fn, config, x0)
    ckpt = None if checkpoint is None else Checkpoints(checkpoint, fingerprint=fingerprint)
    compiled: dict = {}  # the step, compiled once for this call
    try:
        start = None if ckpt is None else ckpt.latest_step()
        if start is not None and start > config.steps:
            raise InputError(
                f"checkpoint {ckpt.directory} is at step {start}, past this run's {config.steps} "
                "steps; ask for at least as many steps, or use another folder"
            )
        opt_dtypes, opt_def = jax.tree.flatten(jax.tree.map(lambda a: a.dtype, state["opt"]))
        run = fit(
            step,
            state,
            lambda i: aux,
            steps=config.steps,
            checkpoints=CheckpointPolicy(
                ckpt,
                every=checkpoint_every,
                saved=lambda s: {"x": s["x"], "opt": jax.tree.leaves(s["opt"])},
                restored=lambda t: {
                    "x": jnp.asarray(t["x"], x0.dtype),
                    "opt": jax.tree.unflatten(
                        opt_def,
                        [jnp.asarray(a, d) for a, d in zip(t["opt"], opt_dtypes, strict=True)],
                    ),
                },
            ),
            progress=Progress(progress, desc),
            compiled=compiled,
        )
    finally:
        if ckpt is not None:
            ckpt.close()
    # the loss of the final colours: one more call of the compiled step, its update discarded
    _, out = next(iter(compiled.values()), step)(run.model, aux)
    rate = run.extra["steps_per_second"]
    stats = {
        "optimize_s": run.seconds,
        "first_step_s": run.compile_seconds,
        "step_s": 1.0 / rate if rate else None,  # None: one step, no rate measured
        "resumed_at": run.resumed_from or 0,
    }
    return run.model["x"], run.losses.get("loss", np.zeros(0)), float(out["loss"]), stats


def _adam_step(loss_fn: Callable, config: Config, x0: jax.Array):
    """``(step, initial state)``: one jitted Adam step on ``{"x", "opt"}`` (the driver's
    ``(state, aux) -> (state, {"loss"})``, the loss at the colours before the update)."""
    boundaries = {
        k * config.halve_every: 0.5 for k in range(1, config.steps // config.halve_every + 1)
    }
    optimizer = optax.adam(optax.piecewise_constant_schedule(config.learning_rate, boundaries))

    @jax.jit
    def step(state, aux):
        x = state["x"]
        loss, grad = jax.value_and_grad(loss_fn)(x, aux)
        x, opt = optimizer_update(optimizer, grad, state["opt"], x)
        return {"x": jnp.clip(x, 0.0, 1.0).astype(x0.dtype), "opt": opt}, {"loss": loss}

    with jax.numpy_dtype_promotion("standard"):
        return step, {"x": x0, "opt": optimizer.init(x0)}

"""The texel-colour optimisation: Adam with the halving schedule, clipped to [0, 1], resumable.

One jitted step; the arrays the loss needs (taps, groups, weights, targets) travel in ``aux`` as
arguments of the step, never as constants baked into the compiled program (hundreds of MB at 1024²,
and XLA would try to constant-fold through them). Checkpoints go through
:class:`jmeshtex.io.Checkpoints`: the colours and the Adam state as arrays, the loss curve as JSON.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._errors import InputError
from .._jit import jit_loop
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
    """
    if checkpoint_every < 1:
        raise InputError(f"checkpoint_every must be >= 1, got {checkpoint_every}")
    boundaries = {
        k * config.halve_every: 0.5 for k in range(1, config.steps // config.halve_every + 1)
    }
    schedule = optax.piecewise_constant_schedule(config.learning_rate, boundaries)
    optimizer = optax.adam(schedule)

    @jit_loop
    def step(x, state, aux):
        loss, grad = jax.value_and_grad(loss_fn)(x, aux)
        with jax.numpy_dtype_promotion("standard"):
            updates, state = optimizer.update(grad, state, x)
            x = optax.apply_updates(x, updates)
        return jnp.clip(x, 0.0, 1.0).astype(x0.dtype), state, loss

    with jax.numpy_dtype_promotion("standard"):
        state = optimizer.init(x0)
    leaves, treedef = jax.tree.flatten(state)
    x, start, losses = x0, 0, []
    ckpt = None if checkpoint is None else Checkpoints(checkpoint, fingerprint=fingerprint)
    if ckpt is not None and ckpt.latest_step() is not None:
        start = ckpt.latest_step()
        if start > config.steps:
            raise InputError(
                f"checkpoint {ckpt.directory} is at step {start}, past this run's {config.steps} "
                "steps; ask for at least as many steps, or use another folder"
            )
        saved, meta = ckpt.restore({"x": x0, "opt": leaves})
        x = jnp.asarray(saved["x"], x0.dtype)
        state = jax.tree.unflatten(
            treedef, [jnp.asarray(a, b.dtype) for a, b in zip(saved["opt"], leaves, strict=True)]
        )
        losses = [float(v) for v in meta["losses"]][:start]

    def save(at: int) -> None:
        ckpt.save(
            at, {"x": x, "opt": jax.tree.leaves(state)}, meta={"losses": [float(v) for v in losses]}
        )

    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=config.steps, initial=start, desc=desc, unit="step", dynamic_ncols=True)
    t0 = time.perf_counter()
    compile_s = 0.0
    try:
        for i in range(start, config.steps):
            x, state, loss = step(x, state, aux)
            losses.append(loss)
            if i == start:
                jax.block_until_ready(x)
                compile_s = time.perf_counter() - t0
            if bar is not None:
                bar.update(1)
                if i % 10 == 0 or i == config.steps - 1:
                    bar.set_postfix(loss=f"{float(loss):.4g}")
            if ckpt is not None and (i + 1) % checkpoint_every == 0 and i + 1 < config.steps:
                save(i + 1)
        jax.block_until_ready(x)
        total = time.perf_counter() - t0
        final = float(jax.jit(loss_fn)(x, aux))
        losses = np.asarray([float(v) for v in losses], np.float64)
        if ckpt is not None:
            save(config.steps)
    finally:
        if bar is not None:
            bar.close()
        if ckpt is not None:
            ckpt.close()
    ran = config.steps - start
    steady = (total - compile_s) / max(ran - 1, 1)
    return (
        x,
        losses,
        final,
        {"optimize_s": total, "first_step_s": compile_s, "step_s": steady, "resumed_at": start},
    )

"""The texel-colour optimisation runs on the training driver: it converges, reports the loss of its
final colours, and refuses a non-finite loss like every other method's training."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import TrainingDivergedError
from jmeshtex.surfacecnn import Config
from jmeshtex.surfacecnn._optimize import optimize_colors


def _loss(x, target):
    return jnp.sum((x - target) ** 2)


def test_colours_move_to_the_target_and_the_final_loss_is_theirs(seed):
    rng = np.random.default_rng(seed)
    target = jnp.asarray(rng.uniform(0.2, 0.8, (16, 3)))
    x0 = jnp.asarray(rng.uniform(0.0, 1.0, (16, 3)))
    cfg = Config(size=16, steps=60, learning_rate=0.05, halve_every=30)
    x, losses, final, stats = optimize_colors(x0, _loss, target, cfg, progress=False, desc="t")
    assert losses.shape == (60,) and losses.dtype == np.float64
    assert losses[0] == pytest.approx(float(_loss(x0, target)))  # the loss before each update
    assert final == pytest.approx(float(_loss(x, target)), rel=1e-9)
    # against the start: the colours moved most of the way to the target
    assert final < 0.05 * losses[0]
    assert float(jnp.min(x)) >= 0.0 and float(jnp.max(x)) <= 1.0 and stats["resumed_at"] == 0


def test_a_non_finite_loss_raises_naming_its_step(tmp_path):
    from jmeshtex.io import Checkpoints

    x0 = jnp.full((4, 3), 0.5)
    cfg = Config(size=16, steps=5)
    with jax.debug_nans(False), pytest.raises(TrainingDivergedError, match="step 0"):
        optimize_colors(
            x0,
            lambda x, aux: jnp.sum(x) + aux,
            jnp.inf,
            cfg,
            progress=False,
            desc="t",
            checkpoint=tmp_path / "ckpt",
            checkpoint_every=1,
        )
    assert Checkpoints(tmp_path / "ckpt").steps() == []  # nothing non-finite was saved

"""The one training driver (``jmeshtex._training.fit``): resume, saves, finiteness, timing, progress;
its two small records (``CheckpointPolicy``, ``Progress``)."""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import CheckpointMismatchError, ConfigError, TrainingDivergedError, TrainResult
from jmeshtex._training import CheckpointPolicy, Progress, fit
from jmeshtex.io import Checkpoints


@jax.jit
def _step(state, batch):
    """One SGD step on ``0.5 (w·x − y)²``; the batch of step ``i`` is a function of ``i`` alone."""
    x, y = batch

    def loss(w):
        return 0.5 * (jnp.dot(w, x) - y) ** 2

    value, grad = jax.value_and_grad(loss)(state["w"])
    return {"w": state["w"] - 0.1 * grad, "t": state["t"] + 1}, {"loss": value, "grad": grad[0]}


def _batches(i: int):
    rng = np.random.default_rng(i)
    return rng.normal(size=3).astype(np.float32), np.float32(rng.normal())


def _state():
    return {"w": jnp.zeros(3, jnp.float32), "t": jnp.int32(0)}


def test_resumed_run_equals_uninterrupted_run(tmp_path):
    full = fit(_step, _state(), _batches, steps=7, progress=False)
    assert isinstance(full, TrainResult) and full.steps == 7 and full.resumed_from is None
    assert set(full.losses) == {"loss", "grad"} and full.losses["loss"].shape == (7,)
    # stop after 3 steps, saving every 2: checkpoints 2 and 3 (the end of the call)
    policy = CheckpointPolicy(tmp_path, fingerprint={"run": 1}, every=2)
    part = fit(_step, _state(), _batches, steps=7, stop_after=3, checkpoints=policy, progress=False)
    assert part.steps == 3 and Checkpoints(tmp_path).steps() == [2, 3]
    np.testing.assert_array_equal(part.losses["loss"], full.losses["loss"][:3])
    rest = fit(_step, _state(), _batches, steps=7, checkpoints=policy, progress=False)
    assert rest.resumed_from == 3 and rest.steps == 7
    for name in ("loss", "grad"):
        np.testing.assert_array_equal(rest.losses[name], full.losses[name])
    np.testing.assert_array_equal(rest.model["w"], full.model["w"])
    assert int(rest.model["t"]) == 7
    # another run's folder is refused, not resumed
    with pytest.raises(CheckpointMismatchError, match="run"):
        other = CheckpointPolicy(tmp_path, fingerprint={"run": 2})
        fit(_step, _state(), _batches, steps=7, checkpoints=other, progress=False)


def test_a_checkpoint_without_the_driver_s_loss_record_is_refused(tmp_path):
    Checkpoints(tmp_path).save(2, _state(), meta={"loss": [0.5, 0.25]})  # an older layout
    with pytest.raises(CheckpointMismatchError, match="no loss record"):
        fit(_step, _state(), _batches, steps=4, checkpoints=tmp_path, progress=False)


def test_non_finite_loss_raises_naming_the_step_and_saves_nothing_non_finite(tmp_path):
    def batches(i):
        x, y = _batches(i)
        return x, np.float32(np.nan) if i == 4 else y

    # the suite's jax_debug_nans would stop inside the step: the driver's own check is under test
    with jax.debug_nans(False), pytest.raises(TrainingDivergedError, match="at step 4") as err:
        policy = CheckpointPolicy(tmp_path, every=2)
        fit(_step, _state(), batches, steps=8, checkpoints=policy, progress=False)
    assert err.value.step == 4 and isinstance(err.value, FloatingPointError)
    assert Checkpoints(tmp_path).steps() == [2, 4]  # step 4's checkpoint holds steps 0..3
    state, meta = Checkpoints(tmp_path).restore(_state())
    assert np.isfinite(np.asarray(state["w"])).all() and len(meta["losses"]["loss"]) == 4


def test_non_finite_parameters_raise_even_when_the_losses_are_finite():
    @jax.jit
    def step(state, batch):
        return {"w": state["w"] / batch}, {"loss": jnp.float32(1.0)}

    with (
        jax.debug_nans(False),
        pytest.raises(TrainingDivergedError, match="parameters are not finite after step 2"),
    ):
        fit(step, {"w": jnp.ones(2, jnp.float32)}, lambda i: np.float32(i), steps=2, progress=False)


def test_seconds_is_the_whole_call_and_compile_time_is_apart():
    started = time.perf_counter()
    time.sleep(0.2)  # the caller's data preparation, before fit
    r = fit(_step, _state(), _batches, steps=3, progress=False, started=started)
    assert r.seconds >= 0.2 + r.compile_seconds and r.compile_seconds > 0
    # the compiled step belongs to the cache the caller passes: a second call does not compile
    cache: dict = {}
    fit(_step, _state(), _batches, steps=2, progress=False, compiled=cache)
    again = fit(_step, _state(), _batches, steps=2, progress=False, compiled=cache)
    assert len(cache) == 1 and again.compile_seconds == 0.0


def test_progress_off_writes_nothing_and_on_shows_a_bar(capsys):
    fit(_step, _state(), _batches, steps=2, progress=False)
    assert capsys.readouterr().err == ""
    fit(_step, _state(), _batches, steps=2, progress=Progress(desc="toy train", show=("grad",)))
    err = capsys.readouterr().err
    assert "toy train" in err and "grad=" in err and "loss=" not in err
    fit(_step, _state(), _batches, steps=2, progress=Progress(False, "toy train"))
    assert capsys.readouterr().err == ""


def test_chunked_steps_and_checkpoint_offset(tmp_path):
    """``steps_per_call`` steps per call (the last call partial) and numbered after an offset."""

    @jax.jit
    def chunk(state, batch):
        return {"s": state["s"] + batch.sum()}, {"loss": batch}

    ckpt = Checkpoints(tmp_path)
    r = fit(
        chunk, {"s": jnp.float32(0)}, lambda i: np.arange(i, i + 4, dtype=np.float32), steps=10,
        steps_per_call=4, checkpoints=CheckpointPolicy(ckpt, every=4, offset=100), progress=False,
    )  # fmt: skip
    ckpt.close()
    # calls at steps 0, 4, 8; the last runs 2 of its 4 steps and only those are recorded
    assert r.losses["loss"].tolist() == [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]
    assert Checkpoints(tmp_path).steps() == [108, 110]


def test_a_folder_alone_saves_once_at_the_end_and_a_folderless_policy_still_calls_on_save(
    tmp_path,
):
    fit(_step, _state(), _batches, steps=5, checkpoints=tmp_path / "a", progress=False)
    assert Checkpoints(tmp_path / "a").steps() == [5]
    # a policy without a folder keeps its save points: on_save runs there, nothing is written
    seen = []
    policy = CheckpointPolicy(every=2, on_save=lambda done, state, losses: seen.append(done))
    fit(_step, _state(), _batches, steps=5, checkpoints=policy, progress=False)
    assert seen == [2, 4, 5] and sorted(p.name for p in tmp_path.iterdir()) == ["a"]


def test_the_policy_stores_what_saved_gives_and_resumes_through_restored(tmp_path):
    """``saved`` / ``restored`` change the stored pytree, ``meta`` adds to each record, ``final``
    turns the end-of-call save off."""
    policy = CheckpointPolicy(
        tmp_path,
        every=2,
        final=False,
        saved=lambda s: {"weights": s["w"], "count": s["t"]},
        restored=lambda tree: {"w": tree["weights"], "t": tree["count"]},
        meta=lambda done: {"done": done},
    )
    part = fit(_step, _state(), _batches, steps=6, stop_after=3, checkpoints=policy, progress=False)
    assert Checkpoints(tmp_path).steps() == [2]  # step 3 ends the call, but final=False
    tree, record = Checkpoints(tmp_path).restore({"weights": jnp.zeros(3), "count": jnp.int32(0)})
    assert int(tree["count"]) == 2 and record["done"] == 2 and len(record["losses"]["loss"]) == 2
    rest = fit(_step, _state(), _batches, steps=6, checkpoints=policy, progress=False)
    full = fit(_step, _state(), _batches, steps=6, progress=False)
    assert rest.resumed_from == 2 and part.steps == 3
    np.testing.assert_array_equal(rest.model["w"], full.model["w"])
    np.testing.assert_array_equal(rest.losses["loss"], full.losses["loss"])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"every": 0}, "every must be a positive integer"),
        ({"every": 2.5}, "every must be a positive integer"),
        ({"every": True}, "every must be a positive integer"),
        ({"offset": -1}, "offset must be a non-negative integer"),
    ],
)
def test_a_bad_policy_is_a_config_error(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        CheckpointPolicy("folder", **kwargs)


def test_fit_takes_the_grouped_records_not_their_fields():
    """The signature stays narrow: checkpoint and progress settings only through their records."""
    import inspect

    params = set(inspect.signature(fit).parameters)
    assert {"checkpoints", "progress"} <= params
    loose = {"fingerprint", "save_every", "final_save", "checkpoint_offset", "saved", "restored"}
    assert not params & (loose | {"meta", "on_save", "desc", "show"}), sorted(params & loose)
    assert len(params) <= 15, sorted(params)

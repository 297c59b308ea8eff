"""The one training driver: every method's ``train`` builds its data and its step, then calls :func:`fit`.

:func:`fit` runs a step function over numbered batches and owns what every training loop needs:
resuming from a :class:`~jmeshtex.io.Checkpoints` folder, periodic and final saves, the per-step
loss histories, a finiteness check (a non-finite loss or parameter raises
:class:`~jmeshtex.TrainingDivergedError` naming the step; nothing non-finite is saved or returned),
a tqdm progress bar, timing (``seconds`` of the whole call, compilation reported apart) and the
refusal of checkpoints in a multi-process run. Compiled steps belong to the call: a jitted step is
compiled ahead of time once per argument shapes into a cache the caller owns (``compiled``), never a
process-global one. Two small records keep its signature narrow: :class:`CheckpointPolicy` (where,
when and what is saved, and how a checkpoint becomes a state again) and :class:`Progress` (the bar
and the run's name in messages). :func:`optimizer_update` is the one optax update every method's
step applies.

Example:
  >>> import jax, jax.numpy as jnp
  >>> step = jax.jit(lambda w, x: (w - 0.5 * (w - x), {"loss": jnp.sum((w - x) ** 2)}))
  >>> r = fit(step, jnp.zeros(2), lambda i: jnp.ones(2), steps=3, progress=False)
  >>> r.steps, r.losses["loss"].tolist(), r.model.tolist()
  (3, [2.0, 0.5, 0.125], [0.875, 0.875])

A run stopped early (``stop_after``) continues from its checkpoint as if never interrupted:

  >>> import tempfile
  >>> step = jax.jit(lambda s, x: ({"w": s["w"] + x}, {"loss": jnp.sum(s["w"])}))
  >>> state, policy = {"w": jnp.zeros(1)}, CheckpointPolicy(tempfile.mkdtemp(), every=1)
  >>> part = fit(step, state, lambda i: jnp.ones(1), steps=4, stop_after=2,
  ...            checkpoints=policy, progress=False)
  >>> rest = fit(step, state, lambda i: jnp.ones(1), steps=4, checkpoints=policy,
  ...            progress=False)
  >>> rest.resumed_from, rest.losses["loss"].tolist()
  (2, [0.0, 1.0, 2.0, 3.0])
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypeVar

import jax
import jax.numpy as jnp
import numpy as np

from ._config import is_int
from ._errors import CheckpointMismatchError, ConfigError, TrainingDivergedError
from ._jit import loop_options
from ._train_result import TrainResult
from .io import Checkpoints
from .parallel import fetch, is_multiprocess, replicate

State = TypeVar("State")

#: losses shown in the progress bar are averaged over this many recent steps
_SHOWN_WINDOW = 20


@dataclasses.dataclass(frozen=True)
class CheckpointPolicy:
    """Where, when and what :func:`fit` saves, and how a restored checkpoint becomes a state.

    Attributes:
      folder: a :class:`~jmeshtex.io.Checkpoints` (the caller closes it) or a folder (opened with
        ``fingerprint`` and closed by :func:`fit`); None: nothing on disk (``on_save`` still runs).
      fingerprint: what a folder given by path is tied to (``Checkpoints(fingerprint=)``).
      every: save every this many steps; None: only at the end of the call.
      final: also save after the last step of the call.
      offset: added to the steps done to number the checkpoints (DGTS's levels).
      saved: ``state -> stored pytree`` (default: the state itself).
      restored: ``stored pytree -> state`` (default: the pytree itself).
      meta: ``steps done -> dict`` stored with every checkpoint next to ``"losses"``.
      on_save: called with ``(steps done, state, histories)`` at every save point (periodic and
        final), with or without ``folder``.

    Raises:
      ConfigError: ``every`` not a positive integer (or None), ``offset`` not a non-negative one.

    Example:
      >>> CheckpointPolicy("ckpt/", every=100).final
      True
    """

    folder: Checkpoints | str | os.PathLike | None = None
    fingerprint: dict | None = None
    every: int | None = None
    final: bool = True
    offset: int = 0
    saved: Callable[[Any], Any] | None = None
    restored: Callable[[Any], Any] | None = None
    meta: Callable[[int], dict] | None = None
    on_save: Callable[[int, Any, dict[str, list[float]]], None] | None = None

    def __post_init__(self):
        if self.every is not None and not is_int(self.every, 1):
            raise ConfigError(
                f"CheckpointPolicy.every must be a positive integer or None, got {self.every!r}"
            )
        if not is_int(self.offset, 0):
            raise ConfigError(
                f"CheckpointPolicy.offset must be a non-negative integer, got {self.offset!r}"
            )


@dataclasses.dataclass(frozen=True)
class Progress:
    """:func:`fit`'s progress bar and the name of the run in its messages.

    Attributes:
      bar: draw a tqdm bar with ETA on stderr.
      desc: the bar's label and the prefix of the driver's error messages.
      show: the loss names the bar shows (each the mean of its last 20 steps).

    Example:
      >>> Progress(False, "FL-VAE train").show
      ('loss',)
    """

    bar: bool = True
    desc: str = "train"
    show: tuple[str, ...] = ("loss",)


def optimizer_update(opt, grads, state, params):
    """``(params, state)`` after one update of the optax transformation ``opt``: ``opt.update`` then
    ``optax.apply_updates``, under standard dtype promotion (optax mixes integer step counters with
    float leaves, which strict promotion refuses).

    Example:
      >>> import jax.numpy as jnp, optax
      >>> opt, w = optax.sgd(0.5), jnp.ones(2)
      >>> w, state = optimizer_update(opt, jnp.ones(2), opt.init(w), w)  # gradient 1
      >>> w.tolist()
      [0.5, 0.5]
    """
    import optax

    with jax.numpy_dtype_promotion("standard"):
        updates, state = opt.update(grads, state, params)
        return optax.apply_updates(params, updates), state


def fit(
    step: Callable[[State, Any], tuple[State, Mapping[str, Any]]],
    state: State,
    batches: Callable[[int], Any],
    *,
    steps: int,
    stop_after: int | None = None,
    steps_per_call: int = 1,
    checkpoints: CheckpointPolicy | Checkpoints | str | os.PathLike | None = None,
    progress: Progress | bool = True,
    start: int | None = None,
    history: Mapping[str, Sequence[float]] | None = None,
    device_mesh: jax.sharding.Mesh | None = None,
    on_step: Callable[[int, State, Any], None] | None = None,
    model: Callable[[State], Any] | None = None,
    compiled: dict | None = None,
    started: float | None = None,
) -> TrainResult:
    """Run ``step`` over ``batches`` from the resumed (or initial) ``state`` up to ``steps``.

    Args:
      step: ``(state, batch) -> (state, losses)``, ``losses`` a dict of scalars (or, with
        ``steps_per_call > 1``, of ``[steps_per_call]`` arrays whose first ``n`` entries are the
        steps run). A :func:`jax.jit` function is compiled ahead of time (timed apart); any other
        callable runs as it is and its first call counts as compilation.
      state: the initial training state (a pytree; a dict or another container to be
        checkpointed); replaced by the checkpoint's on resume.
      batches: ``first step index -> batch`` of the call; a function of the index alone, so a
        resumed run sees the batches an uninterrupted one would.
      steps: the run's length (the schedule's ``steps``).
      stop_after: run at most this many steps in this call (continue later from a checkpoint).
      steps_per_call: steps one ``step`` call runs (a compiled chunk of steps).
      checkpoints: a :class:`CheckpointPolicy`; a :class:`~jmeshtex.io.Checkpoints` or a folder
        alone is ``CheckpointPolicy(folder)`` (saved at the end of the call only); None: nothing
        on disk and no save points.
      progress: a :class:`Progress`; True / False is ``Progress(bar=True / False)``.
      start: the steps already done, with ``history`` their losses: no resume from
        ``checkpoints`` (the caller restored). None: resume from the newest checkpoint, if any.
      history: losses of earlier steps by name (kept in front of this call's).
      device_mesh: replicate the initial or restored state on this :class:`jax.sharding.Mesh`.
      on_step: called with ``(steps done, state, batch)`` after each call.
      model: ``state -> model`` for :attr:`TrainResult.model` (default: the state).
      compiled: the cache of ahead-of-time compiled steps (a dict the caller owns, shared by its
        calls of :func:`fit`); None: a fresh one.
      started: :func:`time.perf_counter` when the caller's ``train`` began; ``seconds`` counts from
        it (default: from entering :func:`fit`).

    Returns:
      :class:`~jmeshtex.TrainResult`: ``losses`` (1-D float64 arrays, earlier steps included),
      ``steps`` (done in all), ``seconds`` (the whole call), ``compile_seconds``, ``resumed_from``
      and ``extra["steps_per_second"]`` (this call's rate after its first call; ``None`` when
      no call after the first ran, so nothing was measured).

    Raises:
      TrainingDivergedError: a loss or, at a save point or the end, a parameter is not finite.
      ConfigError: checkpoints in a multi-process run (not supported yet).
      CheckpointMismatchError: the folder holds a checkpoint of another run (or one without
        this driver's loss record).
    """
    t_call = time.perf_counter() if started is None else started
    progress = progress if isinstance(progress, Progress) else Progress(bool(progress))
    run = _Run.open(step, state, batches, _as_policy(checkpoints), progress.desc, device_mesh)
    run.compiled = {} if compiled is None else compiled
    run.losses = {k: [float(x) for x in v] for k, v in (history or {}).items()}
    try:
        start = run.resume(device_mesh) if start is None else start
        end = max(start, steps if stop_after is None else min(steps, start + int(stop_after)))
        run.loop(start, end, steps_per_call, progress, steps, on_step)
    finally:
        run.close()
    return run.result(end - start, steps_per_call, end, t_call, model)


def _as_policy(checkpoints) -> CheckpointPolicy:
    """:func:`fit`'s ``checkpoints`` argument as a :class:`CheckpointPolicy`."""
    if checkpoints is None:
        return CheckpointPolicy(final=False)
    if isinstance(checkpoints, CheckpointPolicy):
        return checkpoints
    return CheckpointPolicy(checkpoints)


def _progress_bar(progress: Progress, steps: int, start: int):
    """A tqdm bar on stderr (redrawn every 0.5 s on a terminal, every 30 s into a log)."""
    from tqdm.auto import tqdm

    return tqdm(
        total=steps,
        initial=start,
        desc=progress.desc,
        unit="step",
        mininterval=0.5 if sys.stderr.isatty() else 30.0,
    )


@dataclasses.dataclass
class _Run:
    """The mutable state of one :func:`fit` call: the training state, the loss histories, the
    resume point and the timings, with the three things a call does (resume, step, save)."""

    step: Callable
    batches: Callable[[int], Any]
    policy: CheckpointPolicy
    ckpt: Checkpoints | None
    desc: str
    compiled: dict
    losses: dict[str, list[float]]
    state: Any
    resumed_from: int | None = None
    compile_seconds: float = 0.0
    t_first: float | None = None
    own_ckpt: bool = False

    @classmethod
    def open(cls, step, state, batches, policy: CheckpointPolicy, desc: str, device_mesh) -> _Run:
        """A run with its checkpoint folder open (one given by path is opened here and closed by
        :meth:`close`) and its state replicated on ``device_mesh``."""
        if policy.folder is not None and is_multiprocess():
            raise ConfigError(
                f"{desc}: checkpoints with several processes (jax.distributed) are not "
                "supported yet; train without checkpoints, or in one process"
            )
        own = policy.folder is not None and not isinstance(policy.folder, Checkpoints)
        ckpt = Checkpoints(policy.folder, fingerprint=policy.fingerprint) if own else policy.folder
        return cls(
            step=step,
            batches=batches,
            policy=policy,
            ckpt=ckpt,
            desc=desc,
            compiled={},
            losses={},
            state=state if device_mesh is None else replicate(state, device_mesh),
            own_ckpt=own,
        )

    def close(self) -> None:
        """Close the checkpoint folder if this run opened it."""
        if self.own_ckpt:
            self.ckpt.close()

    def result(self, ran: int, per_call: int, end: int, t_call: float, model) -> TrainResult:
        """The :class:`~jmeshtex.TrainResult` of ``ran`` steps ending at ``end``."""
        after_first = time.perf_counter() - self.t_first if self.t_first is not None else 0.0
        fast = ran > per_call and after_first > 0
        return TrainResult(
            model=self.state if model is None else model(self.state),
            losses={k: np.asarray(v, np.float64) for k, v in self.losses.items()},
            steps=end,
            seconds=time.perf_counter() - t_call,
            compile_seconds=self.compile_seconds,
            resumed_from=self.resumed_from,
            extra={"steps_per_second": (ran - per_call) / after_first if fast else None},
        )

    def resume(self, device_mesh) -> int:
        """Restore the newest checkpoint, if any; the steps already done."""
        latest = None if self.ckpt is None else self.ckpt.latest_step()
        if latest is None:
            return 0
        saved = self.policy.saved or (lambda s: s)
        restored = self.policy.restored or (lambda s: s)
        tree, record = self.ckpt.restore(saved(self.state), step=latest)
        self.state = restored(tree)
        if device_mesh is not None:
            self.state = replicate(self.state, device_mesh)
        if not isinstance(record.get("losses"), dict):
            raise CheckpointMismatchError(
                f"{self.desc}: checkpoint {latest} in {self.ckpt.directory} has no loss record of "
                "this driver (written by an older jmeshtex?); resume with that version, or use "
                "another folder"
            )
        self.resumed_from = latest
        start = latest - self.policy.offset
        self.losses = {k: [float(x) for x in v][:start] for k, v in record["losses"].items()}
        return start

    def loop(self, start: int, end: int, per_call: int, progress: Progress, steps: int, on_step):
        """Steps ``start`` to ``end``, ``per_call`` a call, saving where the policy says."""
        bar = _progress_bar(progress, steps, start) if progress.bar and start < end else None
        try:
            self._loop(start, end, per_call, bar, progress.show, on_step)
        finally:
            if bar is not None:
                bar.close()

    def _loop(self, start: int, end: int, per_call: int, bar, show, on_step) -> None:
        for i in range(start, end, per_call):
            n = min(per_call, end - i)
            batch = self.batches(i)
            out = self.advance(batch)
            self.record(out, i, n)
            if self.t_first is None:
                self.t_first = time.perf_counter()
            done = i + n
            if bar is not None:
                bar.update(n)
                recent = {k: self.losses[k][-_SHOWN_WINDOW:] for k in show if k in self.losses}
                bar.set_postfix({k: f"{np.mean(v):.4g}" for k, v in recent.items()}, refresh=False)
            if on_step is not None:
                on_step(done, self.state, batch)
            every = self.policy.every
            periodic = every is not None and done % every == 0 and done < end
            if periodic or (self.policy.final and done == end):
                self.save(done)
        jax.block_until_ready(self.state)
        _check_finite_state(self.state, self.desc, self.policy.offset + end)

    def advance(self, batch):
        """One call of the step (compiled ahead of time once per shapes); its losses."""
        run, t_compile = _compiled_step(self.step, self.state, batch, self.compiled)
        if t_compile is None:  # not a jitted step: time its first call instead
            t0 = time.perf_counter()
            self.state, out = run(self.state, batch)
            if self.t_first is None:
                jax.block_until_ready((self.state, out))
                self.compile_seconds += time.perf_counter() - t0
        else:
            self.compile_seconds += t_compile
            self.state, out = run(self.state, batch)
        return fetch(out)

    def record(self, out: Mapping[str, Any], i: int, n: int) -> None:
        """Append the first ``n`` values of each loss; a non-finite one raises, naming its step."""
        for name, values in out.items():
            values = np.asarray(values, np.float64).reshape(-1)[:n]
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                at = self.policy.offset + i + int(bad[0])
                raise TrainingDivergedError(
                    f"{self.desc}: loss {name!r} is {values[bad[0]]} at step {at}; nothing "
                    "non-finite was saved (lower learning_rate, or check the data's scale)",
                    step=at,
                )
            self.losses.setdefault(name, []).extend(values.tolist())

    def save(self, done: int) -> None:
        """Check the state is finite, then checkpoint it and call ``on_save``."""
        _check_finite_state(self.state, self.desc, self.policy.offset + done)
        if self.ckpt is not None:
            meta = self.policy.meta(done) if self.policy.meta else {}
            saved = self.policy.saved or (lambda s: s)
            self.ckpt.save(
                self.policy.offset + done, saved(self.state), meta={**meta, "losses": self.losses}
            )
        if self.policy.on_save is not None:
            self.policy.on_save(done, self.state, self.losses)


def _compiled_step(step, state, batch, compiled: dict):
    """``(callable, compile seconds)``: a :func:`jax.jit` ``step`` compiled ahead of time once per
    argument shapes and dtypes into ``compiled`` (0 s on a hit), with the process's loop options
    (``jmeshtex._jit``: none by default, so ``XLA_FLAGS`` decide); ``(step, None)`` for any other."""
    if not hasattr(step, "lower"):
        return step, None
    leaves, treedef = jax.tree.flatten((state, batch))
    signature = (
        step,
        treedef,
        tuple((np.shape(x), jnp.result_type(x).name) for x in leaves),
    )
    hit = compiled.get(signature)
    if hit is not None:
        return hit, 0.0
    t = time.perf_counter()
    compiled[signature] = step.lower(state, batch).compile(loop_options())
    return compiled[signature], time.perf_counter() - t


@jax.jit
def _all_finite(leaves: list) -> jax.Array:
    return jnp.stack([jnp.all(jnp.isfinite(x)) for x in leaves]).all()


def _check_finite_state(state: Any, desc: str, step: int) -> None:
    """Raise :class:`TrainingDivergedError` if a floating leaf of ``state`` is not finite."""
    leaves = [
        x
        for x in jax.tree.leaves(state)
        if hasattr(x, "dtype") and jnp.issubdtype(x.dtype, jnp.inexact)
    ]
    if leaves and not bool(fetch(_all_finite(leaves))):
        raise TrainingDivergedError(
            f"{desc}: the parameters are not finite after step {step}; nothing non-finite was "
            "saved (lower learning_rate, or check the data's scale)",
            step=step,
        )

"""Resumable training checkpoints: one mechanism for every method, on ``orbax-checkpoint``.

A :class:`Checkpoints` folder holds numbered steps (``<folder>/<step>/``), each an array pytree
(the training state: parameters, optimiser state, PRNG key data, ...) plus a small JSON record
(``meta``: losses so far, the config, anything JSON-serialisable). Orbax writes every step into a
temporary folder and renames it when complete, so an interrupted save never leaves a half-written
step behind; the last ``keep`` steps are kept.

A *fingerprint* (a JSON-able dict: the config, a hash of the data) is stored with every step; a
folder whose fingerprint differs from the caller's cannot be resumed by mistake: :meth:`restore`
raises :class:`~jmeshtex.CheckpointMismatchError` naming the keys that differ.

Restoring takes a ``like`` pytree with the structure, shapes and dtypes of the saved state (e.g.
the freshly initialised state); leaves come back as arrays with ``like``'s placement, so a state
saved by a sharded run restores on one device and back.

Example:
  >>> import tempfile, numpy as np
  >>> ckpt = Checkpoints(tempfile.mkdtemp(), fingerprint={"steps": 10})
  >>> ckpt.latest_step() is None
  True
  >>> ckpt.save(5, {"w": np.ones(3)}, meta={"losses": [0.5, 0.25]})
  >>> state, meta = ckpt.restore({"w": np.zeros(3)})
  >>> ckpt.latest_step(), state["w"].tolist(), meta["losses"]
  (5, [1.0, 1.0, 1.0], [0.5, 0.25])
"""

from __future__ import annotations

import json
import os
import pathlib
from typing import Any

import jax
import numpy as np

from .._errors import CheckpointMismatchError, MeshIOError

_FINGERPRINT = "fingerprint"


def _jsonable(value: Any) -> Any:
    """``value`` through a JSON round trip (tuples become lists), so comparisons match what is read."""
    return json.loads(json.dumps(value, sort_keys=True, default=_json_default))


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"checkpoint meta: {type(value).__name__} is not JSON-serialisable")


def _to_arrays(state: Any) -> Any:
    """Leaves as arrays orbax can store: NumPy scalars and Python numbers become 0-d arrays."""

    def leaf(x):
        if isinstance(x, jax.Array):
            if jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key):
                raise TypeError(
                    "checkpoint state: store jax.random.key_data(key), not a typed PRNG key"
                )
            return x
        return np.asarray(x)

    return jax.tree.map(leaf, state)


class Checkpoints:
    """A folder of numbered training checkpoints (atomic, resumable, the last ``keep`` kept).

    Args:
      directory: the folder (created on the first save).
      keep: how many of the newest steps to keep (older ones are deleted after a save).
      fingerprint: JSON-able description of what is being trained; stored with every step and
        compared on :meth:`restore`. None: no check.
    """

    def __init__(
        self, directory: str | os.PathLike, *, keep: int = 2, fingerprint: dict | None = None
    ):
        if keep < 1:
            raise ValueError(f"Checkpoints(keep={keep}): keep at least 1 step")
        self.directory = pathlib.Path(directory).absolute()
        if self.directory.exists() and not self.directory.is_dir():
            raise MeshIOError(f"checkpoint folder {self.directory} exists and is not a folder")
        self.keep = keep
        self.fingerprint = None if fingerprint is None else _jsonable(fingerprint)
        self._manager = None

    def _mgr(self):
        if self._manager is None:
            import orbax.checkpoint as ocp

            options = ocp.CheckpointManagerOptions(
                max_to_keep=self.keep, create=True, enable_async_checkpointing=False
            )
            self._manager = ocp.CheckpointManager(self.directory, options=options)
        return self._manager

    def steps(self) -> list[int]:
        """The saved steps, oldest first (empty when the folder holds none)."""
        if not self.directory.is_dir():
            return []
        return sorted(
            int(p.name) for p in self.directory.iterdir() if p.is_dir() and p.name.isdigit()
        )

    def latest_step(self) -> int | None:
        """The newest complete step, or None."""
        steps = self.steps()
        return steps[-1] if steps else None

    def save(self, step: int, state: Any, *, meta: dict | None = None) -> None:
        """Write ``state`` (an array pytree) and ``meta`` (JSON-able) as ``step``, atomically.

        Saving a step that already exists replaces it.
        """
        import orbax.checkpoint as ocp

        record = _jsonable(dict(meta or {}))
        record[_FINGERPRINT] = self.fingerprint
        mgr = self._mgr()
        if step in self.steps():
            mgr.delete(step)
        mgr.save(
            int(step),
            args=ocp.args.Composite(
                state=ocp.args.StandardSave(_to_arrays(state)), meta=ocp.args.JsonSave(record)
            ),
        )
        mgr.wait_until_finished()

    def restore(self, like: Any, *, step: int | None = None) -> tuple[Any, dict]:
        """The state and meta of ``step`` (default: the newest), shaped like ``like``.

        Raises:
          MeshIOError: no checkpoint in the folder, or the state does not match ``like``.
          CheckpointMismatchError: the stored fingerprint differs from this object's.
        """
        import orbax.checkpoint as ocp

        step = self.latest_step() if step is None else step
        if step is None or step not in self.steps():
            raise MeshIOError(f"no checkpoint {'' if step is None else step} in {self.directory}")
        meta = self.read_meta(step)
        self._check_fingerprint(meta.get(_FINGERPRINT), step)
        like = _to_arrays(like)
        try:
            out = self._mgr().restore(
                step, args=ocp.args.Composite(state=ocp.args.StandardRestore(like))
            )
        except (ValueError, KeyError, TypeError) as err:
            raise MeshIOError(
                f"checkpoint {self.directory / str(step)} does not match the state to resume: {err}"
            ) from err
        state = jax.tree.map(
            lambda ref, x: np.asarray(x) if isinstance(ref, np.ndarray) else x, like, out.state
        )
        meta.pop(_FINGERPRINT, None)
        return state, meta

    def read_meta(self, step: int | None = None) -> dict:
        """The JSON record of ``step`` (default: the newest), fingerprint included."""
        import orbax.checkpoint as ocp

        step = self.latest_step() if step is None else step
        if step is None:
            raise MeshIOError(f"no checkpoint in {self.directory}")
        out = self._mgr().restore(step, args=ocp.args.Composite(meta=ocp.args.JsonRestore()))
        return dict(out.meta)

    def _check_fingerprint(self, stored: Any, step: int) -> None:
        if self.fingerprint is None or stored == self.fingerprint:
            return
        stored = stored or {}
        keys = sorted(
            k
            for k in set(stored) | set(self.fingerprint)
            if stored.get(k) != self.fingerprint.get(k)
        )
        raise CheckpointMismatchError(
            f"checkpoint {self.directory / str(step)} was written for a different run (differs in: "
            f"{', '.join(keys)}); resume with the same settings, or use another folder"
        )

    def close(self) -> None:
        """Release orbax's resources (also done when the object is garbage-collected)."""
        if self._manager is not None:
            self._manager.close()
            self._manager = None

    def __enter__(self) -> Checkpoints:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

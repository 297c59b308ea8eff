"""Resumable training checkpoints: one mechanism for every method, on ``orbax-checkpoint``.

A :class:`Checkpoints` folder holds numbered steps (``<folder>/<step>/``), each an array pytree
(the training state: parameters, optimiser state, PRNG key data, ...) plus a small JSON record
(``meta``: losses so far, the config, anything JSON-serialisable). Orbax writes every step into a
temporary folder and renames it when complete, so an interrupted save never leaves a half-written
step behind; the last ``keep`` steps are kept.

A *fingerprint* (a JSON-able dict: the config, a hash of the data) is stored with every step; a
folder whose fingerprint differs from the caller's cannot be resumed by mistake: :meth:`restore`
raises :class:`~jmeshtex.CheckpointMismatchError` naming the keys that differ.

Resume takes the newest *valid* step: a step folder that is empty, has no readable ``meta`` or no
state metadata (a stray ``999/``, a truncated copy, garbage bytes) is skipped with a
:class:`~jmeshtex.CheckpointSkippedWarning` naming it, and :meth:`latest_step` returns the newest
step before it. Errors reading or writing a step (corrupt data, a full or read-only disk) are one
:class:`~jmeshtex.MeshIOError` naming the folder; a failed save leaves no temporary folder behind.

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

import contextlib
import errno
import json
import os
import pathlib
import shutil
import warnings
from typing import Any

import jax
import numpy as np

from .._errors import CheckpointMismatchError, CheckpointSkippedWarning, MeshIOError

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


def _first_line(err: BaseException) -> str:
    """A short reason for an error: the errno name and text for OS errors, else the first line."""
    if isinstance(err, OSError) and err.errno in errno.errorcode:
        return f"{errno.errorcode[err.errno]}: {err.strerror or err}"
    text = str(err).strip().splitlines()
    reason = text[0] if text else type(err).__name__
    return reason[:300] + ("..." if len(reason) > 300 else "")


def _step_problem(folder: pathlib.Path) -> str | None:
    """Why ``folder`` is not a readable checkpoint step, or None when it looks complete."""
    try:
        record = json.loads((folder / "meta" / "metadata").read_text(encoding="utf-8"))
    except FileNotFoundError:
        return "no meta record (empty, incomplete, or not a jmeshtex checkpoint)"
    except (OSError, ValueError, UnicodeDecodeError) as err:
        return f"unreadable meta record ({_first_line(err)})"
    if not isinstance(record, dict):
        return "the meta record is not a JSON object"
    try:
        json.loads((folder / "state" / "_METADATA").read_text(encoding="utf-8"))
    except FileNotFoundError:
        return "no state metadata (incomplete, or not a jmeshtex checkpoint)"
    except (OSError, ValueError, UnicodeDecodeError) as err:
        return f"unreadable state metadata ({_first_line(err)})"
    return None


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


def _root(err: BaseException) -> BaseException:
    """The innermost cause of a chained error (orbax wraps the OS error several times)."""
    seen = set()
    while (err.__cause__ or err.__context__) is not None and id(err) not in seen:
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return err


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
        self._warned: set[int] = set()

    def _mgr(self):
        if self._manager is None:
            import orbax.checkpoint as ocp

            options = ocp.CheckpointManagerOptions(
                max_to_keep=self.keep, create=True, enable_async_checkpointing=False
            )
            self._manager = ocp.CheckpointManager(self.directory, options=options)
        return self._manager

    def _all_steps(self) -> list[int]:
        if not self.directory.is_dir():
            return []
        return sorted(
            int(p.name) for p in self.directory.iterdir() if p.is_dir() and p.name.isdigit()
        )

    def steps(self) -> list[int]:
        """The saved, readable steps, oldest first (empty when the folder holds none).

        A step folder that is not a readable checkpoint is left out, with a
        :class:`~jmeshtex.CheckpointSkippedWarning` naming it (once per folder and object).
        """
        valid = []
        for step in self._all_steps():
            problem = _step_problem(self.directory / str(step))
            if problem is None:
                valid.append(step)
            elif step not in self._warned:
                self._warned.add(step)
                warnings.warn(
                    f"checkpoint {self.directory / str(step)} skipped: {problem}; resuming from "
                    "the newest readable step before it (delete the folder to silence this)",
                    CheckpointSkippedWarning,
                    stacklevel=3,
                )
        return valid

    def latest_step(self) -> int | None:
        """The newest complete, readable step, or None (unreadable step folders are skipped)."""
        steps = self.steps()
        return steps[-1] if steps else None

    def save(self, step: int, state: Any, *, meta: dict | None = None) -> None:
        """Write ``state`` (an array pytree) and ``meta`` (JSON-able) as ``step``, atomically.

        Saving a step that already exists replaces it.
        """
        import orbax.checkpoint as ocp

        record = _jsonable(dict(meta or {}))
        record[_FINGERPRINT] = self.fingerprint
        state = _to_arrays(state)
        existing = self.directory / str(int(step))
        try:
            if existing.is_dir():
                if existing.name.isdigit() and _step_problem(existing) is not None:
                    shutil.rmtree(existing)  # an unreadable step of the same number: replaced
                    self.close()  # the manager re-reads the folder
                else:
                    self._mgr().delete(step)
            mgr = self._mgr()
            mgr.save(
                int(step),
                args=ocp.args.Composite(
                    state=ocp.args.StandardSave(state), meta=ocp.args.JsonSave(record)
                ),
            )
            mgr.wait_until_finished()
        except Exception as err:
            self._clean_failed_save(int(step))
            raise MeshIOError(
                f"cannot write checkpoint {existing}: {_first_line(_root(err))}. The previous "
                "steps are kept; free space or fix the folder's permissions, then run again"
            ) from err

    def _clean_failed_save(self, step: int) -> None:
        """Remove the temporary folders of a failed save of ``step`` (the complete steps stay)."""
        with contextlib.suppress(Exception):
            self.close()
        if not self.directory.is_dir():
            return
        for p in self.directory.iterdir():
            if p.name.startswith(f"{step}.") and "tmp" in p.name:
                shutil.rmtree(p, ignore_errors=True)

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
            self.close()
            raise MeshIOError(
                f"checkpoint {self.directory / str(step)} does not match the state to resume: "
                f"{_first_line(err)}. Delete that step folder to resume from an older one"
            ) from err
        except Exception as err:  # corrupt data: orbax/tensorstore errors of many types
            self.close()
            raise MeshIOError(
                f"checkpoint {self.directory / str(step)} cannot be read: "
                f"{_first_line(_root(err))}. Delete that step folder to resume from an older one"
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
        problem = _step_problem(self.directory / str(step))
        if problem is not None:
            raise MeshIOError(f"checkpoint {self.directory / str(step)} cannot be read: {problem}")
        try:
            out = self._mgr().restore(step, args=ocp.args.Composite(meta=ocp.args.JsonRestore()))
        except Exception as err:
            self.close()
            raise MeshIOError(
                f"checkpoint {self.directory / str(step)} cannot be read: {_first_line(_root(err))}"
            ) from err
        if not isinstance(out.meta, dict):
            raise MeshIOError(f"checkpoint {self.directory / str(step)}: meta is not a JSON object")
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
        manager, self._manager = self._manager, None
        if manager is not None:
            with contextlib.suppress(Exception):
                manager.close()

    def __enter__(self) -> Checkpoints:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

"""Resumable training checkpoints: one mechanism for every method, on ``orbax-checkpoint``.

A :class:`Checkpoints` folder holds numbered steps (``<folder>/<step>/``), each an array pytree
(the training state: parameters, optimiser state, PRNG key data, ...) plus a small JSON record
(``meta``: losses so far, the config, anything JSON-serialisable). Every step is written into a
temporary folder and renamed when complete, so an interrupted save never leaves a half-written step
behind; the last ``keep`` steps are kept.

**Ownership.** The folder's record, ``.jmeshtex-checkpoints.json`` (written atomically), lists the
steps this mechanism wrote with the size and SHA-256 of every file in them. Only those steps are
resumed from, replaced or deleted by retention: anything else in the folder (a user's ``100/``, a
``²`` folder, photos) is ignored and never touched, and saving over a step folder the record does
not list is refused with a typed error. The folder itself may not be a symbolic link.

**Damage.** A recorded step whose files are missing, truncated or changed (checksums differ) is
skipped with a :class:`~jmeshtex.CheckpointSkippedWarning` naming it, and resume falls back to the
newest intact step before it; saving that step number again replaces it. A recorded step whose
folder was deleted as a whole (by hand, or by an interrupted retention) is left out silently.

A *fingerprint* (a JSON-able dict: the config, a hash of the data) is stored with every step; a
folder whose fingerprint differs from the caller's cannot be resumed by mistake: :meth:`restore`
raises :class:`~jmeshtex.CheckpointMismatchError` naming the keys that differ. Errors reading or
writing a step (corrupt data, a full or read-only disk) are one :class:`~jmeshtex.CheckpointError`
naming the folder; a failed save leaves no temporary folder behind.

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
import hashlib
import json
import os
import pathlib
import re
import shutil
import tempfile
import warnings
from typing import Any

import jax
import numpy as np

from .._config import is_int
from .._errors import (
    CheckpointError,
    CheckpointMismatchError,
    CheckpointSkippedWarning,
    InputError,
    MeshIOError,
)

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


#: the record of the steps this mechanism wrote (module docstring: ownership)
RECORD = ".jmeshtex-checkpoints.json"
_TMP = ".jmeshtex-tmp-"  # prefix of the temporary folders of saves and replacements
_STEP_NAME = re.compile(r"[0-9]+")  # ASCII digits only ("²".isdigit() is True)


def _file_digests(folder: pathlib.Path) -> dict[str, list]:
    """``{relative path: [size, sha256]}`` of every regular file under ``folder``."""
    out = {}
    for p in sorted(folder.rglob("*")):
        if p.is_symlink():
            out[p.relative_to(folder).as_posix()] = [-1, "symlink"]
        elif p.is_file():
            digest = hashlib.sha256()
            with open(p, "rb") as fh:
                for block in iter(lambda fh=fh: fh.read(1 << 20), b""):
                    digest.update(block)
            out[p.relative_to(folder).as_posix()] = [p.stat().st_size, digest.hexdigest()]
    return out


def _signature(folder: pathlib.Path) -> tuple:
    """Cheap identity of a folder's files (names, sizes, modification times) for caching digests."""
    items = []
    for p in sorted(folder.rglob("*")):
        with contextlib.suppress(OSError):
            st = p.lstat()
            items.append((p.relative_to(folder).as_posix(), st.st_size, st.st_mtime_ns, st.st_mode))
    return tuple(items)


class Checkpoints:
    """A folder of numbered training checkpoints (atomic, resumable, the last ``keep`` kept).

    Args:
      directory: the folder (created on the first save; not a symbolic link).
      keep: how many of the newest steps to keep (older steps this mechanism wrote are deleted
        after a save; nothing else in the folder is ever deleted).
      fingerprint: JSON-able description of what is being trained; stored with every step and
        compared on :meth:`restore`. None: no check.

    Raises:
      InputError: ``keep`` is not a whole number >= 1.
      CheckpointError: ``directory`` exists and is not a folder, or is a symbolic link.
    """

    def __init__(
        self, directory: str | os.PathLike, *, keep: int = 2, fingerprint: dict | None = None
    ):
        if not is_int(keep, 1):
            raise InputError(f"Checkpoints(keep={keep!r}): keep must be a whole number >= 1")
        try:
            self.directory = pathlib.Path(directory).absolute()
        except TypeError:
            raise InputError(f"Checkpoints: {directory!r} is not a folder path") from None
        self._check_folder()
        self.keep = int(keep)
        self.fingerprint = None if fingerprint is None else _jsonable(fingerprint)
        self._warned: set[int] = set()
        self._verified: dict[int, tuple] = {}  # step -> signature of the files checked intact

    def _check_folder(self) -> None:
        from ._atomic import _check_protected

        try:
            _check_protected(self.directory / RECORD)
        except MeshIOError as err:
            raise CheckpointError(
                f"cannot keep checkpoints in {self.directory}: that folder was there before this "
                "command claimed its output folder (--overwrite never writes into or deletes "
                "foreign files). Fix: move it away, or pick a new output folder"
            ) from err
        if self.directory.is_symlink():
            raise CheckpointError(
                f"checkpoint folder {self.directory} is a symbolic link: refusing to write or "
                "delete through it. Fix: remove the link (or pick another output folder)"
            )
        if self.directory.exists() and not self.directory.is_dir():
            raise CheckpointError(f"checkpoint folder {self.directory} exists and is not a folder")

    # -- the record ---------------------------------------------------------------------------
    def _read_record(self) -> dict[int, dict]:
        path = self.directory / RECORD
        if not path.exists():
            return {}
        try:
            if path.is_symlink() or not path.is_file():
                raise ValueError("not a regular file")
            record = json.loads(path.read_text(encoding="utf-8"))
            steps = record["steps"]
            return {int(k): dict(v["files"]) for k, v in steps.items() if _STEP_NAME.fullmatch(k)}
        except (OSError, ValueError, KeyError, TypeError, AttributeError, UnicodeDecodeError) as e:
            if -1 not in self._warned:
                self._warned.add(-1)
                warnings.warn(
                    f"checkpoint record {path} is unreadable ({_first_line(e)}): no step in "
                    f"{self.directory} is resumed from or deleted; delete the folder to start over",
                    CheckpointSkippedWarning,
                    stacklevel=4,
                )
            return {}

    def _write_record(self, steps: dict[int, dict]) -> None:
        from ._atomic import atomic_write

        record = {"format": 1, "steps": {str(k): {"files": steps[k]} for k in sorted(steps)}}
        atomic_write(self.directory / RECORD, json.dumps(record, sort_keys=True) + "\n")

    # -- listing ------------------------------------------------------------------------------
    def _damage(self, step: int, files: dict) -> str | None:
        """Why recorded ``step`` cannot be resumed from, or None when all its files are intact."""
        folder = self.directory / str(step)
        if folder.is_symlink() or not folder.is_dir():
            return "it is not a folder (a link or a file replaced it)"
        signature = _signature(folder)
        if self._verified.get(step) == signature:
            return None
        problem = _step_problem(folder)
        if problem is not None:
            return problem
        found = _file_digests(folder)
        if found != files:
            missing = sorted(set(files) - set(found))
            changed = sorted(k for k in files if k in found and found[k] != files[k])
            what = (
                f"{len(missing)} file(s) missing ({', '.join(missing[:3])})"
                if missing
                else f"{len(changed)} file(s) changed or truncated ({', '.join(changed[:3])})"
                if changed
                else "files added to it"
            )
            return f"its checksums differ from the record: {what}"
        self._verified[step] = signature
        return None

    def steps(self) -> list[int]:
        """The saved, intact steps this mechanism wrote, oldest first (empty when none).

        A recorded step whose files are missing or damaged is left out, with a
        :class:`~jmeshtex.CheckpointSkippedWarning` naming it (once per step and object); one whose
        folder was deleted as a whole is left out silently. Folders the record does not list are
        ignored.
        """
        if not self.directory.is_dir():
            return []
        valid = []
        for step, files in sorted(self._read_record().items()):
            folder = self.directory / str(step)
            if not folder.exists() and not folder.is_symlink():
                continue  # deleted as a whole (by a user, or retention cut short): nothing to say
            problem = self._damage(step, files)
            if problem is None:
                valid.append(step)
            elif step not in self._warned:
                self._warned.add(step)
                warnings.warn(
                    f"checkpoint {self.directory / str(step)} skipped: {problem}; resuming from "
                    "the newest intact step before it",
                    CheckpointSkippedWarning,
                    stacklevel=3,
                )
        return valid

    def latest_step(self) -> int | None:
        """The newest intact step, or None (damaged steps are skipped with a warning)."""
        steps = self.steps()
        return steps[-1] if steps else None

    # -- saving -------------------------------------------------------------------------------
    def save(self, step: int, state: Any, *, meta: dict | None = None) -> None:
        """Write ``state`` (an array pytree) and ``meta`` (JSON-able) as ``step``, atomically.

        Saving a step this mechanism wrote before replaces it; a step folder of that number that
        it did not write is refused (:class:`~jmeshtex.CheckpointError`), never deleted.
        """
        import orbax.checkpoint as ocp

        from ._atomic import atomic_write

        if not is_int(step, 0):
            raise InputError(f"Checkpoints.save: step must be a whole number >= 0, not {step!r}")
        step = int(step)
        record_meta = _jsonable(dict(meta or {}))
        record_meta[_FINGERPRINT] = self.fingerprint
        state = _to_arrays(state)
        self._check_folder()
        target = self.directory / str(step)
        steps = self._read_record()
        if (target.exists() or target.is_symlink()) and step not in steps:
            raise CheckpointError(
                f"cannot write checkpoint {target}: a folder of that name exists that jmeshtex did "
                "not write (it is not in the folder's record); refusing to replace it. Fix: move it "
                "away, or use another output folder"
            )
        tmp = None
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            self._clean_leftovers()
            tmp = pathlib.Path(tempfile.mkdtemp(prefix=f"{_TMP}{step}-", dir=self.directory))
            with ocp.Checkpointer(ocp.StandardCheckpointHandler()) as checkpointer:
                checkpointer.save(tmp / "state", args=ocp.args.StandardSave(state))
            atomic_write(tmp / "meta" / "metadata", json.dumps(record_meta))
            files = _file_digests(tmp)
            steps[step] = files
            self._write_record(steps)  # first the record: a kill after it leaves a damaged step
            if target.exists() or target.is_symlink():
                old = pathlib.Path(
                    tempfile.mkdtemp(prefix=f"{_TMP}old-{step}-", dir=self.directory)
                )
                os.replace(target, old / "step")
            os.replace(tmp, target)
            tmp = None
            self._verified.pop(step, None)
            self._retain(steps)
            self._clean_leftovers()
        except Exception as err:
            if tmp is not None:
                shutil.rmtree(tmp, ignore_errors=True)
            raise CheckpointError(
                f"cannot write checkpoint {target}: {_first_line(_root(err))}. The previous "
                "steps are kept; free space or fix the folder's permissions, then run again"
            ) from err

    def _retain(self, steps: dict[int, dict]) -> None:
        """Delete the recorded steps beyond the newest ``keep`` (only recorded ones, never others)."""
        ordered = sorted(steps)
        drop = ordered[: max(0, len(ordered) - self.keep)]
        if not drop:
            return
        for step in drop:
            del steps[step]
        trash = []
        for step in drop:
            folder = self.directory / str(step)
            if folder.is_dir() and not folder.is_symlink():
                bin_ = pathlib.Path(
                    tempfile.mkdtemp(prefix=f"{_TMP}old-{step}-", dir=self.directory)
                )
                os.replace(folder, bin_ / "step")
                trash.append(bin_)
        self._write_record(steps)
        for bin_ in trash:
            shutil.rmtree(bin_, ignore_errors=True)

    def _clean_leftovers(self) -> None:
        """Remove temporary folders of this mechanism left by an interrupted save (by prefix)."""
        for p in self.directory.iterdir():
            if p.name.startswith(_TMP) and p.is_dir() and not p.is_symlink():
                shutil.rmtree(p, ignore_errors=True)

    # -- reading ------------------------------------------------------------------------------
    def restore(self, like: Any, *, step: int | None = None) -> tuple[Any, dict]:
        """The state and meta of ``step`` (default: the newest intact one), shaped like ``like``.

        Raises:
          CheckpointError: no intact checkpoint in the folder, or the state does not match ``like``.
          CheckpointMismatchError: the stored fingerprint differs from this object's.
        """
        import orbax.checkpoint as ocp

        step = self.latest_step() if step is None else step
        if step is None or step not in self.steps():
            raise CheckpointError(
                f"no checkpoint {'' if step is None else step} in {self.directory}"
            )
        meta = self.read_meta(step)
        self._check_fingerprint(meta.get(_FINGERPRINT), step)
        like = _to_arrays(like)
        folder = self.directory / str(step)
        try:
            with ocp.Checkpointer(ocp.StandardCheckpointHandler()) as checkpointer:
                out = checkpointer.restore(folder / "state", args=ocp.args.StandardRestore(like))
        except (ValueError, KeyError, TypeError) as err:
            raise CheckpointError(
                f"checkpoint {folder} does not match the state to resume: {_first_line(err)}. "
                "Resume with the same settings, or use another output folder"
            ) from err
        except Exception as err:  # corrupt data: orbax/tensorstore errors of many types
            raise CheckpointError(
                f"checkpoint {folder} cannot be read: {_first_line(_root(err))}"
            ) from err
        state = jax.tree.map(
            lambda ref, x: np.asarray(x) if isinstance(ref, np.ndarray) else x, like, out
        )
        meta.pop(_FINGERPRINT, None)
        return state, meta

    def read_meta(self, step: int | None = None) -> dict:
        """The JSON record of ``step`` (default: the newest intact one), fingerprint included."""
        step = self.latest_step() if step is None else step
        if step is None or step not in self.steps():
            raise CheckpointError(
                f"no checkpoint {'' if step is None else step} in {self.directory}"
            )
        path = self.directory / str(step) / "meta" / "metadata"
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError, UnicodeDecodeError) as err:
            raise CheckpointError(f"checkpoint {path} cannot be read: {_first_line(err)}") from err
        if not isinstance(record, dict):
            raise CheckpointError(
                f"checkpoint {self.directory / str(step)}: meta is not a JSON object"
            )
        return record

    def _check_fingerprint(self, stored: Any, step: int) -> None:
        if self.fingerprint is None or stored == self.fingerprint:
            return
        stored = stored if isinstance(stored, dict) else {}
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
        """Nothing to release (kept so callers may close every checkpoint folder alike)."""

    def __enter__(self) -> Checkpoints:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

"""Output folders of the ``jmeshtex`` subcommands: nothing a user gave is overwritten or deleted.

Every subcommand that writes calls :func:`claim_output` before any work. It

- refuses (:class:`~jmeshtex.InputError`) an ``--out`` that is one of the command's inputs, or a
  folder holding one of them (the outputs could overwrite it), whatever ``--overwrite`` says;
- refuses an ``--out`` that exists but is not a folder, or is a link (a write through it would land
  elsewhere);
- writes a small manifest, ``.jmeshtex-owner.json``, naming the command that owns the folder. A
  non-empty folder is only written into by its owner (or a command the caller accepts, such as
  ``dgts train`` in the folder of ``dgts prepare``); another command's folder or one with foreign
  files needs ``--overwrite``;
- protects (:func:`jmeshtex.io.protect`) every input, the MTL files and textures an OBJ input
  names, and every entry that is not the owner's: no output of the command may replace them, even
  with ``--overwrite`` (a typed error names the file);
- takes a lock (``.jmeshtex.lock``, ``flock``): one process per output folder, a second run gets
  :class:`~jmeshtex.OutputLockedError`. The lock is released by :func:`release_all` (``main`` calls
  it after every command) or when the process ends.

:func:`owns` tells whether an entry of the folder was written by this command in an earlier run:
only then may the command delete it (``surfacecnn``'s stale ``checkpoints/``). A folder claimed with
``--overwrite`` lists what was already there as ``foreign`` in the manifest: never the new owner's.
"""

from __future__ import annotations

import contextlib
import json
import os
import pathlib
from collections.abc import Iterable

from .._errors import InputError, OutputLockedError

#: the manifest naming the command that owns an output folder
MANIFEST = ".jmeshtex-owner.json"
#: the lock file that keeps a second process out of an output folder
LOCK = ".jmeshtex.lock"

_HELD: list[int] = []  # file descriptors of the locks this process holds
_HELD_FOLDER: dict[int, pathlib.Path] = {}  # lock file descriptor -> its output folder
_CREATED: list[pathlib.Path] = []  # output folders this process created (removed if left empty)
_PREVIOUS_OWNER: dict[pathlib.Path, str | None] = {}


def _same(a: pathlib.Path, b: pathlib.Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def _inside(path: pathlib.Path, folder: pathlib.Path) -> bool:
    try:
        path.resolve().relative_to(folder.resolve())
    except ValueError:
        return False
    return True


def _manifest(folder: str | os.PathLike) -> dict:
    try:
        record = json.loads((pathlib.Path(folder) / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return {}
    return record if isinstance(record, dict) else {}


def read_owner(folder: str | os.PathLike) -> str | None:
    """The command named by ``folder``'s manifest, or None (no manifest, or an unreadable one).

    Example:
      >>> import tempfile
      >>> with tempfile.TemporaryDirectory() as d:
      ...     read_owner(d)
    """
    command = _manifest(folder).get("command")
    return command if isinstance(command, str) else None


def _foreign_entries(folder: str | os.PathLike) -> set[str]:
    """Entries the manifest lists as not the owner's (there before ``--overwrite`` claimed it)."""
    entries = _manifest(folder).get("foreign", [])
    return {e for e in entries if isinstance(e, str)} if isinstance(entries, list) else set()


def _with_referenced(inputs: Iterable[str | os.PathLike | None]) -> list[pathlib.Path]:
    """The inputs plus the files they make jmeshtex read (an OBJ's MTL files and textures)."""
    from ..io import referenced_files

    out = []
    for given in inputs:
        if given is None:
            continue
        try:
            path = pathlib.Path(given)
        except TypeError:
            continue
        out.append(path)
        out.extend(referenced_files(path))
    return out


def check_output_file(
    out: str | os.PathLike, inputs: Iterable[str | os.PathLike | None], *, flag: str = "--out"
) -> None:
    """Refuse an output file that is one of the inputs, a folder, or a link.

    Args:
      out: the file the command will write.
      inputs: the command's input paths (None and procedural names that are not files are skipped).
      flag: the option that named ``out``, for the message.

    Raises:
      InputError: ``out`` is an input, a folder or a symbolic link.

    Example:
      >>> import tempfile
      >>> with tempfile.TemporaryDirectory() as d:
      ...     m = pathlib.Path(d) / "m.obj"
      ...     _ = m.write_text("v 0 0 0")
      ...     try:
      ...         check_output_file(m, [m])
      ...     except InputError as err:
      ...         print(str(err).split(":")[0])
      refusing to write --out ...m.obj
    """
    out = pathlib.Path(out)
    inputs = _with_referenced(inputs)
    for path in inputs:
        if path.exists() and (_same(out, path) or out.resolve() == path.resolve()):
            raise InputError(
                f"refusing to write {flag} {out}: it is the input {path}, which the output would "
                f"overwrite. Fix: pick another {flag}"
            )
    if out.is_symlink():
        raise InputError(f"{flag} {out} is a symbolic link: pick a plain path")
    if out.is_dir():
        raise InputError(f"{flag} {out} is a folder; this command writes a file there")
    from ..io import protect

    # input files (a folder input, such as a model folder, may hold this command's --out)
    protect([p for p in inputs if not p.is_dir()], "an input of this command")


def claim_output(
    out: str | os.PathLike,
    *,
    command: str,
    inputs: Iterable[str | os.PathLike | None] = (),
    overwrite: bool = False,
    accept: Iterable[str] = (),
) -> pathlib.Path:
    """Make ``out`` this command's output folder (module docstring): check, lock, write the manifest.

    Args:
      out: the output folder (created if missing).
      command: the owning command, e.g. ``"meshmatch transfer"``.
      inputs: the command's input paths (files or folders; None and non-paths are skipped).
      overwrite: write into a folder of another command or with foreign files.
      accept: other owners whose folder this command may write into without ``overwrite``.

    Returns:
      ``out`` as a :class:`pathlib.Path`.

    Raises:
      InputError: ``out`` is or holds an input, is not a folder, or belongs to someone else.
      OutputLockedError: another process holds the folder.

    Example:
      >>> import tempfile
      >>> with tempfile.TemporaryDirectory() as d:
      ...     out = claim_output(pathlib.Path(d) / "run", command="demo example")
      ...     print(read_owner(out), owns(out, "checkpoints", "demo example"))
      ...     release_all()
      demo example False
    """
    out = pathlib.Path(out)
    inputs = _with_referenced(inputs)
    for path in inputs:
        if not path.exists():
            continue
        if _same(out, path) or (out.exists() and _inside(path, out)):
            raise InputError(
                f"refusing to write into --out {out}: it holds the input {path}, which the outputs "
                "could overwrite. Fix: pick another --out (a new folder)"
            )
    if out.is_symlink():
        raise InputError(f"--out {out} is a symbolic link: pick a plain folder path")
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder: pick another path")
    try:
        if not out.exists():
            out.mkdir(parents=True)
            _CREATED.append(out)
    except OSError as err:
        raise InputError(f"cannot create --out {out}: {err.strerror or err}") from err
    owner = read_owner(out)
    foreign = sorted(p.name for p in out.iterdir() if p.name not in (MANIFEST, LOCK))
    allowed = {command, *accept}
    if foreign and owner not in allowed and not overwrite:
        whose = f"the output of `jmeshtex {owner}`" if owner else "files jmeshtex did not write"
        listed = ", ".join(foreign[:5]) + (", ..." if len(foreign) > 5 else "")
        raise InputError(
            f"--out {out} holds {whose} ({listed}): refusing to write over them. Fix: pick a new "
            "folder, or pass --overwrite to write into it anyway"
        )
    _lock(out, command)
    _PREVIOUS_OWNER[out.resolve()] = owner
    from ..io import protect

    # input files (a folder input, such as a model folder, may hold this command's --out)
    protect([p for p in inputs if not p.is_dir()], "an input of this command")
    theirs = set(_foreign_entries(out))
    if foreign and owner not in allowed:
        theirs |= set(foreign)
    protect(
        (out / name for name in sorted(theirs)),
        "a file that was in --out before this command claimed it (--overwrite never replaces "
        "foreign files)",
    )
    if owner is None or owner not in allowed or not foreign:
        from ..io import atomic_write

        record: dict = {"command": command}
        if foreign and owner not in allowed:  # --overwrite: what was there stays someone else's
            record["foreign"] = sorted(set(foreign) | _foreign_entries(out))
        try:
            atomic_write(out / MANIFEST, json.dumps(record) + "\n")
        except OSError as err:
            release_all()
            raise InputError(f"cannot write into --out {out}: {err}") from err
    return out


def claim_args(
    args, command: str, *inputs: str | os.PathLike | None, accept: Iterable[str] = ()
) -> pathlib.Path:
    """:func:`claim_output` of a subcommand's parsed arguments: ``args.out`` for ``command``, with
    ``args.overwrite``; ``inputs`` are the command's input paths (None: not given).

    Example:
      >>> import argparse, tempfile
      >>> with tempfile.TemporaryDirectory() as d:
      ...     args = argparse.Namespace(out=pathlib.Path(d) / "run", overwrite=False)
      ...     print(read_owner(claim_args(args, "demo example", None)))
      ...     release_all()
      demo example
    """
    return claim_output(
        args.out, command=command, inputs=inputs, overwrite=args.overwrite, accept=accept
    )


def owns(out: str | os.PathLike, name: str, command: str | Iterable[str]) -> bool:
    """Whether ``out/name`` was written by ``command`` in an earlier run (so it may delete it).

    True only when ``out`` belonged to ``command`` before this run claimed it and ``name`` is not
    among the entries that were there when a run claimed the folder with ``--overwrite``.

    Example:
      >>> owns("/nonexistent-folder", "checkpoints", "surfacecnn synthesize")
      False
    """
    commands = {command} if isinstance(command, str) else set(command)
    if _PREVIOUS_OWNER.get(pathlib.Path(out).resolve()) not in commands:
        return False
    return name not in _foreign_entries(out)


def _lock(out: pathlib.Path, command: str) -> None:
    import fcntl

    path = out / LOCK
    if path.is_symlink():
        raise InputError(f"{path} is a symbolic link: remove it")
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as err:
        raise InputError(f"cannot write into --out {out}: {err.strerror or err}") from err
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as err:
        os.close(fd)
        raise OutputLockedError(
            f"--out {out} is in use by another jmeshtex process (lock {path}): wait for it to "
            f"finish, or pick another --out"
        ) from err
    _HELD.append(fd)
    _HELD_FOLDER[fd] = out.resolve()


def release(out: str | os.PathLike) -> None:
    """Release the lock this process holds on one output folder (a library caller's run is done)."""
    folder = pathlib.Path(out).resolve()
    for fd in [fd for fd in _HELD if _HELD_FOLDER.get(fd) == folder]:
        _HELD.remove(fd)
        _HELD_FOLDER.pop(fd, None)
        with contextlib.suppress(OSError):
            os.close(fd)


def release_all(*, failed: bool = False) -> None:
    """Release every output-folder lock this process holds (``main`` calls it after a command).

    Args:
      failed: the command failed; an output folder it created and left holding only the manifest
        and the lock is removed again.
    """
    while _HELD:
        fd = _HELD.pop()
        _HELD_FOLDER.pop(fd, None)
        with contextlib.suppress(OSError):
            os.close(fd)
    while _CREATED:
        folder = _CREATED.pop()
        with contextlib.suppress(OSError):
            if failed and {p.name for p in folder.iterdir()} <= {MANIFEST, LOCK}:
                for name in (MANIFEST, LOCK):
                    (folder / name).unlink(missing_ok=True)
                folder.rmdir()

"""Atomic file writes: every file jmeshtex writes goes through a temporary file in the same folder and
``os.replace``, so a crash or a full disk never leaves a half-written output or destroys the
file it replaces; a symbolic link at the path is replaced, never written through.

The ``jmeshtex`` command also protects what is not its own (one mechanism, :func:`protect`): the
files it read (a mesh, the MTL and textures an OBJ names, images, arrays) and the entries an
``--overwrite`` found in its output folder. :func:`atomic_write` refuses to replace a protected
path or to write below a protected folder, with a :class:`~jmeshtex.MeshIOError` naming it. The
library itself protects nothing unless :func:`protect_reads` was turned on (the CLI does)."""

from __future__ import annotations

import contextlib
import io
import os
import pathlib
import tempfile

import numpy as np

from .._errors import MeshIOError

_PROTECTED: dict[str, str] = {}  # real path -> why atomic_write may not replace it
_RECORD_READS = False


def protect(paths, why: str) -> None:
    """Forbid :func:`atomic_write` to replace any of ``paths`` (files or folders) in this process.

    Args:
      paths: paths (None entries and paths that do not exist are skipped).
      why: what the paths are, for the error (``"an input of this command"``).
    """
    for p in paths:
        if p is None:
            continue
        with contextlib.suppress(OSError, TypeError, ValueError):
            if os.path.lexists(p):
                _PROTECTED.setdefault(os.path.realpath(p), why)


def protect_reads(on: bool = True) -> None:
    """Protect every file jmeshtex's readers open from now on (``load_mesh``, ``load_texture``,
    the MTL and textures an OBJ names, ...): the CLI turns this on, so no output replaces an input."""
    global _RECORD_READS
    _RECORD_READS = on


def note_read(path) -> None:
    """Record that ``path`` was read (protected when :func:`protect_reads` is on)."""
    if _RECORD_READS:
        protect([path], "an input this command read")


def unprotect_all() -> None:
    """Forget every protected path and stop protecting reads (the CLI calls it after a command)."""
    global _RECORD_READS
    _PROTECTED.clear()
    _RECORD_READS = False


def _check_protected(path: pathlib.Path) -> None:
    if not _PROTECTED:
        return
    # a link at the path is replaced, not followed: only its folder is resolved
    real = os.path.join(os.path.realpath(path.parent), path.name)
    probe = real
    while True:
        why = _PROTECTED.get(probe)
        if why is not None:
            inside = "" if probe == real else f" (inside {probe})"
            raise MeshIOError(
                f"refusing to write {path}{inside}: it is {why}, not a file this command wrote. "
                "Fix: pick another output path (or move the file away)"
            )
        parent = os.path.dirname(probe)
        if parent == probe:
            return
        probe = parent


def _new_file_mode(path: pathlib.Path) -> int:
    """Keep the permissions of a file being replaced, else the usual ``0o666 & ~umask``."""
    with contextlib.suppress(OSError):
        return path.stat().st_mode & 0o7777
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def atomic_write(
    path: str | os.PathLike, data: bytes | str, *, parents: bool = True
) -> pathlib.Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and ``os.replace``.

    On any failure the temporary file is removed and the previous ``path`` (if any) is untouched.
    A replaced file keeps its permissions. Text is written as UTF-8.

    Args:
      path: the file to (re)write.
      data: bytes, or text.
      parents: create missing parent folders (else a missing folder is an error naming the fix).

    Returns:
      ``path`` as a :class:`pathlib.Path`.

    Raises:
      MeshIOError: the folder is missing (``parents=False``), ``path`` is a folder or protected
        (:func:`protect`), or the OS refused.

    Example:
      >>> import tempfile
      >>> with tempfile.TemporaryDirectory() as d:
      ...     p = atomic_write(pathlib.Path(d) / "sub" / "a.txt", "hello")
      ...     p.read_text(), sorted(x.name for x in p.parent.iterdir())
      ('hello', ['a.txt'])
    """
    path = pathlib.Path(path)
    if isinstance(data, str):
        data = data.encode("utf-8")
    folder = path.parent
    if path.is_dir() and not path.is_symlink():
        raise MeshIOError(f"cannot write {path}: it is a directory")
    _check_protected(path)
    if not folder.is_dir():
        if not parents:
            raise MeshIOError(
                f"cannot write {path}: folder {folder} does not exist. Fix: create it first"
            )
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise MeshIOError(f"cannot write {path}: {err}") from err
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    except OSError as err:
        raise MeshIOError(f"cannot write {path}: {err}") from err
    try:
        with os.fdopen(fd, "wb") as fh:
            os.fchmod(fh.fileno(), _new_file_mode(path))
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as err:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(err, OSError):
            raise MeshIOError(f"cannot write {path}: {err}") from err
        raise
    return path


def atomic_save_npz(
    path: str | os.PathLike, arrays: dict[str, np.ndarray], *, parents: bool = True
) -> pathlib.Path:
    """``np.savez`` (uncompressed, no pickles needed to read it back) written with :func:`atomic_write`.

    Example:
      >>> import tempfile
      >>> with tempfile.TemporaryDirectory() as d:
      ...     p = atomic_save_npz(pathlib.Path(d) / "x.npz", {"a": np.arange(3)})
      ...     np.load(p)["a"].tolist()
      [0, 1, 2]
    """
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return atomic_write(path, buf.getvalue(), parents=parents)


def load_npz(path: str | os.PathLike, what: str) -> dict[str, np.ndarray]:
    """Read a whole ``.npz`` (no pickles) into a dict; a typed error names the file if it fails.

    Args:
      path: the file.
      what: what the file holds, for the error message (``"training meshes"``).

    Raises:
      MeshIOError: the file is missing or not a readable ``.npz``.

    Example:
      >>> import tempfile, numpy as np
      >>> p = atomic_save_npz(tempfile.mkdtemp() + "/a.npz", {"x": np.arange(3)})
      >>> load_npz(p, "example")["x"].tolist()
      [0, 1, 2]
    """
    path = pathlib.Path(path)
    if not path.is_file():
        raise MeshIOError(f"cannot read {what} {path}: no such file")
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except (OSError, ValueError) as err:
        raise MeshIOError(f"cannot read {what} {path}: {err}") from err

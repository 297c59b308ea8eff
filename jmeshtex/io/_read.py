"""Bounded reads: the one check every file jmeshtex reads goes through.

:func:`check_input_file` accepts only a regular file (a FIFO, a device such as ``/dev/zero`` -- also
through a symbolic link -- or a socket would block or never end) no larger than
``jmeshtex.io.MAX_INPUT_BYTES``, and records it as an input (:func:`~jmeshtex.io.protect_reads`).
:func:`check_memory` refuses, before anything is allocated, an array a file describes (an image's
pixels, a header's counts) that would need more than ``jmeshtex.io.MEMORY_BUDGET_BYTES``.
"""

from __future__ import annotations

import os
import pathlib
import stat

from .._errors import MeshIOError
from ._atomic import note_read

#: the largest file jmeshtex reads (2 GiB): a larger mesh, image or array is refused unread
MAX_INPUT_BYTES = 2 << 30
#: the most memory one array described by a file may take once decoded (4 GiB)
MEMORY_BUDGET_BYTES = 4 << 30


def _size(n: float) -> str:
    for unit in ("bytes", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} PiB"  # pragma: no cover


def check_input_file(
    path: str | os.PathLike, what: str, *, max_bytes: int | None = None
) -> pathlib.Path:
    """``path`` as a :class:`pathlib.Path` if it is a readable regular file of bounded size.

    Args:
      path: the file.
      what: what it holds, for the error (``"mesh"``, ``"texture"``, ``"--labels"``).
      max_bytes: the size cap (default ``jmeshtex.io.MAX_INPUT_BYTES``).

    Raises:
      MeshIOError: not a path, missing, a folder, not a regular file (FIFO, device, socket),
        larger than the cap, or not readable.

    Example:
      >>> check_input_file("/dev/null", "mesh")
      Traceback (most recent call last):
      ...
      jmeshtex._errors.MeshIOError: cannot read mesh /dev/null: it is a character device, not a regular file. Fix: give a regular file (copy the data into one)
    """
    try:
        path = pathlib.Path(path)
    except TypeError:
        raise MeshIOError(f"cannot read {what}: {path!r} is not a path") from None
    cap = MAX_INPUT_BYTES if max_bytes is None else max_bytes
    try:
        st = path.stat()  # follows links: a link to /dev/zero is a device
    except FileNotFoundError:
        raise MeshIOError(f"cannot read {what} {path}: no such file") from None
    except OSError as err:
        raise MeshIOError(f"cannot read {what} {path}: {err.strerror or err}") from err
    if stat.S_ISDIR(st.st_mode):
        raise MeshIOError(f"cannot read {what} {path}: it is a directory")
    if not stat.S_ISREG(st.st_mode):
        kind = (
            "a FIFO (named pipe)"
            if stat.S_ISFIFO(st.st_mode)
            else "a character device"
            if stat.S_ISCHR(st.st_mode)
            else "a block device"
            if stat.S_ISBLK(st.st_mode)
            else "a socket"
            if stat.S_ISSOCK(st.st_mode)
            else "not a regular file"
        )
        kind = kind if kind == "not a regular file" else f"{kind}, not a regular file"
        raise MeshIOError(
            f"cannot read {what} {path}: it is {kind}. Fix: give a regular file (copy the data "
            "into one)"
        )
    if st.st_size > cap:
        raise MeshIOError(
            f"cannot read {what} {path}: it is {_size(st.st_size)}, more than the {_size(cap)} "
            "jmeshtex reads from one file. Fix: decimate or downscale it first"
        )
    if not os.access(path, os.R_OK):
        raise MeshIOError(f"cannot read {what} {path}: permission denied")
    note_read(path)
    return path


def check_memory(nbytes: float, what: str, *, budget: int | None = None) -> None:
    """Refuse ``what`` when decoding it would need more than the memory budget.

    Raises:
      MeshIOError: ``nbytes`` exceeds the budget (the error says the size and the budget).

    Example:
      >>> check_memory(1e3, "texture t.png (10 x 10 pixels)")
    """
    budget = MEMORY_BUDGET_BYTES if budget is None else budget
    if nbytes > budget:
        raise MeshIOError(
            f"cannot read {what}: it would need {_size(nbytes)} of memory, more than the "
            f"{_size(budget)} budget for one array. Fix: downscale or split it"
        )

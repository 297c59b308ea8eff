"""Writing and reading a :class:`~jmeshtex.meshmatch.Transfer`: one folder, atomically.

The folder holds ``transfer.npz`` (the target mesh's arrays and the match's arrays, no pickles) and
``transfer.json`` (the mesh's name, the match statistics, a format tag), written last so a folder
with a ``transfer.json`` is complete.
"""

from __future__ import annotations

import dataclasses
import json
import os
import pathlib

import numpy as np

from .._errors import InputError, MeshIOError
from .._mesh import Mesh
from ._match import Match
from ._transfer import Transfer

ARRAYS_FILE = "transfer.npz"
META_FILE = "transfer.json"
KIND = "jmeshtex.meshmatch.Transfer"

#: the Mesh fields stored as arrays (the rest, ``name``, goes to the JSON)
_MESH_ARRAYS = tuple(f.name for f in dataclasses.fields(Mesh) if f.name != "name")
_MATCH_ARRAYS = tuple(f for f in Match._fields if f != "stats")


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def save(result: Transfer, path: str | os.PathLike) -> pathlib.Path:
    """Write a transfer result into the folder ``path``, atomically (read it back with :func:`load`).

    Args:
      result: a :class:`~jmeshtex.meshmatch.Transfer` (from
        :func:`~jmeshtex.meshmatch.transfer`, :func:`~jmeshtex.meshmatch.paint_by_example`
        or :func:`~jmeshtex.meshmatch.transfer_displacement`).
      path: the folder; created if needed, a result already there is replaced.

    Returns:
      The folder.

    Raises:
      InputError: ``result`` is not a ``Transfer``.

    Example:
      >>> import tempfile
      >>> from jmeshtex.data import icosphere
      >>> match = Match(*(np.zeros(12) for _ in range(5)), stats={"levels": []})
      >>> folder = save(Transfer(icosphere(0), match), tempfile.mkdtemp())
      >>> load(folder).mesh.num_vertices
      12
    """
    from ..io import atomic_save_npz, atomic_write

    if not isinstance(result, Transfer):
        raise InputError(
            f"save(result, path): expected a jmeshtex.meshmatch.Transfer first, "
            f"got {type(result).__name__}"
        )
    folder = pathlib.Path(path)
    arrays = {
        f"mesh/{name}": np.asarray(getattr(result.mesh, name))
        for name in _MESH_ARRAYS
        if getattr(result.mesh, name) is not None
    }
    arrays.update(
        {f"match/{name}": np.asarray(getattr(result.match, name)) for name in _MATCH_ARRAYS}
    )
    atomic_save_npz(folder / ARRAYS_FILE, arrays)
    meta = {"kind": KIND, "mesh_name": result.mesh.name, "stats": result.match.stats}
    atomic_write(folder / META_FILE, json.dumps(meta, indent=1, default=_json_default) + "\n")
    return folder


def load(path: str | os.PathLike) -> Transfer:
    """Read a transfer result written by :func:`save`.

    Args:
      path: the folder that holds ``transfer.npz`` and ``transfer.json``.

    Returns:
      The :class:`~jmeshtex.meshmatch.Transfer`, its arrays with their saved dtypes.

    Raises:
      MeshIOError: the folder holds no transfer result, or its files are damaged.

    Example:
      >>> import tempfile
      >>> load(tempfile.mkdtemp())
      Traceback (most recent call last):
      ...
      jmeshtex._errors.MeshIOError: ... holds no MeshMatch transfer ...
    """
    from ..io import load_npz

    folder = pathlib.Path(path)
    if not (folder / META_FILE).is_file():
        raise MeshIOError(
            f"{folder} holds no MeshMatch transfer (expected {META_FILE} and {ARRAYS_FILE}; "
            "write one with jmeshtex.meshmatch.save or `jmeshtex meshmatch transfer`)"
        )
    try:
        meta = json.loads((folder / META_FILE).read_text())
    except (OSError, ValueError) as err:
        raise MeshIOError(f"cannot read {folder / META_FILE}: {err}") from err
    if not isinstance(meta, dict) or meta.get("kind") != KIND:
        raise MeshIOError(
            f"{folder / META_FILE} is not a MeshMatch transfer (kind {meta.get('kind')!r})"
            if isinstance(meta, dict)
            else f"{folder / META_FILE} is not a MeshMatch transfer"
        )
    arrays = load_npz(folder / ARRAYS_FILE, "MeshMatch transfer")
    missing = [
        k
        for k in ("mesh/vertices", "mesh/faces", *(f"match/{n}" for n in _MATCH_ARRAYS))
        if k not in arrays
    ]
    if missing:
        raise MeshIOError(f"{folder / ARRAYS_FILE} lacks {missing}: a damaged or foreign file")
    mesh = Mesh(
        **{name: arrays.get(f"mesh/{name}") for name in _MESH_ARRAYS},
        name=str(meta.get("mesh_name", "mesh")),
    )
    match = Match(
        **{name: arrays[f"match/{name}"] for name in _MATCH_ARRAYS}, stats=meta.get("stats", {})
    )
    return Transfer(mesh, match)

"""The one model file format of every jmeshtex method: :func:`save_model` / :func:`load_model`.

A model file is one uncompressed ``.npz`` (no pickles): each parameter array under its pytree key
path joined by ``/`` (``encoder/mean``, ``generators/0/weights/1``), plus the header
``__jmeshtex_model__``, a UTF-8 JSON string
``{"container": 1, "kind": ..., "format_version": ..., "config": {...}, "extra": {...}}``. ``kind``
names the method's model (``"jmeshtex.fl.Model"``), ``format_version`` the layout of its arrays,
so a file of another method or of an unknown layout is refused before any array is used. The file is
written atomically (temporary file + ``os.replace``; a symbolic link at the path is replaced, never
written through).
"""

from __future__ import annotations

import dataclasses
import io
import json
import os
import pathlib
import zipfile
from collections.abc import Mapping
from typing import Any

import jax
import numpy as np

from .._errors import CorruptModelError, MeshIOError
from ._atomic import atomic_write

#: the npz entry that holds the JSON header
HEADER = "__jmeshtex_model__"
#: the version of the container itself (header + ``/``-keyed arrays)
CONTAINER_VERSION = 1


def _key_name(key) -> str:
    for attr in ("key", "name", "idx"):
        if hasattr(key, attr):
            return str(getattr(key, attr))
    return str(key)


def _flatten(params) -> dict[str, np.ndarray]:
    arrays: dict[str, np.ndarray] = {}
    for path, leaf in jax.tree_util.tree_flatten_with_path(params)[0]:
        name = "/".join(_key_name(k) for k in path)
        if not name or name == HEADER or name in arrays:
            raise MeshIOError(f"cannot store a parameter at key path {name!r}")
        arrays[name] = np.asarray(leaf)
    return arrays


def _nested(arrays: Mapping[str, np.ndarray]) -> dict:
    tree: dict = {}
    for name, value in arrays.items():
        node = tree
        *parents, leaf = name.split("/")
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    return tree


@dataclasses.dataclass(frozen=True)
class ModelFile:
    """What :func:`load_model` read: the header and the parameters.

    Attributes:
      path: the file.
      kind: the model kind stored in it.
      format_version: the layout version stored in it.
      config: the method's config as a dict (``Config.to_dict()``).
      extra: the JSON metadata saved with it (``{}`` if none).
      arrays: the parameter arrays by ``/``-joined key path.
      params: the parameters as a pytree: the structure of ``like`` when one was given, else nested
        dicts keyed by the path parts.
    """

    path: pathlib.Path
    kind: str
    format_version: int
    config: dict
    extra: dict
    arrays: dict[str, np.ndarray]
    params: Any

    def config_as(self, cls):
        """The stored config as ``cls`` (a method's ``Config``): every field must be stored,
        no defaults filled in (``jmeshtex._config.stored_config``).

        Raises:
          CorruptModelError: fields missing, unknown or invalid; the message names them and the file.
        """
        from .._config import display_name, stored_config

        try:
            return stored_config(cls, self.config, self.path)
        except (ValueError, TypeError, KeyError) as err:
            raise CorruptModelError(
                f"model file {self.path}: its stored config is not a valid Config "
                f"({display_name(cls)}): {err}"
            ) from err

    def restore(self, like) -> Any:
        """The arrays in the structure of ``like``; every key path, shape and dtype must match.

        Args:
          like: a pytree of arrays or :class:`jax.ShapeDtypeStruct` (e.g. from ``jax.eval_shape``).

        Returns:
          The pytree of ``like`` with the stored NumPy arrays as leaves.

        Raises:
          CorruptModelError: a missing or surplus array, or a shape or dtype that differs (the
            message names the first one and the counts, never the whole tree).
        """
        flat, treedef = jax.tree_util.tree_flatten_with_path(like)
        names = ["/".join(_key_name(k) for k in path) for path, _ in flat]
        missing = [n for n in names if n not in self.arrays]
        surplus = sorted(set(self.arrays) - set(names))
        if missing or surplus:
            what = []
            if missing:
                what.append(f"{len(missing)} missing (first {missing[0]!r})")
            if surplus:
                what.append(f"{len(surplus)} unexpected (first {surplus[0]!r})")
            raise CorruptModelError(
                f"model file {self.path}: its arrays do not match its config: {', '.join(what)}"
            )
        leaves = []
        for name, (_, ref) in zip(names, flat, strict=True):
            got = self.arrays[name]
            shape, dtype = tuple(np.shape(ref)), np.dtype(ref.dtype)
            if got.shape != shape or got.dtype != dtype:
                raise CorruptModelError(
                    f"model file {self.path}: array {name!r} is {got.dtype}{list(got.shape)}, "
                    f"its config needs {dtype}{list(shape)}"
                )
            leaves.append(got)
        return jax.tree_util.tree_unflatten(treedef, leaves)


def save_model(
    path: str | os.PathLike,
    *,
    kind: str,
    params,
    config: Mapping,
    extra: Mapping | None = None,
    format_version: int = 1,
) -> pathlib.Path:
    """Write a model's parameters, config and metadata to one ``.npz`` file, atomically.

    Args:
      path: the file (missing folders are created; a file or link already there is replaced).
      kind: what the model is, e.g. ``"jmeshtex.fl.Model"``; :func:`load_model` checks it.
      params: a pytree of arrays; each is stored under its key path joined by ``/``.
      config: the config as a JSON-able dict (``Config.to_dict()``).
      extra: JSON-able metadata stored alongside (e.g. the training step).
      format_version: the version of the method's layout of ``params``.

    Returns:
      ``path`` as a :class:`pathlib.Path`.

    Raises:
      MeshIOError: ``config`` or ``extra`` is not JSON-able, or the file cannot be written.

    Example:
      >>> import tempfile, numpy as np
      >>> p = save_model(tempfile.mkdtemp() + "/m.npz", kind="demo", config={"width": 2},
      ...                params={"w": np.ones((2, 2)), "layers": (np.zeros(2),)})
      >>> sorted(load_model(p, kind="demo").arrays)
      ['layers/0', 'w']
    """
    path = pathlib.Path(path)
    arrays = _flatten(params)
    header = {
        "container": CONTAINER_VERSION,
        "kind": str(kind),
        "format_version": int(format_version),
        "config": dict(config),
        "extra": dict(extra or {}),
    }
    try:
        text = json.dumps(header, allow_nan=False)
    except (TypeError, ValueError) as err:
        raise MeshIOError(f"cannot write model {path}: config or extra is not JSON: {err}") from err
    buf = io.BytesIO()
    np.savez(buf, **{HEADER: np.asarray(text)}, **arrays)
    return atomic_write(path, buf.getvalue())


def _read(path: pathlib.Path, what: str) -> dict[str, np.ndarray]:
    if not path.exists():
        raise CorruptModelError(f"cannot read {what} {path}: no such file")
    if not path.is_file():
        raise CorruptModelError(f"cannot read {what} {path}: not a file")
    try:
        with open(path, "rb") as fh:  # closed even when np.load fails half-way
            data = np.load(fh, allow_pickle=False)
            if not hasattr(data, "files"):
                raise CorruptModelError(
                    f"cannot read {what} {path}: not a readable model file (a bare .npy array, not an .npz)"
                )
            with data:
                return {k: data[k] for k in data.files}
    except CorruptModelError:
        raise
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as err:
        raise CorruptModelError(
            f"cannot read {what} {path}: not a readable model file (truncated or damaged: {err})"
        ) from None
    except Exception as err:  # zlib/struct errors of a damaged archive
        raise CorruptModelError(
            f"cannot read {what} {path}: not a readable model file ({type(err).__name__}: {err})"
        ) from None


def read_arrays(path: str | os.PathLike, *, what: str = "model") -> dict[str, np.ndarray]:
    """Every entry of an ``.npz`` (no pickles); failures are :class:`~jmeshtex.CorruptModelError`.

    For readers of an older layout behind a version check; new files go through :func:`load_model`.

    Example:
      >>> import tempfile, numpy as np
      >>> p = save_model(tempfile.mkdtemp() + "/m.npz", kind="demo", config={},
      ...                params={"w": np.ones(2)})
      >>> sorted(read_arrays(p))
      ['__jmeshtex_model__', 'w']
    """
    return _read(pathlib.Path(path), what)


def load_model(
    path: str | os.PathLike,
    *,
    kind: str,
    like=None,
    format_versions: tuple[int, ...] = (1,),
    what: str | None = None,
) -> ModelFile:
    """Read a model file written by :func:`save_model`, checking its kind and version.

    Args:
      path: the file.
      kind: the kind it must hold.
      like: optional pytree of the expected parameters (arrays or :class:`jax.ShapeDtypeStruct`);
        with it the parameters come back in its structure and every shape and dtype is checked.
      format_versions: the layout versions the caller reads.
      what: how to call the model in messages (default: ``kind``).

    Returns:
      :class:`ModelFile` (NumPy arrays with their saved dtypes).

    Raises:
      CorruptModelError: the file is missing, truncated or not a model file, holds another kind or
        a version not in ``format_versions``, NaN or infinite numbers, or (with ``like``) arrays
        that do not match.

    Example:
      >>> import tempfile, numpy as np
      >>> p = save_model(tempfile.mkdtemp() + "/m.npz", kind="demo", config={"width": 2},
      ...                params={"w": np.ones(2)}, extra={"step": 3})
      >>> m = load_model(p, kind="demo")
      >>> m.config, m.extra, m.params["w"].tolist()
      ({'width': 2}, {'step': 3}, [1.0, 1.0])
      >>> load_model(p, kind="other")
      Traceback (most recent call last):
      ...
      jmeshtex._errors.CorruptModelError: .../m.npz holds a 'demo', not a 'other'
    """
    path = pathlib.Path(path)
    what = what or kind
    arrays = _read(path, what)
    if HEADER not in arrays:
        raise CorruptModelError(
            f"{path} is not a jmeshtex model file (no {HEADER} header); expected a {what}"
        )
    try:
        header = json.loads(str(arrays.pop(HEADER)))
        if not isinstance(header, dict):
            raise CorruptModelError(f"{path}: damaged model header (not a JSON object)")
        container = header["container"]
        stored_kind, version = header["kind"], header["format_version"]
        config, extra = header["config"], header.get("extra", {})
        if not isinstance(config, dict) or not isinstance(extra, dict):
            raise CorruptModelError(
                f"{path}: damaged model header (config and extra must be JSON objects)"
            )
    except (ValueError, KeyError, TypeError) as err:
        raise CorruptModelError(f"{path}: damaged model header ({err})") from None
    if container != CONTAINER_VERSION:
        raise CorruptModelError(
            f"{path} is a model file of container version {container!r}; this jmeshtex reads "
            f"version {CONTAINER_VERSION} (written by another jmeshtex version)"
        )
    if stored_kind != kind:
        raise CorruptModelError(f"{path} holds a {stored_kind!r}, not a {kind!r}")
    if version not in format_versions:
        raise CorruptModelError(
            f"{path}: {what} format version {version!r}; this jmeshtex reads "
            f"{', '.join(map(str, format_versions))} (written by another jmeshtex version)"
        )
    bad = sorted(
        name
        for name, a in arrays.items()
        if a.dtype.kind in "fc" and a.size and not np.isfinite(a).all()
    )
    if bad:  # a model trained to NaN, or bytes flipped inside an array
        shown = ", ".join(bad[:5]) + (f", ... ({len(bad) - 5} more)" if len(bad) > 5 else "")
        raise CorruptModelError(
            f"{path}: the {what} holds NaN or infinite numbers in {shown}; the file is damaged or "
            "was saved from a diverged run. Fix: train again, or use an earlier model file"
        )
    file = ModelFile(path, stored_kind, int(version), config, extra, arrays, _nested(arrays))
    if like is not None:
        file = dataclasses.replace(file, params=file.restore(like))
    return file

"""A method's model folder: ``model.npz`` in the one model format (:func:`jmeshtex.io.save_model`).

DGTS, the FL-VAE and FLDM save the same way: the model's type checked first (arguments swapped are
the usual slip), then one atomic ``model.npz`` written with the method's kind and format version.
"""

from __future__ import annotations

import os
import pathlib
from collections.abc import Callable, Mapping

from ._errors import InputError
from .io import save_model

#: the model file's name in a method's model folder
MODEL_FILE = "model.npz"


def save_model_folder(
    model,
    path: str | os.PathLike,
    *,
    model_type: type,
    kind: str,
    arrays: Callable,
    format_version: int,
    extra: Mapping | None = None,
) -> pathlib.Path:
    """Write ``arrays(model)`` and ``model.config`` as ``path/model.npz``, atomically; return the folder.

    Args:
      model: the method's model (its ``config.to_dict()`` is stored).
      path: the folder (created if needed; a model already there is replaced).
      model_type: the method's model class: anything else raises.
      kind: the file's kind, the model's qualified name (e.g. ``"jmeshtex.fl.Model"``).
      arrays: ``arrays(model)``: the pytree of host arrays to store.
      format_version: the method's layout version of those arrays.
      extra: JSON-able metadata stored beside them.

    Returns:
      The folder.

    Raises:
      InputError: ``model`` is not a ``model_type``.

    Example:
      >>> import tempfile, numpy as np
      >>> from jmeshtex.dgts import Config
      >>> class Tiny:
      ...     config = Config()
      >>> save_model_folder(Tiny(), tempfile.mkdtemp(), model_type=Tiny, kind="demo",
      ...                   arrays=lambda m: {"w": np.ones(2)}, format_version=1).joinpath(MODEL_FILE).is_file()
      True
      >>> save_model_folder(None, ".", model_type=Tiny, kind="demo.Model", arrays=dict,
      ...                   format_version=1)
      Traceback (most recent call last):
      ...
      jmeshtex._errors.InputError: save(model, path): expected a demo.Model first, got NoneType
    """
    if not isinstance(model, model_type):
        raise InputError(f"save(model, path): expected a {kind} first, got {type(model).__name__}")
    folder = pathlib.Path(path)
    save_model(
        folder / MODEL_FILE,
        kind=kind,
        params=arrays(model),
        config=model.config.to_dict(),
        extra=extra,
        format_version=format_version,
    )
    return folder

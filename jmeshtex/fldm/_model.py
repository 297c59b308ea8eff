"""The FLDM model: the denoiser's parameters with their config and latent scale, saved and loaded."""

from __future__ import annotations

import json
import os
import pathlib
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError, MeshIOError
from ._config import Config

MODEL_FILE = "model.npz"
MODEL_JSON = "model.json"


class Model(NamedTuple):
    """A trained (or freshly initialised) FLDM: the denoiser's parameters with their config and scale.

    Attributes:
      params: denoiser parameters (flax ``params`` dict, :func:`init_denoiser`).
      config: the :class:`Config`.
      scale: ``[d]`` latent scale ``s`` (train on ``s·μ``, decode ``z/s``; eq. 38–39).
    """

    params: dict
    config: Config
    scale: np.ndarray


def save(model: Model, path: str | os.PathLike) -> pathlib.Path:
    """Write ``model.npz`` (parameters) + ``model.json`` (config, scale) into the folder ``path``, atomically.

    Args:
      model: the :class:`Model` (e.g. ``train(...).model``).
      path: the folder (created if needed).

    Returns:
      The folder.

    Example:
      >>> import tempfile
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.fldm import build_dataset, init
      >>> cfg = Config.tiny(latent_channels=1, n_copies=1, copy_vertices=0, bucket=32)
      >>> data = build_dataset(icosphere(1), cfg, encode=lambda m: m.vertices[:, :1] + 0j,
      ...                      key=jax.random.key(0), progress=False)
      >>> folder = save(init(data, cfg, key=jax.random.key(1)), tempfile.mkdtemp())
      >>> load(folder).config == cfg
      True
    """
    from ..io import atomic_save_npz, atomic_write

    if not isinstance(model, Model):
        raise InputError(
            f"save(model, path): expected a jmeshtex.fldm.Model first, got {type(model).__name__}"
        )
    out = pathlib.Path(path)
    arrays = {
        "/".join(str(getattr(k, "key", k)) for k in kp): np.asarray(v)
        for kp, v in jax.tree_util.tree_flatten_with_path(model.params)[0]
    }
    atomic_save_npz(out / MODEL_FILE, arrays)
    meta = {"config": model.config.to_dict(), "scale": np.asarray(model.scale).tolist()}
    atomic_write(out / MODEL_JSON, json.dumps(meta, indent=2).encode())
    return out


def load(path: str | os.PathLike) -> Model:
    """Read a model written by :func:`save`.

    Args:
      path: the folder that holds ``model.npz`` and ``model.json``.

    Returns:
      The :class:`Model` (parameters as JAX arrays with their saved dtypes).

    Raises:
      MeshIOError: missing or unreadable files.
    """
    from ..io import load_npz

    out = pathlib.Path(path)
    if not (out / MODEL_JSON).is_file():
        raise MeshIOError(
            f"no FLDM model in {out} (expected {MODEL_JSON} and {MODEL_FILE}; train one with `jmeshtex fldm train`)"
        )
    meta = json.loads((out / MODEL_JSON).read_text())
    arrays = load_npz(out / MODEL_FILE, "FLDM model")
    params: dict = {}
    for name, value in arrays.items():
        node = params
        *parents, leaf = name.split("/")
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = jnp.asarray(value)
    return Model(params, Config.from_dict(meta["config"]), np.asarray(meta["scale"], np.float64))

"""The FLDM model: the denoiser's parameters with their config and latent scale, saved and loaded
(one ``model.npz`` in the model format of :func:`jmeshtex.io.save_model`)."""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import pathlib

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ConfigError, CorruptModelError
from .._model_folder import MODEL_FILE, save_model_folder
from ..io import load_model
from ._config import Config
from ._denoiser import init_denoiser

CARD_FILE = "card.json"
#: the ``kind`` recorded in an FLDM model file
MODEL_KIND = "jmeshtex.fldm.Model"
#: the layout of the file: parameters under ``params/...``, ``scale``, every config field in the
#: header; a file of another version is refused with a CorruptModelError naming it
FORMAT_VERSION = 2
_WHAT = "FLDM model"


@functools.partial(
    jax.tree_util.register_dataclass, data_fields=["params", "scale"], meta_fields=["config"]
)
@dataclasses.dataclass(frozen=True, eq=False)
class Model:
    """A trained (or freshly initialised) FLDM: the denoiser's parameters with their config and scale.

    A pytree whose config is static metadata (as every method's ``Model``): the parameters and
    the scale are its leaves, so a ``Model`` passes through ``jax.jit`` and ``jax.tree`` maps.

    Attributes:
      params: denoiser parameters (flax ``params`` dict, :func:`~jmeshtex.fldm.core.init_denoiser`).
      config: the :class:`Config`.
      scale: ``[d]`` latent scale ``s`` (train on ``s·μ``, decode ``z/s``; eq. 38–39).
    """

    params: dict
    config: Config
    scale: np.ndarray

    def __post_init__(self) -> None:
        if not isinstance(self.config, Config):
            raise ConfigError(
                f"Model.config must be a jmeshtex.fldm.Config, got {type(self.config).__name__}"
            )


def save(model: Model, path: str | os.PathLike, *, card: dict | None = None) -> pathlib.Path:
    """Write ``model`` as ``model.npz`` into the folder ``path``, atomically.

    The file is the one model format of :func:`jmeshtex.io.save_model`: the denoiser's parameters
    under ``params/...`` and the latent scale under ``scale``, with the config.

    Args:
      model: the :class:`Model` (e.g. ``train(...).model``).
      path: the folder (created if needed; a model already there is replaced).
      card: a JSON-able model card written next to it as ``card.json`` (e.g. the training's
        steps, losses and the decoder-free statistics of ``TrainResult.extra["statistics"]``:
        :func:`~jmeshtex.fldm.core.model_card`); None: none (an old card there is left as it is).

    Returns:
      The folder.

    Example:
      >>> import tempfile
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.fldm import Config, build_dataset, init, load, save
      >>> cfg = Config.tiny(latent_channels=1, n_copies=1, copy_vertices=0, bucket=32)
      >>> data = build_dataset(icosphere(1), cfg, encode=lambda m: m.vertices[:, :1] + 0j,
      ...                      key=jax.random.key(0), progress=False)
      >>> folder = save(init(data, cfg, key=jax.random.key(1)), tempfile.mkdtemp())
      >>> load(folder).config == cfg
      True
    """
    out = save_model_folder(
        model,
        path,
        model_type=Model,
        kind=MODEL_KIND,
        arrays=_arrays,
        format_version=FORMAT_VERSION,
    )
    if card is not None:
        from ..io import atomic_write

        text = json.dumps({"config": model.config.to_dict(), **card}, indent=1, default=float)
        atomic_write(out / CARD_FILE, text.encode())
    return out


def _arrays(model: Model) -> dict:
    """What :func:`save` stores: the parameters and the latents' scale (float64)."""
    return {
        "params": jax.tree.map(np.asarray, model.params),
        "scale": np.asarray(model.scale, np.float64),
    }


def model_card(result) -> dict:
    """The card of a trained model (:func:`~jmeshtex.fldm.save`'s ``card``): steps, final loss and statistics.

    Args:
      result: the :class:`~jmeshtex.TrainResult` of :func:`~jmeshtex.fldm.train`.

    Returns:
      ``{"steps", "final_loss", "statistics"}``: ``statistics`` the decoder-free statistics logged
      at each checkpoint (:func:`~jmeshtex.fldm.core.latent_statistics`; empty without
      ``config.experimental.stats_samples``).
    """
    return {
        "steps": int(result.steps),
        "final_loss": float(result.final_loss()),
        "statistics": list(result.extra.get("statistics", [])),
    }


def _model(params: dict, config: Config, scale) -> Model:
    return Model(jax.tree.map(jnp.asarray, params), config, np.asarray(scale, np.float64))


def load(path: str | os.PathLike) -> Model:
    """Read a model written by :func:`save`.

    Args:
      path: the folder that holds ``model.npz``.

    Returns:
      The :class:`Model` (parameters as JAX arrays with their saved dtypes).

    Raises:
      CorruptModelError: no model in the folder, or a truncated, damaged or foreign file.

    Example:
      >>> import tempfile
      >>> load(tempfile.mkdtemp())
      Traceback (most recent call last):
      ...
      jmeshtex._errors.CorruptModelError: no FLDM model in ...
    """
    out = pathlib.Path(path)
    if not (out / MODEL_FILE).is_file():
        raise CorruptModelError(
            f"no FLDM model in {out} (expected {MODEL_FILE}; train one with `jmeshtex fldm train`)"
        )
    file = load_model(
        out / MODEL_FILE, kind=MODEL_KIND, format_versions=(FORMAT_VERSION,), what=_WHAT
    )
    config = file.config_as(Config)
    shapes = jax.eval_shape(lambda k: init_denoiser(k, config), jax.random.key(0))
    # parameters saved from a float64 run (complex128 weights) are restored as such
    if any(a.dtype == np.complex128 for n, a in file.arrays.items() if n.startswith("params/")):
        wide = {np.dtype(np.complex64): np.complex128, np.dtype(np.float32): np.float64}
        shapes = jax.tree.map(
            lambda x: jax.ShapeDtypeStruct(x.shape, wide.get(np.dtype(x.dtype), x.dtype)), shapes
        )
    like = {
        "params": shapes,
        "scale": jax.ShapeDtypeStruct((config.latent_channels,), np.float64),
    }
    tree = file.restore(like)  # every array's key path, shape and dtype checked against the config
    return _model(tree["params"], config, tree["scale"])

"""FL-VAE model files: :func:`save` / :func:`load` / :func:`load_extra` and the models shipped in
``jmeshtex/fl/weights``.

A model file is the one model format of :func:`jmeshtex.io.save_model` (one ``.npz``: the
parameters by key path, the config and the ``extra`` metadata as JSON), written atomically. One format version is read (:data:`FORMAT_VERSION`, whose header holds every
config field); a file of another version is refused with a :class:`~jmeshtex.CorruptModelError`
that names its version.
"""

from __future__ import annotations

import os
import pathlib

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ConfigError, CorruptModelError, MeshIOError
from .._model_folder import MODEL_FILE, save_model_folder
from ..io import load_model
from ._config import Config
from ._model import Model, init

WEIGHTS_DIR = pathlib.Path(__file__).parent / "weights"
#: the shipped models, by decoder variant (``weights/README.md`` says how they were trained)
_PRETRAINED = {
    "log": WEIGHTS_DIR / "fl_vae.npz",
    "barycentric": WEIGHTS_DIR / "fl_vae_barycentric.npz",
}
#: the ``kind`` recorded in an FL-VAE model file
MODEL_KIND = "jmeshtex.fl.Model"
#: the layout of the file: parameters by key path, every config field in the header
FORMAT_VERSION = 2
_WHAT = "FL-VAE model"


def save(model: Model, path: str | os.PathLike, *, extra: dict | None = None) -> pathlib.Path:
    """Write a model (parameters and config) as ``model.npz`` into the folder ``path``, atomically.

    Args:
      model: :class:`~jmeshtex.fl.Model`.
      path: the folder (created if needed; a model already there is replaced).
      extra: optional JSON-serialisable metadata (e.g. the training step) stored in the file; read
        it back with :func:`load_extra`.

    Returns:
      The folder.

    Raises:
      InputError: ``model`` is not a :class:`~jmeshtex.fl.Model` (e.g. the arguments swapped).

    Example:
      >>> import jax, tempfile
      >>> from jmeshtex.fl import Config, init
      >>> model = init(Config(features=8, num_heads=2), key=jax.random.key(0))
      >>> folder = save(model, tempfile.mkdtemp(), extra={"step": 3})
      >>> back = load(folder)
      >>> back.config == model.config and all(bool((a == b).all()) for a, b in
      ...     zip(jax.tree.leaves(model.params), jax.tree.leaves(back.params)))
      True
      >>> load_extra(folder), sorted(p.name for p in folder.iterdir())
      ({'step': 3}, ['model.npz'])
    """
    return save_model_folder(
        model,
        path,
        model_type=Model,
        kind=MODEL_KIND,
        arrays=lambda m: jax.tree.map(np.asarray, m.params),
        format_version=FORMAT_VERSION,
        extra=extra,
    )


def _file(path: str | os.PathLike) -> pathlib.Path:
    """The model file of ``path``: ``path/model.npz`` for a folder, else ``path`` itself (a model
    file, such as the shipped ones)."""
    path = pathlib.Path(path)
    if path.is_dir():
        if not (path / MODEL_FILE).is_file():
            raise CorruptModelError(
                f"no FL-VAE model in {path} (expected {MODEL_FILE}; train one with "
                "`jmeshtex fl train`)"
            )
        return path / MODEL_FILE
    return path


def _like(config: Config, real) -> object:
    return jax.eval_shape(lambda k: init(config, key=k, dtype=real).params, jax.random.key(0))


def _load(path: str | os.PathLike) -> tuple[Model, dict]:
    path = _file(path)
    file = load_model(path, kind=MODEL_KIND, format_versions=(FORMAT_VERSION,), what=_WHAT)
    config = file.config_as(Config)
    mean = file.arrays.get("encoder/mean")
    real = jnp.float64 if mean is not None and mean.dtype == np.complex128 else jnp.float32
    params = file.restore(_like(config, real))
    return Model(jax.tree.map(jnp.asarray, params), config), file.extra


def load(path: str | os.PathLike) -> Model:
    """Read a model written by :func:`save`.

    Args:
      path: the folder :func:`save` wrote (or a model file itself, such as the shipped ones).

    Returns:
      :class:`~jmeshtex.fl.Model`.

    Raises:
      CorruptModelError: missing, truncated or foreign file, another method's model, an unknown
        format version, or arrays that do not match the stored config.

    Example:
      >>> model = load(_PRETRAINED["log"])
      >>> model.config.latent_dim, model.config.decoder
      (8, 'log')
    """
    return _load(path)[0]


def load_extra(path: str | os.PathLike) -> dict:
    """The ``extra`` metadata stored with a model by :func:`save` (``{}`` if none).

    Args:
      path: as in :func:`load`.

    Returns:
      The JSON metadata as a dict (the CLI stores the training step, seed and data there).

    Raises:
      CorruptModelError: as :func:`load`.

    Example:
      >>> import jax, tempfile, pathlib
      >>> from jmeshtex.fl import Config, init
      >>> model = init(Config(features=8, num_heads=2), key=jax.random.key(0))
      >>> load_extra(save(model, pathlib.Path(tempfile.mkdtemp()) / "m", extra={"seed": 1}))
      {'seed': 1}
    """
    return _load(path)[1]


def load_pretrained(*, decoder: str = "log") -> Model:
    """The small FL-VAE shipped in ``jmeshtex/fl/weights`` (see its README for how it was trained).

    Args:
      decoder: ``"log"`` (the FL-VAE, default) or ``"barycentric"`` (the paper's ablation, trained
        with the same data and steps; scored in ``docs/results.md``).

    Returns:
      :class:`~jmeshtex.fl.Model`.

    Raises:
      ConfigError: unknown ``decoder``.
      MeshIOError: the package was installed without the weights file.

    Example:
      >>> model = load_pretrained()
      >>> model.config.latent_dim, model.config.decoder
      (8, 'log')
    """
    if decoder not in _PRETRAINED:
        raise ConfigError(f"decoder must be one of {sorted(_PRETRAINED)}, got {decoder!r}")
    path = _PRETRAINED[decoder]
    if not path.is_file():
        raise MeshIOError(
            f"no pre-trained FL-VAE shipped at {path}. Fix: train one with "
            "`jmeshtex fl train --preset small --out DIR` and load it with jmeshtex.fl.load(DIR)"
        )
    return load(path)

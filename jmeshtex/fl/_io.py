"""FL-VAE model files: :func:`save` / :func:`load` / :func:`load_extra` and the models shipped in
``jmeshtex/fl/weights``.

A model file is the one model format of :func:`jmeshtex.io.save_model` (one ``.npz``: the
parameters by key path, the config and the ``extra`` metadata as JSON), written atomically. Files
of the earlier layout (``leaf_0000`` ... in pytree order and a ``meta`` entry of UTF-8 JSON) are
read behind a version check.
"""

from __future__ import annotations

import json
import os
import pathlib

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ConfigError, CorruptModelError, MeshIOError
from ..io import load_model, read_arrays, save_model
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
#: the layout of the parameters in the file (0: the earlier ``leaf_0000`` layout, read only)
FORMAT_VERSION = 1
_WHAT = "FL-VAE model"


def save(model: Model, path: str | os.PathLike, *, extra: dict | None = None) -> pathlib.Path:
    """Write a model (parameters and config) to one ``.npz`` file atomically.

    Args:
      model: :class:`~jmeshtex.fl.Model`.
      path: target file (``.npz``); folders are created.
      extra: optional JSON-serialisable metadata (e.g. the training step) stored alongside; read it
        back with :func:`load_extra`.

    Returns:
      The path written.

    Example:
      >>> import jax, tempfile, pathlib
      >>> from jmeshtex.fl import Config, init
      >>> model = init(Config(features=8, num_heads=2), key=jax.random.key(0))
      >>> path = save(model, pathlib.Path(tempfile.mkdtemp()) / "m.npz", extra={"step": 3})
      >>> back = load(path)
      >>> back.config == model.config and all(bool((a == b).all()) for a, b in
      ...     zip(jax.tree.leaves(model.params), jax.tree.leaves(back.params)))
      True
      >>> load_extra(path)
      {'step': 3}
    """
    if not isinstance(model, Model):
        raise ConfigError(f"save expects a jmeshtex.fl.Model, got {type(model).__name__}")
    return save_model(
        path,
        kind=MODEL_KIND,
        params=jax.tree.map(np.asarray, model.params),
        config=model.config.to_dict(),
        extra=extra,
        format_version=FORMAT_VERSION,
    )


def _like(config: Config, real) -> object:
    return jax.eval_shape(lambda k: init(config, key=k, dtype=real).params, jax.random.key(0))


def _is_legacy(arrays: dict) -> bool:
    return "meta" in arrays and all(k == "meta" or k.startswith("leaf_") for k in arrays)


def _load_legacy(path: pathlib.Path, arrays: dict) -> tuple[Model, dict]:
    """Format version 0: ``leaf_0000`` ... in pytree order, ``meta`` UTF-8 JSON bytes."""
    try:
        meta = json.loads(arrays.pop("meta").tobytes().decode())
        config = Config.from_stored(meta["config"])  # fields it lacks: the writer's behaviour
        leaves = [arrays[f"leaf_{i:04d}"] for i in range(int(meta["num_leaves"]))]
        extra = meta.get("extra", {})
    except (ValueError, KeyError, TypeError) as err:
        raise CorruptModelError(f"cannot read {_WHAT} {path} (earlier layout): {err}") from None
    real = jnp.float64 if leaves and leaves[0].dtype == np.float64 else jnp.float32
    flat, treedef = jax.tree.flatten(_like(config, real))
    if len(flat) != len(leaves) or any(
        a.shape != tuple(b.shape) for a, b in zip(flat, leaves, strict=True)
    ):
        raise CorruptModelError(
            f"{_WHAT} {path}: stored arrays do not match its config (corrupt or foreign file)"
        )
    return Model(jax.tree.unflatten(treedef, [jnp.asarray(x) for x in leaves]), config), extra


def _load(path: str | os.PathLike) -> tuple[Model, dict]:
    path = pathlib.Path(path)
    arrays = read_arrays(path, what=_WHAT)
    if _is_legacy(arrays):
        return _load_legacy(path, arrays)
    file = load_model(path, kind=MODEL_KIND, format_versions=(FORMAT_VERSION,), what=_WHAT)
    try:  # fields the file lacks mean the behaviour of the version that wrote it
        config = Config.from_stored(file.config)
    except (ValueError, TypeError, KeyError) as err:
        raise CorruptModelError(
            f"model file {path}: its stored config is not a valid fl.Config: {err}"
        ) from err
    mean = file.arrays.get("encoder/mean")
    real = jnp.float64 if mean is not None and mean.dtype == np.complex128 else jnp.float32
    params = file.restore(_like(config, real))
    return Model(jax.tree.map(jnp.asarray, params), config), file.extra


def load(path: str | os.PathLike) -> Model:
    """Read a model written by :func:`save`.

    Args:
      path: the ``.npz`` file.

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
      path: the ``.npz`` file.

    Returns:
      The JSON metadata as a dict (the CLI stores the training step, seed and data there).

    Raises:
      CorruptModelError: as :func:`load`.

    Example:
      >>> import jax, tempfile, pathlib
      >>> from jmeshtex.fl import Config, init
      >>> model = init(Config(features=8, num_heads=2), key=jax.random.key(0))
      >>> load_extra(save(model, pathlib.Path(tempfile.mkdtemp()) / "m.npz", extra={"seed": 1}))
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
            "`jmeshtex fl train --preset small --out DIR` and load it with jmeshtex.fl.load(DIR/'fl_vae.npz')"
        )
    return load(path)

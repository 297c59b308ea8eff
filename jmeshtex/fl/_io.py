"""FL-VAE model files: :func:`save` / :func:`load` and the model shipped in ``jmeshtex/fl/weights``.

A model file is one ``.npz``: the parameter leaves (``leaf_0000`` ...) in pytree order and a
``meta`` entry, UTF-8 JSON ``{"config": Config.to_dict(), "num_leaves": n, "extra": {...}}``.
Files are written atomically (temporary file + rename).
"""

from __future__ import annotations

import io
import json
import os
import pathlib

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ConfigError, MeshIOError
from ..io import atomic_write
from ._config import Config
from ._model import Model, init

WEIGHTS_DIR = pathlib.Path(__file__).parent / "weights"
#: the shipped models, by decoder variant (``weights/README.md`` says how they were trained)
_PRETRAINED = {
    "log": WEIGHTS_DIR / "fl_vae.npz",
    "barycentric": WEIGHTS_DIR / "fl_vae_barycentric.npz",
}


def save(model: Model, path: str | os.PathLike, *, extra: dict | None = None) -> pathlib.Path:
    """Write a model (parameters and config) to one ``.npz`` file atomically.

    Args:
      model: :class:`~jmeshtex.fl.Model`.
      path: target file (``.npz``); folders are created.
      extra: optional JSON-serialisable metadata (e.g. the training step) stored alongside.

    Returns:
      The path written.

    Example:
      >>> import jax, tempfile, pathlib
      >>> from jmeshtex.fl import Config, init
      >>> model = init(Config(features=8, num_heads=2), key=jax.random.key(0))
      >>> path = save(model, pathlib.Path(tempfile.mkdtemp()) / "m.npz")
      >>> back = load(path)
      >>> back.config == model.config and all(bool((a == b).all()) for a, b in
      ...     zip(jax.tree.leaves(model.params), jax.tree.leaves(back.params)))
      True
    """
    if not isinstance(model, Model):
        raise ConfigError(f"save expects a jmeshtex.fl.Model, got {type(model).__name__}")
    path = pathlib.Path(path)
    leaves = jax.tree.leaves(model.params)
    arrays = {f"leaf_{i:04d}": np.asarray(leaf) for i, leaf in enumerate(leaves)}
    meta = {"config": model.config.to_dict(), "num_leaves": len(leaves), "extra": extra or {}}
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write(path, buf.getvalue())
    return path


def load(path: str | os.PathLike, *, with_extra: bool = False):
    """Read a model written by :func:`save`.

    Args:
      path: the ``.npz`` file.
      with_extra: also return the ``extra`` metadata stored with it.

    Returns:
      :class:`~jmeshtex.fl.Model`, or ``(Model, extra)`` with ``with_extra=True``.

    Raises:
      MeshIOError: missing or unreadable file, or leaves that do not match the config.

    Example:
      >>> model = load(_PRETRAINED["log"])
      >>> model.config.latent_dim, model.config.decoder
      (8, 'log')
    """
    path = pathlib.Path(path)
    if not path.is_file():
        raise MeshIOError(f"cannot read FL-VAE model {path}: no such file")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        meta = json.loads(arrays.pop("meta").tobytes().decode())
        config = Config.from_dict(meta["config"])
        leaves = [arrays[f"leaf_{i:04d}"] for i in range(meta["num_leaves"])]
    except (OSError, ValueError, KeyError) as err:
        raise MeshIOError(f"cannot read FL-VAE model {path}: {err}") from err
    real = jnp.float64 if leaves and leaves[0].dtype == np.float64 else jnp.float32
    shapes = jax.eval_shape(lambda k: init(config, key=k, dtype=real).params, jax.random.key(0))
    flat, treedef = jax.tree.flatten(shapes)
    if len(flat) != len(leaves) or any(
        a.shape != tuple(b.shape) for a, b in zip(flat, leaves, strict=True)
    ):
        raise MeshIOError(
            f"FL-VAE model {path}: stored arrays do not match its config (corrupt or foreign file)"
        )
    model = Model(jax.tree.unflatten(treedef, [jnp.asarray(x) for x in leaves]), config)
    return (model, meta.get("extra", {})) if with_extra else model


def load_pretrained(*, decoder: str = "log") -> Model:
    """The small FL-VAE shipped in ``jmeshtex/fl/weights`` (see its README for how it was trained).

    Args:
      decoder: ``"log"`` (the FL-VAE, default) or ``"barycentric"`` (the paper's ablation, trained
        with the same data and steps; used by ``benchmarks/fl_vae.py``).

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

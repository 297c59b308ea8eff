"""The DGTS model shipped with the package: knobs learnt on a sphere (``jmeshtex/dgts/weights``)."""

from __future__ import annotations

import pathlib

from .._errors import ConfigError, MeshIOError
from ._model import Model, load
from ._multiscale import TrainingMeshes, load_training_meshes

WEIGHTS_DIR = pathlib.Path(__file__).parent / "weights"

#: the shipped models: name -> (model file, training-mesh file, the reference's texture period in
#: the reference's units)
_PRETRAINED = {
    "knobs": ("knobs.npz", "knobs_training_meshes.npz", 0.45),
}


def _known(name: str) -> tuple:
    if name not in _PRETRAINED:
        raise ConfigError(f"no shipped DGTS model {name!r}; shipped: {sorted(_PRETRAINED)}")
    return _PRETRAINED[name]


def _file(name: str, which: int) -> pathlib.Path:
    path = WEIGHTS_DIR / _known(name)[which]
    if not path.is_file():
        raise MeshIOError(
            f"no shipped DGTS model at {path} (the package was installed without its weights). "
            "Fix: reinstall jmeshtex, or train one with `jmeshtex dgts train`"
        )
    return path


def load_pretrained(name: str = "knobs") -> Model:
    """A DGTS model shipped in ``jmeshtex/dgts/weights`` (its README says how it was trained).

    ``"knobs"``: the paper's network (7 layers, 32 to 128 channels), 4 levels x 1,000 steps on a
    sphere with knobs of period 0.45. Transfer it from level 1 (the official default start) with
    :func:`~jmeshtex.dgts.transfer`.

    Args:
      name: which shipped model (``"knobs"``).

    Returns:
      The :class:`~jmeshtex.dgts.Model`.

    Raises:
      ConfigError: unknown ``name``.
      MeshIOError: the package was installed without the weights file.

    Example:
      >>> model = load_pretrained()
      >>> model.num_levels, model.config.num_layers
      (4, 7)
    """
    return load(_file(name, 0))


def pretrained_training_meshes(name: str = "knobs") -> TrainingMeshes:
    """The training meshes a shipped model was trained on (for untrained weights of the same
    architecture, ``train(meshes, model.config.replace(steps=0), ...)``, and for the period in
    mean edges, :func:`~jmeshtex.dgts.core.period_in_mean_edges`).

    Example:
      >>> meshes = pretrained_training_meshes()
      >>> meshes.num_levels, pretrained_period()
      (4, 0.45)
    """
    return load_training_meshes(_file(name, 1))


def pretrained_period(name: str = "knobs") -> float:
    """The texture period of a shipped model's reference, in the reference's units."""
    return _known(name)[2]

"""The FLDM model shipped with the package: Spot's texture (``jmeshtex/fldm/weights``)."""

from __future__ import annotations

import pathlib

from .._errors import ConfigError, MeshIOError
from ._model import MODEL_FILE, Model, load

WEIGHTS_DIR = pathlib.Path(__file__).parent / "weights"

#: the shipped models: name -> folder (``model.npz`` + ``card.json``) under :data:`WEIGHTS_DIR`
_PRETRAINED = {"spot": "spot"}


def load_pretrained(name: str = "spot") -> Model:
    """An FLDM model shipped in ``jmeshtex/fldm/weights`` (its README says how it was trained and
    how good its samples are).

    ``"spot"``: :meth:`Config.cpu <jmeshtex.fldm.Config.cpu>` trained 10,000 steps on the shipped
    FL-VAE's latents (:func:`jmeshtex.fl.load_pretrained`) of 16 re-triangulations of Spot
    (:func:`jmeshtex.data.spot`) at 10,000 vertices, the FL-VAE's training density, with the
    latents' phases on flat rings synchronised (``phase_sync="flat"``, beyond the paper:
    :func:`~jmeshtex.fldm.core.synchronize_phases`). Sample it on
    a mesh of about that density (Spot midpoint-subdivided once: 11.7K vertices) and decode the
    samples with that FL-VAE (:func:`~jmeshtex.fldm.decode_samples`).

    Args:
      name: which shipped model (``"spot"``).

    Returns:
      The :class:`~jmeshtex.fldm.Model`.

    Raises:
      ConfigError: unknown ``name``.
      MeshIOError: the package was installed without the weights.

    Example:
      >>> model = load_pretrained()
      >>> model.config.copy_vertices, model.config.latent_channels, model.config.steps
      (10000, 8, 10000)
    """
    if name not in _PRETRAINED:
        raise ConfigError(f"no shipped FLDM model {name!r}; shipped: {sorted(_PRETRAINED)}")
    folder = WEIGHTS_DIR / _PRETRAINED[name]
    if not (folder / MODEL_FILE).is_file():
        raise MeshIOError(
            f"no shipped FLDM model at {folder} (the package was installed without its weights). "
            "Fix: reinstall jmeshtex, or train one with `jmeshtex fldm train`"
        )
    return load(folder)

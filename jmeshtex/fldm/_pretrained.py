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

    ``"spot"``: trained on the shipped FL-VAE's latents (:func:`jmeshtex.fl.load_pretrained`) of
    re-triangulated copies of Spot (:func:`jmeshtex.data.spot`) at about 3K vertices, Spot's own
    density, with the flat rings' phases synchronised (``config.phase_sync == "flat"``, beyond the
    paper). Decode its samples with that FL-VAE (:func:`~jmeshtex.fldm.decode_samples`).

    Args:
      name: which shipped model (``"spot"``).

    Returns:
      The :class:`~jmeshtex.fldm.Model`.

    Raises:
      ConfigError: unknown ``name``.
      MeshIOError: the package was installed without the weights.

    Example:
      >>> model = load_pretrained()
      >>> model.config.phase_sync, model.config.latent_channels
      ('flat', 8)
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

"""DGTS: learn a geometric texture from one mesh and transfer it to any mesh (Hertz et al. 2020).

Pipeline: :func:`training_meshes` (multi-scale fitting of a template to the reference, §3.3,
configured by :class:`PrepareConfig`) → :func:`train` (hierarchical WGAN-GP, §3.4, configured by
:class:`Config`, resumable checkpoints, on one fit or several, e.g. remeshes from turned
templates; returns a :class:`~jmeshtex.TrainResult` holding a :class:`Model`) → :func:`save` /
:func:`load` → :func:`transfer` / :func:`interpolate` (any target
mesh, open or closed, any genus, no re-meshing; a :class:`Transfer`). Levels run: by default
jmeshtex's own choice, from the level whose training mesh has the target's face count (within a
face budget, ``max_faces``) to the last; the official code's ``--gen-levels`` (default ``[1, 4]``)
are ``start_level`` / ``stop_level``, clipped to the model as the official code does by
:func:`~jmeshtex.dgts.official_gen_levels`.

Inference modes: zero noise above a level (``transfer(..., zero_noise_from=k)``), the training
reconstruction (:func:`reconstruct`), conditional generation at scale ``k`` (:func:`conditional`:
``z*`` below ``k``, fresh noise above), every level's output (``per_level=True``), training snapshots
(``train(..., snapshot_every=N)``). Structure measures (:func:`~jmeshtex.dgts.core.peak_statistics`,
:func:`~jmeshtex.dgts.core.height_autocorrelation_length`,
:func:`~jmeshtex.dgts.core.reconstruction_errors`, :func:`~jmeshtex.dgts.core.texture_scores`) are in
:mod:`jmeshtex.dgts.core`.

The building blocks (the generator and discriminator of one level, the gradient penalty, the two
halves of a transfer, the template fit of one level) are in :mod:`jmeshtex.dgts.core`.

Models trained with the official code (amirhertz/geometric-textures): export the generator's
``state_dict`` to ``.npz`` and read it with :func:`load_official` (or :func:`from_official_state_dict`);
the converted model reproduces the official outputs (tested against the official network's outputs on the same weights, ``tests/dgts/test_official_parity.py``).
One official training iteration at two levels (``tests/dgts/test_official_training.py``) and the
official inference with ``--gen-levels`` (``tests/dgts/test_official_inference.py``) are reproduced
too, from numbers the official code produced.

Example:
  >>> import jax
  >>> from jmeshtex import dgts
  >>> from jmeshtex.data import icosahedron, icosphere, torus
  >>> meshes = dgts.training_meshes(icosphere(2), icosahedron(), config=dgts.PrepareConfig(levels=2, steps=5),
  ...                               key=jax.random.key(0), progress=False)
  >>> config = dgts.Config(num_layers=3, start_features=4, min_features=4, max_features=4, steps=2)
  >>> result = dgts.train(meshes, config, key=jax.random.key(1), progress=False)
  >>> out = dgts.transfer(result.model, torus(8, 6), key=jax.random.key(2))
  >>> out.vertices.shape, out.start_level  # 96 target faces: level 1's resolution (20 x 4)
  ((1, 48, 3), 1)
"""

from .._errors import FaceBudgetError as FaceBudgetError
from .._extras import needs_methods as _needs_methods  # noqa: F401 (names a missing extra)
from .._train_result import TrainResult as TrainResult
from . import core as core  # the building blocks
from ._config import Config as Config
from ._config import PrepareConfig as PrepareConfig
from ._model import Model as Model
from ._model import load as load
from ._model import save as save
from ._multiscale import TrainingMeshes as TrainingMeshes
from ._multiscale import load_training_meshes as load_training_meshes
from ._multiscale import save_training_meshes as save_training_meshes
from ._multiscale import training_meshes as training_meshes
from ._official import from_official_state_dict as from_official_state_dict
from ._official import load_official as load_official
from ._pretrained import load_pretrained as load_pretrained
from ._pretrained import pretrained_period as pretrained_period
from ._pretrained import pretrained_training_meshes as pretrained_training_meshes
from ._train import LevelReport as LevelReport
from ._train import train as train
from ._transfer import Transfer as Transfer
from ._transfer import conditional as conditional
from ._transfer import interpolate as interpolate
from ._transfer import official_gen_levels as official_gen_levels
from ._transfer import reconstruct as reconstruct
from ._transfer import transfer as transfer

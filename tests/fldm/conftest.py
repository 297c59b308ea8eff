"""Shared FLDM fixtures: models trained once per session and reused by every test that trains with
the same settings (the same exemplar, configuration, data key and training key give the same model,
so a test that takes the fixture sees exactly what it would have trained itself).

- ``striped_exemplar``: the learning check's striped sphere (icosphere(3), 642 vertices);
- ``striped_data`` / ``striped_model``: the learning check's tiny configuration
  (``fldm.Config.demo()``: 4 copies × 500 vertices, 300 steps, T = 200) with the analytic stripe
  codec, copies drawn with :data:`DATA_KEY` and training with :data:`TRAIN_KEY`;
- ``tiny_sphere`` / ``tiny_data``: the three 80-vertex copies of the striped icosphere(2) that the
  pipeline tests (``test_fldm.py``) and the mask-conditioning tests train their few-step models
  on: the copies depend only on the configuration's dataset fields (:data:`TINY_DATA_FIELDS`),
  which the two test configurations share (each checks it with :func:`uses_tiny_data`).
"""

from __future__ import annotations

import jax
import pytest

from jmeshtex import Mesh, fldm
from jmeshtex.data import stripe_encoder, striped_sphere

#: keys of the striped-sphere model's copies and of its training
DATA_KEY, TRAIN_KEY = jax.random.key(10), jax.random.key(11)


@pytest.fixture(scope="session")
def striped_exemplar() -> Mesh:
    return striped_sphere(subdivisions=3)


def _stripe_dataset(mesh: Mesh, config: fldm.Config, key: jax.Array) -> fldm.Dataset:
    return fldm.build_dataset(mesh, config, encode=stripe_encoder, key=key, progress=False)


@pytest.fixture(scope="session")
def striped_data(striped_exemplar) -> fldm.Dataset:
    return _stripe_dataset(striped_exemplar, fldm.Config.demo(), DATA_KEY)


@pytest.fixture(scope="session")
def striped_model(striped_data) -> fldm.Model:
    return fldm.train(striped_data, fldm.Config.demo(), key=TRAIN_KEY, progress=False).model


#: the Config fields :func:`jmeshtex.fldm.build_dataset` reads
TINY_DATA_FIELDS = (
    "latent_channels",
    "n_copies",
    "copy_vertices",
    "knn",
    "pool_ratio",
    "bucket",
    "num_labels",
    "encodings_per_copy",
    "latent_scaling",
    "phase_sync",
    "flat_spread",
)
#: the dataset settings of ``tiny_data`` (the training fields are the tests' own)
TINY_DATA = fldm.Config.tiny(latent_channels=2, n_copies=3, copy_vertices=80, knn=7, bucket=32)
#: the key of ``tiny_data``'s copies
TINY_DATA_KEY = jax.random.key(0)
#: the few-step training settings on ``tiny_data`` that ``test_fldm.py`` and the mask-conditioning
#: tests share (each adds its own ``steps`` and switches)
TINY_TRAIN = TINY_DATA.replace(widths=(6, 8), hdim=4, diffusion_steps=50, batch_size=2)
#: ``jmeshtex fldm train`` on the tiny preset, 2 copies × 60 vertices, 2 steps (the CLI tests add
#: ``--mesh``, ``--out`` and their own flags)
TINY_CLI_TRAIN = (
    "fldm",
    "train",
    "--preset",
    "tiny",
    "--copies",
    "2",
    "--vertices",
    "60",
    "--steps",
    "2",
)


def uses_tiny_data(config: fldm.Config) -> bool:
    """Whether ``config`` builds the same copies as ``tiny_data`` (so a test may take the fixture)."""
    mine, theirs = config.to_dict(), TINY_DATA.to_dict()  # flat: the experimental fields too
    return all(mine[f] == theirs[f] for f in TINY_DATA_FIELDS)


@pytest.fixture(scope="session")
def tiny_sphere() -> Mesh:
    return striped_sphere(subdivisions=2)


@pytest.fixture(scope="session")
def tiny_data(tiny_sphere) -> fldm.Dataset:
    return _stripe_dataset(tiny_sphere, TINY_DATA, TINY_DATA_KEY)

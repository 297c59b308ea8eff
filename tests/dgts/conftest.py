"""Shared tiny DGTS fixtures (small meshes and networks so the whole folder stays fast)."""

from __future__ import annotations

import jax
import pytest

from jmeshtex.data import icosahedron, icosphere
from jmeshtex.dgts import Config, PrepareConfig, train, training_meshes

TINY = Config(
    num_layers=3, start_features=4, min_features=4, max_features=4, steps=2, shared_levels=2
)
#: the key the tiny model is trained with
TINY_KEY = 3


def _tiny_fit(**extra):
    """Two levels (20 → 80 faces) of an icosahedron fitted to an icosphere (few steps)."""
    return training_meshes(
        icosphere(2),
        icosahedron(),
        config=PrepareConfig(levels=2, steps=20, samples_per_level=200),
        key=jax.random.key(0),
        progress=False,
        **extra,
    )


@pytest.fixture(scope="session")
def tiny_meshes():
    return _tiny_fit()


@pytest.fixture(scope="session")
def tiny_remeshed():
    """The same reference fitted from a turned template: a second remesh of one reference."""
    return _tiny_fit(rotation=[[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


@pytest.fixture(scope="session")
def tiny_result(tiny_meshes):
    return train(tiny_meshes, TINY, key=jax.random.key(TINY_KEY), progress=False)


@pytest.fixture(scope="session")
def tiny_model(tiny_result):
    return tiny_result.model

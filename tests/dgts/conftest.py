"""Shared tiny DGTS fixtures (small meshes and networks so the whole folder stays fast)."""

from __future__ import annotations

import pytest

from jmeshtex.data import icosahedron, icosphere
from jmeshtex.dgts import PrepareConfig, TrainConfig, train, training_meshes

TINY = TrainConfig(num_layers=3, start_features=4, min_features=4, max_features=4, iterations=2, seed=3,
                   shared_levels=2)


@pytest.fixture(scope="session")
def tiny_meshes():
    """Two levels (20 → 80 faces) of an icosahedron fitted to an icosphere (few steps)."""
    return training_meshes(icosphere(2), icosahedron(), config=PrepareConfig(num_levels=2, iterations=20, samples_per_level=200))


@pytest.fixture(scope="session")
def tiny_model(tiny_meshes):
    model, _ = train(tiny_meshes, TINY, progress=False)
    return model

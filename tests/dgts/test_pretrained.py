"""The shipped DGTS model: it loads, and its transfer is told apart from its baselines."""

from __future__ import annotations

import jax
import pytest

from jmeshtex import ConfigError, dgts
from jmeshtex.data import torus
from jmeshtex.dgts.core import period_in_mean_edges, scores_beside_baselines


def test_unknown_name_names_the_shipped_models():
    with pytest.raises(ConfigError, match=r"no shipped DGTS model 'spikes'; shipped: \['knobs'\]"):
        dgts.load_pretrained("spikes")


@pytest.mark.slow
def test_transfer_of_the_shipped_model_beats_untrained_weights_and_noise():
    """The demo's setting (a 32 x 12 torus from level 1, the official default start)."""
    model = dgts.load_pretrained()
    meshes = dgts.pretrained_training_meshes()
    untrained = dgts.train(meshes, model.config.replace(steps=0), key=jax.random.key(0)).model
    key = jax.random.key(1)
    out = {
        name: dgts.transfer(m, torus(32, 12), num_samples=2, start_level=1, key=key)
        for name, m in (("trained", model), ("untrained", untrained))
    }
    r = out["trained"]
    s, _, _ = scores_beside_baselines(
        {name: [o.mesh(0), o.mesh(1)] for name, o in out.items()},
        (r.base, r.faces),
        kind="knobs",
        period=period_in_mean_edges(meshes, dgts.pretrained_period()),
        key=jax.random.key(0),
    )
    density, distance = {k: v[0] for k, v in s.items()}, {k: v[2] for k, v in s.items()}
    # knob density within the issue's ±25 % of the oracle's (measured 0.96); noise misses it (1.4)
    assert 0.75 <= density["trained"] <= 1.25, s
    assert not 0.75 <= density["noise"] <= 1.25, s
    # the patch distance: at most half of untrained weights' (measured 0.35x) and below matched
    # noise's (0.67x); no displacement is farthest
    assert distance["trained"] <= 0.5 * distance["untrained"], s
    assert distance["trained"] < distance["noise"] < distance["no displacement"], s

"""The learning checks: a tiny model trained on a knobbed sphere transfers knobs to a torus, judged
by the tessellation-independent measure (``dgts.core.knob_scores``) on the transfer's own base.

One model is trained (tiny config, knobs at 2.8 mean edges) and transferred to a 64 x 24 torus
(default start level, two samples); the oracle is the same knobs at the same period on the
transfer's base. Against it:

- the patch distance (sliced Wasserstein of rotation-invariant ring descriptors) must be below
  untrained weights' (same architecture, no step; 0.57-0.87 of it over the seeds measured, a
  modest separation) and well below zero displacement's;
- the knob density (knobs per squared period of the shared base) must be within a factor of the
  oracle's and zero displacement must have no knob; with it, the level-1 reconstruction must be
  close for the trained model and far for untrained weights.

The distance and the reconstruction fail when training does not move the generators towards the
texture (a broken loss sign, frozen parameters, a wrong reconstruction target). Bounds come from
the margins over training keys 0-4 (``studies/dgts_learning_margins.py``,
``studies/results/dgts_learning_margins.md``, setting "tiny, period 0.45", x64 as here), each with
a safety margin (training is not bit-reproducible across machines).

Two baselines are computed and printed but not asserted against, because the tiny model does not
beat them on every seed measured: untrained weights' knob density (on one seed of five it is within
6 % of the oracle's, closer than the trained model's), and matched noise (``texture_noise``, the
oracle's band-passed relief), whose distance is below the trained model's (the trained one is
1.06-1.5x noise's) and whose density is within 10 % of the oracle's on every seed. A period of
2.8 mean edges is at the measure's resolution limit (the fine band-pass P/8 and the first ring P/4
are under one edge), where noise of the right relief has maxima at the knobs' spacing. The noise
ceiling is judged where the measure resolves the texture: the models at depth in
``benchmarks/dgts.py`` (5.6 mean edges per period and more).
"""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jmeshtex.data import icosphere, textured_sphere, torus
from jmeshtex.dgts import Config, PrepareConfig, train, training_meshes, transfer
from jmeshtex.dgts.core import (
    knob_scores,
    oracle_texture,
    period_in_mean_edges,
    reconstruction_errors,
    texture_noise,
    texture_operators,
)

#: the training seed (transfer key 100 + seed), one of the five measured
SEED = 0
#: the reference's knob period on the unit sphere (2.8 mean edges of the finest training level)
PERIOD = 0.45
SAMPLES = 2

#: over seeds 0-4 (studies/results/dgts_learning_margins.md): trained patch distance / untrained
#: weights' 0.57-0.87 (a modest separation at this period) -> bound 0.95
MAX_DISTANCE_VS_UNTRAINED = 0.95
#: trained patch distance / zero displacement's at most 0.33 -> 0.6
ZERO_FRACTION = 0.6
#: trained |log(knob density / oracle's)| 0.36-0.97 (the tiny model makes too few knobs: 0.38x
#: the oracle's at seed 0) -> bound log(3.5)
MAX_DENSITY_ERROR = float(np.log(3.5))
#: level-1 reconstruction (mean edges): trained 0.23-0.24, untrained 0.57-1.98
REC_BOUND = 0.4


@pytest.fixture(scope="module")
def knobs_run():
    """The trained and untrained tiny models, their transfers, the baselines and the oracle."""
    tm = training_meshes(
        textured_sphere("knobs", subdivisions=4, period=PERIOD),
        icosphere(2),
        config=PrepareConfig.tiny(),
        key=jax.random.key(0),
        progress=False,
    )
    cfg = Config.tiny()
    trained = train(tm, cfg, key=jax.random.key(SEED), progress=False).model
    untrained = train(tm, cfg.replace(steps=0), key=jax.random.key(SEED), progress=False).model
    key = jax.random.key(100 + SEED)
    res = transfer(trained, torus(64, 24), num_samples=SAMPLES, key=key)
    res_u = transfer(untrained, torus(64, 24), num_samples=SAMPLES, key=key)
    base = (res.base, res.faces)
    period = period_in_mean_edges(tm, PERIOD)
    ops = texture_operators(base, period=period)
    oracle = oracle_texture(base, "knobs", period=period)
    own = knob_scores(oracle, oracle, ops=ops)
    rows = {
        "trained": [res.mesh(i) for i in range(SAMPLES)],
        "untrained": [res_u.mesh(i) for i in range(SAMPLES)],
        "noise": [
            texture_noise(base, ops, own.relief, key=jax.random.key(i)) for i in range(SAMPLES)
        ],
        "zero": [base],
    }
    scores = {
        name: [knob_scores(m, oracle, ops=ops) for m in meshes] for name, meshes in rows.items()
    }
    return {"tm": tm, "trained": trained, "untrained": untrained, "own": own, "scores": scores}


def _distance(run, name: str) -> float:
    return float(np.mean([s.distance for s in run["scores"][name]]))


def _density_error(run, name: str) -> float:
    density = float(np.mean([s.density for s in run["scores"][name]]))
    return abs(float(np.log(density / run["own"].density))) if density > 0 else float("inf")


def test_trained_patches_are_closer_to_the_oracle_than_untrained_or_zero(knobs_run):
    d = {name: _distance(knobs_run, name) for name in knobs_run["scores"]}
    print("patch distance to the oracle: " + ", ".join(f"{k} {v:.5f}" for k, v in d.items()))
    assert d["trained"] < MAX_DISTANCE_VS_UNTRAINED * d["untrained"]
    assert d["trained"] < ZERO_FRACTION * d["zero"]


def test_trained_knob_density_is_near_the_oracle_and_the_reconstruction_learnt(knobs_run):
    e = {name: _density_error(knobs_run, name) for name in knobs_run["scores"]}
    ratio = {n: float(np.mean([s.density for s in knobs_run["scores"][n]])) for n in e}
    print(
        "knob density / oracle's: "
        + ", ".join(f"{k} {v / knobs_run['own'].density:.3f}" for k, v in ratio.items())
    )
    assert e["trained"] < MAX_DENSITY_ERROR
    assert all(s.count == 0 for s in knobs_run["scores"]["zero"])
    tm = knobs_run["tm"]
    rec = reconstruction_errors(knobs_run["trained"], tm)[1]
    rec_u = reconstruction_errors(knobs_run["untrained"], tm)[1]
    print(f"level-1 reconstruction error: trained {rec:.3f}, untrained {rec_u:.3f}")
    assert rec < REC_BOUND < rec_u

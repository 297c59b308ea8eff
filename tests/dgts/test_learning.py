"""The learning checks: a model trained on a bumpy sphere transfers bump-like heights to a torus,
and one trained on knobs transfers them at the right density (peaks per squared mean edge against
an oracle on the same surface).

Heights along the normal relative to a Taubin-smoothed copy summarise the geometric texture; their
Wasserstein-1 distance to the reference's must be clearly smaller for the trained generators than for
the untrained ones (same architecture, random weights) and for plain Gaussian vertex noise of the
reference's height amplitude. This test fails if training does not move the generators towards the
texture (e.g. a broken loss sign, frozen parameters or a wrong reconstruction target).
"""

from __future__ import annotations

import jax
import numpy as np
from scipy.stats import wasserstein_distance

from jmeshtex.data import bumpy_sphere, icosphere, torus
from jmeshtex.dgts import Config, PrepareConfig, train, training_meshes, transfer
from jmeshtex.dgts.core import normal_heights


def test_trained_texture_is_closer_to_the_reference_than_untrained_or_noise():
    prep, cfg = PrepareConfig.tiny(), Config.tiny()
    tm = training_meshes(
        bumpy_sphere(subdivisions=3),
        icosphere(1),
        config=prep,
        key=jax.random.key(0),
        progress=False,
    )
    trained = train(tm, cfg, key=jax.random.key(0), progress=False).model
    untrained = train(tm, cfg.replace(steps=0), key=jax.random.key(0), progress=False).model
    h_ref = normal_heights(tm.mesh(-1))
    target = torus(16, 8)
    key = jax.random.key(1)
    # from level 0 (the 1024-face output its bounds were measured on; the default starts at 1)
    res = transfer(trained, target, num_samples=2, start_level=0, key=key)
    res_u = transfer(untrained, target, num_samples=2, start_level=0, key=key)
    edge = np.linalg.norm(res.base[res.faces[:, 0]] - res.base[res.faces[:, 1]], axis=1).mean()
    rng = np.random.default_rng(0)
    noisy = [res.base + rng.standard_normal(res.base.shape) * h_ref.std() * edge for _ in range(2)]

    def w1(meshes):
        return float(
            np.mean([wasserstein_distance(h_ref, normal_heights((v, res.faces))) for v in meshes])
        )

    w_trained, w_untrained, w_noise = w1(res.vertices), w1(res_u.vertices), w1(noisy)
    print(f"W1 trained {w_trained:.4f}, untrained {w_untrained:.4f}, noise {w_noise:.4f}")
    assert w_trained < 0.85 * w_untrained
    assert w_trained < 0.7 * w_noise


#: the density test's seed (training key; transfer key 100 + seed), one of the five measured
SEED = 0
#: bounds from the margins over seeds 0-4 (studies/results/dgts_learning_margins.md, setting
#: "tiny, period 0.45", x64 as here; `studies/dgts_learning_margins.py`), with a safety factor of
#: 1.5-2 (training is not bit-reproducible across runs: seed 0 read 0.15 and 0.21 in two runs):
#: trained |log(density / oracle's)| at most 0.227 -> bound log(1.4)
MAX_DENSITY_ERROR = float(np.log(1.4))
#: untrained error - trained error at least 0.097 -> 0.05; noise error - trained at least 0.48 -> 0.24
MARGIN_UNTRAINED, MARGIN_NOISE = 0.05, 0.24
#: level-1 reconstruction (mean edges): trained 0.23-0.25, untrained 0.56-1.97
REC_BOUND = 0.4


def test_trained_peak_density_is_closer_to_the_oracle_than_every_baseline():
    """Knobs at 2.8 mean edges learned by the tiny model and transferred to a torus (default start
    level): peaks per squared mean edge against the oracle (the same knobs at the same period on
    the transfer's own base), where untrained weights, zero displacement and noise of the oracle's
    relief are off. Fails when training does not reach the texture's layout."""
    from jmeshtex.data import textured_sphere
    from jmeshtex.dgts.core import (
        density_error,
        matched_noise,
        oracle_texture,
        period_in_mean_edges,
        reconstruction_errors,
        texture_scores,
    )

    period = 0.45
    tm = training_meshes(
        textured_sphere("knobs", subdivisions=4, period=period),
        icosphere(2),
        config=PrepareConfig.tiny(),
        key=jax.random.key(0),
        progress=False,
    )
    cfg = Config.tiny()
    trained = train(tm, cfg, key=jax.random.key(SEED), progress=False).model
    untrained = train(tm, cfg.replace(steps=0), key=jax.random.key(SEED), progress=False).model
    target = torus(64, 24)
    key = jax.random.key(100 + SEED)
    res = transfer(trained, target, num_samples=2, key=key)
    res_u = transfer(untrained, target, num_samples=2, key=key)
    base = (res.base, res.faces)
    oracle = oracle_texture(base, "knobs", period=period_in_mean_edges(tm, period))
    own = texture_scores(oracle, oracle, base=base)

    def error(meshes):
        return float(
            np.mean([density_error(texture_scores(m, oracle, base=base), own) for m in meshes])
        )

    e_trained = error([res.mesh(i) for i in range(2)])
    e_untrained = error([res_u.mesh(i) for i in range(2)])
    e_noise = error([matched_noise(base, own.relief, key=jax.random.key(i)) for i in range(2)])
    zero = texture_scores(base, oracle, base=base)
    print(
        f"|log density/oracle|: trained {e_trained:.3f}, untrained {e_untrained:.3f}, "
        f"noise {e_noise:.3f}; zero displacement {zero.peaks} peaks"
    )
    assert e_trained < MAX_DENSITY_ERROR
    assert e_trained + MARGIN_UNTRAINED < e_untrained
    assert e_trained + MARGIN_NOISE < e_noise
    assert zero.peaks == 0
    rec, rec_u = reconstruction_errors(trained, tm)[1], reconstruction_errors(untrained, tm)[1]
    print(f"level-1 reconstruction error: trained {rec:.3f}, untrained {rec_u:.3f}")
    assert rec < REC_BOUND < rec_u

"""Study: the margins of the DGTS learning test (``tests/dgts/test_learning.py``) over training keys.

``python studies/dgts_learning_margins.py [SETTING ...] [--seeds 5]``: per seed the ``|log|``
peak-density error of the trained, untrained and noise transfers against the oracle, and their
differences; a summary row per setting. x64 on, as in the tests. Writes
``studies/results/dgts_learning_margins.{json,md}`` (the settings of this run only).
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np
from _dgts import (
    KIND,
    PERIOD,
    tiny_configs,
)
from _study import Report

from jmeshtex.data import icosphere, textured_sphere, torus
from jmeshtex.dgts import train, training_meshes, transfer
from jmeshtex.dgts.core import (
    density_error,
    matched_noise,
    oracle_texture,
    period_in_mean_edges,
    reconstruction_errors,
    texture_scores,
)

#: the learning test's settings (tests/dgts/test_learning.py): name -> (Config changes, the
#: reference's knob period on the unit sphere)
LEARNING_SETTINGS = {
    "tiny": ({}, PERIOD),
    "tiny, 6 layers": ({"num_layers": 6}, PERIOD),
    "tiny, period 0.45": ({}, 0.45),
}


def learning_setting(name: str = "tiny"):
    """The learning test's reference, template, configs, target and period (about a CPU-minute)."""
    prep, cfg = tiny_configs()
    changes, period = LEARNING_SETTINGS[name]
    ref = textured_sphere(KIND, subdivisions=4, period=period)
    return ref, icosphere(2), prep, cfg.replace(**changes), torus(64, 24), period


def learning_scores(
    model, tm, target, *, key, period: float = PERIOD, samples: int = 2
) -> dict[str, float]:
    """Peak-density error (``|log ρ/ρ*|``) of a transfer against its oracle (default start level)."""
    res = transfer(model, target, num_samples=samples, key=key)
    base = (res.base, res.faces)
    oracle = oracle_texture(base, KIND, period=period_in_mean_edges(tm, period))
    own = texture_scores(oracle, oracle, base=base)
    scores = [texture_scores(res.mesh(i), oracle, base=base) for i in range(samples)]
    return {
        "density_error": float(np.mean([density_error(s, own) for s in scores])),
        "density_vs_oracle": float(np.mean([s.peak_density for s in scores]) / own.peak_density),
        "noise_density_error": float(
            np.mean(
                [
                    density_error(
                        texture_scores(
                            matched_noise(base, own.relief, key=jax.random.key(i)),
                            oracle,
                            base=base,
                        ),
                        own,
                    )
                    for i in range(samples)
                ]
            )
        ),
    }


def learning_margins(seeds: int, settings: list[str]) -> None:
    """Trained vs untrained / zero / noise density errors over ``seeds`` training keys."""
    report = Report("dgts_learning_margins", ceilings=False)  # this run's settings only
    for name in settings:
        ref, template, prep, cfg, target, period = learning_setting(name)
        tm = training_meshes(ref, template, config=prep, key=jax.random.key(0), progress=False)
        for seed in range(seeds):
            t0 = time.perf_counter()
            trained = train(tm, cfg, key=jax.random.key(seed), progress=False).model
            seconds = time.perf_counter() - t0
            untrained = train(tm, cfg.replace(steps=0), key=jax.random.key(seed), progress=False)
            key = jax.random.key(100 + seed)
            t = learning_scores(trained, tm, target, key=key, period=period)
            u = learning_scores(untrained.model, tm, target, key=key, period=period)
            report.add(
                name=f"{name}: seed {seed}",
                trained_error=t["density_error"],
                trained_density_vs_oracle=t["density_vs_oracle"],
                untrained_error=u["density_error"],
                untrained_density_vs_oracle=u["density_vs_oracle"],
                noise_error=t["noise_density_error"],
                zero_error=float("inf"),
                margin_untrained=u["density_error"] - t["density_error"],
                margin_noise=t["noise_density_error"] - t["density_error"],
                train_s=seconds,
                period_mean_edges=period_in_mean_edges(tm, period),
                rec_error_level_1=float(reconstruction_errors(trained, tm)[1]),
                rec_error_level_1_untrained=float(reconstruction_errors(untrained.model, tm)[1]),
            )
            report.write()
    for name in LEARNING_SETTINGS:
        rows = [r for r in report.rows if r["name"].startswith(f"{name}: seed")]
        if rows:
            report.add(
                name=f"{name}: over {len(rows)} seeds",
                trained_error_max=max(r["trained_error"] for r in rows),
                trained_density_vs_oracle_min=min(r["trained_density_vs_oracle"] for r in rows),
                trained_density_vs_oracle_max=max(r["trained_density_vs_oracle"] for r in rows),
                margin_untrained_min=min(r["margin_untrained"] for r in rows),
                margin_noise_min=min(r["margin_noise"] for r in rows),
                seeds_trained_closest=sum(
                    r["margin_untrained"] > 0 and r["margin_noise"] > 0 for r in rows
                ),
            )
    report.notes.append(
        "error = |log(peak density / oracle's)| of a transfer to a 64 x 24 torus (default start "
        "level, 2 samples), oracle: knobs at the reference's period in mean edges on the transfer's "
        "own base; margin = baseline error - trained error (> 0: trained closer)."
    )
    report.write()


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("settings", nargs="*", default=["tiny"], choices=sorted(LEARNING_SETTINGS))
    ap.add_argument("--seeds", type=int, default=5, help="training keys per setting")
    args = ap.parse_args(argv)
    jax.config.update("jax_enable_x64", True)  # as the tests run (conftest.py): same numerics
    learning_margins(args.seeds, args.settings or ["tiny"])


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()

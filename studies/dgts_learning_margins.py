"""Study: the margins of the DGTS learning tests (``tests/dgts/test_learning.py``) over training keys.

``python studies/dgts_learning_margins.py [SETTING ...] [--seeds 5]``: per training seed, a tiny
model's transfers to a 64 x 24 torus (default start level, 2 samples) scored by the tessellation-
independent measure (``dgts.core.knob_scores``: knobs per squared period of the shared base, the
patch distance) against the oracle on the transfer's base, beside untrained weights, Gaussian
noise matched on the measure's heights (``texture_noise``), zero displacement and the floor (the
oracle with other knob centres); a summary row per setting (the worst case over the seeds, which
the tests' bounds are taken from). x64 on, as in the tests. Writes
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
    untrained_weights,
)
from _study import Report

from jmeshtex.data import icosphere, textured_sphere, torus
from jmeshtex.dgts import train, training_meshes, transfer
from jmeshtex.dgts.core import (
    knob_scores,
    oracle_texture,
    period_in_mean_edges,
    reconstruction_errors,
    texture_noise,
    texture_operators,
)

#: the learning tests' settings (tests/dgts/test_learning.py): name -> (Config changes, the
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
    models: dict, tm, target, *, key, period: float = PERIOD, samples: int = 2
) -> dict[str, tuple[float, float]]:
    """``{row: (|log density / oracle's|, patch distance)}`` (means over ``samples``) of each model's
    transfer (default start level, one transfer key) and of the baselines, against the oracle."""
    res = {name: transfer(m, target, num_samples=samples, key=key) for name, m in models.items()}
    first = next(iter(res.values()))
    base = (first.base, first.faces)
    p = period_in_mean_edges(tm, period)
    ops = texture_operators(base, period=p)
    oracle = oracle_texture(base, KIND, period=p)
    own = knob_scores(oracle, oracle, ops=ops)
    rows = {name: [r.mesh(i) for i in range(samples)] for name, r in res.items()}
    rows["noise"] = [
        texture_noise(base, ops, own.relief, key=jax.random.key(i)) for i in range(samples)
    ]
    rows["zero"] = [base]
    rows["floor"] = [
        oracle_texture(base, KIND, period=p, key=jax.random.key(100 + i)) for i in (0, 1)
    ]
    out = {}
    for name, meshes in rows.items():
        k = [knob_scores(m, oracle, ops=ops) for m in meshes]
        density = float(np.mean([s.density for s in k]))
        error = abs(np.log(density / own.density)) if density > 0 else float("inf")
        out[name] = (float(error), float(np.mean([s.distance for s in k])))
    return out


def learning_margins(seeds: int, settings: list[str]) -> None:
    """Trained against untrained / noise / zero / floor, over ``seeds`` training keys."""
    report = Report("dgts_learning_margins", ceilings=False)  # this run's settings only
    for name in settings:
        ref, template, prep, cfg, target, period = learning_setting(name)
        tm = training_meshes(ref, template, config=prep, key=jax.random.key(0), progress=False)
        for seed in range(seeds):
            t0 = time.perf_counter()
            trained = train(tm, cfg, key=jax.random.key(seed), progress=False).model
            seconds = time.perf_counter() - t0
            untrained = untrained_weights(tm, cfg, seed=seed)
            s = learning_scores(
                {"trained": trained, "untrained": untrained},
                tm,
                target,
                key=jax.random.key(100 + seed),
                period=period,
            )
            row = {}
            for k, (err, dist) in s.items():
                row[f"{k}_density_error"] = err
                row[f"{k}_distance"] = dist
            report.add(
                name=f"{name}: seed {seed}",
                **row,
                distance_vs_untrained=s["trained"][1] / s["untrained"][1],
                distance_vs_noise=s["trained"][1] / s["noise"][1],
                margin_untrained=s["untrained"][0] - s["trained"][0],
                margin_noise=s["noise"][0] - s["trained"][0],
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
                trained_density_error_max=max(r["trained_density_error"] for r in rows),
                distance_vs_untrained_max=max(r["distance_vs_untrained"] for r in rows),
                distance_vs_noise_max=max(r["distance_vs_noise"] for r in rows),
                margin_untrained_min=min(r["margin_untrained"] for r in rows),
                margin_noise_min=min(r["margin_noise"] for r in rows),
                rec_error_level_1_max=max(r["rec_error_level_1"] for r in rows),
                rec_error_level_1_untrained_min=min(r["rec_error_level_1_untrained"] for r in rows),
            )
    report.notes.append(
        "Transfers to a 64 x 24 torus (default start level, 2 samples) scored by "
        "dgts.core.knob_scores against the oracle (knobs at the reference's period in mean edges "
        "on the transfer's own base): *_density_error = |log(knobs per squared period / the "
        "oracle's)|, *_distance = patch distance (periods); noise: Gaussian displacement matched "
        "to the oracle's band-passed relief (texture_noise); zero: the undisplaced base; floor: "
        "the oracle with other knob centres. margin = baseline error - trained error (> 0: "
        "trained closer); distance_vs_* = trained distance / the baseline's."
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

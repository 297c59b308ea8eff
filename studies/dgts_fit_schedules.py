"""Study: DGTS training-mesh fitting, the joint schedule against the official one.

``python studies/dgts_fit_schedules.py [--iterations 200]``: the joint schedule (5 x ITERATIONS
Adam steps at 5e-3) against the official one (``PrepareConfig.official``: iterations of 3
regulariser + 2 Chamfer steps at 1e-4, KD-tree nearest neighbours) on the knobs sphere, 2 levels:
final two-sided Chamfer distance (mean edges) and normal error (mean angle between a sample's
normal and its nearest neighbour's, degrees) on 20000 fresh samples per surface, and seconds; the
full official 3000 iterations projected from the measured rate. Writes
``studies/results/dgts_fit_schedules.{json,md}``.
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np
import scipy.spatial
from _dgts import (
    KIND,
    PERIOD,
)
from _study import Report

from jmeshtex.data import icosphere, textured_sphere
from jmeshtex.dgts import PrepareConfig, training_meshes
from jmeshtex.dgts.core import sample_points


def _surface_error(a, b, n: int = 20000) -> tuple[float, float]:
    """Two-sided mean nearest-sample distance and normal angle (degrees) between two meshes."""
    (va, fa), (vb, fb) = a, b
    pa, na = (
        np.asarray(x)
        for x in sample_points(np.asarray(va, np.float32), np.asarray(fa), n, key=jax.random.key(7))
    )
    pb, nb = (
        np.asarray(x)
        for x in sample_points(np.asarray(vb, np.float32), np.asarray(fb), n, key=jax.random.key(8))
    )
    d_ab, i_ab = scipy.spatial.cKDTree(pb).query(pa)
    d_ba, i_ba = scipy.spatial.cKDTree(pa).query(pb)
    ang = np.concatenate([np.sum(na * nb[i_ab], 1), np.sum(nb * na[i_ba], 1)])
    return float(0.5 * (d_ab.mean() + d_ba.mean())), float(
        np.degrees(np.arccos(np.clip(ang, -1, 1))).mean()
    )


def fit_compare(report: Report, iterations: int) -> None:
    ref = reference_mesh()
    for name, cfg in (
        ("joint", PrepareConfig(levels=2, steps=5 * iterations)),
        ("official", PrepareConfig.official(levels=2, steps=iterations)),
    ):
        t0 = time.perf_counter()
        tm = training_meshes(ref, icosphere(1), config=cfg, key=jax.random.key(0), progress=False)
        seconds = time.perf_counter() - t0
        # the reference in the finest level's frame
        ref_l = ((ref.vertices - tm.center) * tm.scales[-1], ref.faces)
        cd, ang = _surface_error(tm.mesh(-1), ref_l)
        edge = float(
            np.linalg.norm(
                np.diff(tm.vertices[-1][tm.faces[-1][:, :2]], axis=1)[:, 0], axis=1
            ).mean()
        )
        row = {
            "name": f"fit: {name} ({cfg.steps} {'iterations' if name == 'official' else 'steps'} x 2 levels)",
            "chamfer_mean_edges": cd / edge,
            "normal_error_deg": ang,
            "seconds": seconds,
        }
        if name == "official":
            row["projected_3000_iterations_s"] = seconds * 3000 / iterations
        report.add(**row)


def reference_mesh():
    return textured_sphere(KIND, subdivisions=4, period=PERIOD)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--iterations", type=int, default=200, help="official iterations")
    args = ap.parse_args(argv)
    report = Report("dgts_fit_schedules", ceilings=False)
    fit_compare(report, args.iterations)
    report.write()


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()

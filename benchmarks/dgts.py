"""Benchmark: DGTS quality on structure, per-level iteration times at the paper's depth, fitting schedules.

Run: ``.venv/bin/python benchmarks/dgts.py [--levels 5] [--measure 10] [--measured-levels 3]
[--png /tmp/round2/dgts_png]``. Writes ``benchmarks/results/dgts.{json,md}`` (and PNGs with ``--png``).

Sections (float32, CPU, jit; compile time reported apart):

- ``quality``: a knobs sphere (``data.textured_sphere("knobs", subdivisions=4, period=0.6)``: known
  spatial period) learned with the tiny configuration (the demo's ``tiny_configs(quick=True)``: 2 levels,
  template icosphere(2), 120 steps) and transferred to a torus (32 × 12 → 3072 faces). Rows trained /
  untrained (same architecture, no step) / zero displacement / Gaussian noise (the reference's height
  std) / the reference itself (the finest training mesh), on the height autocorrelation length and
  the peak spacing and density (``dgts.height_autocorrelation_length``, ``dgts.peak_statistics``, all
  in mean edges, one peak threshold: the reference's) and W1 of the normal-height distributions;
  plus the reconstruction error per level (``dgts.reconstruction_errors``). This is the tiny setting,
  not the paper's (2 levels, 16 channels, 120 steps instead of 5 levels, 32–128 channels, 2000 steps).
- ``train level l``: seconds per WGAN-GP step (2 critic + 3 generator updates) with the default
  widths (``dgts.Config``: 7 layers, 32 → 128 channels) on a 5-level hierarchy of icosphere(1)
  (80 → 20480 faces), measured for the first ``--measured-levels`` levels over ``--measure`` steps,
  projected for the rest as ``t(l) = t(m) · F_l / F_m`` from the last measured level ``m`` (the step
  is linear in faces once the 128-channel width is reached at level 2); the projected total of a
  default run (``5 × 2000`` steps) follows. Projections are labelled as such.
- ``fit``: the joint schedule (1000 Adam steps at 5e-3) against the official one
  (``PrepareConfig.official``: iterations of 3 regulariser + 2 Chamfer steps at 1e-4, KD-tree
  nearest neighbours) with as many Adam steps (200 iterations), on the knobs sphere, 2 levels:
  final two-sided Chamfer distance and normal error (mean angle between a sample's normal and its
  nearest neighbour's, degrees) on 20000 fresh samples per surface, and seconds; the full official
  3000 iterations are projected from the measured rate.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import time

import jax
import numpy as np
import scipy.spatial
from _harness import Report, matmul_ceiling
from scipy.stats import wasserstein_distance

from jmeshtex.data import icosphere, textured_sphere, torus
from jmeshtex.dgts import Config, PrepareConfig, train, training_meshes, transfer
from jmeshtex.dgts.core import (
    height_autocorrelation_length,
    normal_heights,
    peak_statistics,
    reconstruction_errors,
    sample_points,
)

#: Taubin pairs of the heights, as the dgts quality measures use them by default
SMOOTHING = 30


def tiny_configs() -> tuple[PrepareConfig, Config]:
    """The demo's and the learning test's configuration: ``PrepareConfig.tiny``, ``Config.tiny``."""
    return PrepareConfig.tiny(), Config.tiny()


def reference_mesh():
    return textured_sphere("knobs", subdivisions=4, period=0.6)


def quality(report: Report, png: pathlib.Path | None) -> None:
    prep, cfg = tiny_configs()
    t0 = time.perf_counter()
    tm = training_meshes(
        reference_mesh(), icosphere(2), config=prep, key=jax.random.key(0), progress=False
    )
    t_prep = time.perf_counter() - t0
    t0 = time.perf_counter()
    trained = train(tm, cfg, key=jax.random.key(0), progress=False).model
    t_train = time.perf_counter() - t0
    untrained = train(tm, cfg.replace(steps=0), key=jax.random.key(0), progress=False).model
    report.add(
        name="quality: prepare + train (tiny)",
        faces=len(tm.faces[-1]),
        prepare_s=t_prep,
        train_s=t_train,
    )
    target = torus(32, 12)
    res = transfer(trained, target, key=jax.random.key(1), per_level=True)
    res_u = transfer(untrained, target, key=jax.random.key(1))
    ref = tm.mesh(-1)
    h_ref = normal_heights(ref, smoothing=SMOOTHING)
    edge = np.linalg.norm(res.base[res.faces[:, 0]] - res.base[res.faces[:, 1]], axis=1).mean()
    noisy = res.base + np.random.default_rng(0).standard_normal(res.base.shape) * h_ref.std() * edge
    ref_peaks = peak_statistics(ref)
    rows = {
        "reference": ref,
        "trained": res.mesh(0),
        "untrained": res_u.mesh(0),
        "zero displacement": (res.base, res.faces),
        "gaussian noise": (noisy, res.faces),
    }
    acl_ref = height_autocorrelation_length(ref)
    for name, mesh in rows.items():
        acl = height_autocorrelation_length(mesh)
        peaks = peak_statistics(mesh, threshold=ref_peaks.threshold)
        w1 = wasserstein_distance(h_ref, normal_heights(mesh, smoothing=SMOOTHING))
        report.add(
            name=f"quality: {name}",
            autocorrelation_length=acl,
            acl_vs_reference=acl / acl_ref,
            peak_spacing=peaks.spacing,
            spacing_vs_reference=peaks.spacing / ref_peaks.spacing,
            peak_density=peaks.density,
            peaks=peaks.count,
            w1_heights=w1,
        )
    for name, model in (("trained", trained), ("untrained", untrained)):
        errs = reconstruction_errors(model, tm)
        report.add(
            name=f"quality: reconstruction error ({name})",
            **{f"level_{i}": float(e) for i, e in enumerate(errs)},
            target="< 0.1 mean edges",
        )
    if png is not None:
        from jmeshtex.render import figure, render_mesh

        size = (360, 360)
        lim = float(np.abs(res.heights).max()) or 1.0
        panels = [
            ("reference", render_mesh(reference_mesh(), size=size)),
            ("training level 1", render_mesh(ref, size=size)),
        ]
        for i, v in enumerate(res.level_vertices):
            panels.append(
                (
                    f"transfer level {i}",
                    render_mesh((v[0], res.level_faces[i]), size=size, view=(35, -60)),
                )
            )
        panels.append(
            (
                "transfer (height)",
                render_mesh(
                    res.mesh(0),
                    scalars=res.heights[0],
                    cmap="coolwarm",
                    clim=(-lim, lim),
                    size=size,
                    view=(35, -60),
                ),
            )
        )
        panels.append(("untrained", render_mesh(res_u.mesh(0), size=size, view=(35, -60))))
        panels.append(
            ("gaussian noise", render_mesh((noisy, res.faces), size=size, view=(35, -60)))
        )
        png.mkdir(parents=True, exist_ok=True)
        figure(
            panels,
            columns=4,
            title="DGTS tiny: knobs sphere -> torus",
            path=png / "dgts_quality.png",
        )


def timing(report: Report, levels: int, measured: int, steps: int) -> None:
    # timing only: the template's subdivisions, unfitted (steps=0), are valid training meshes of every size
    tm = training_meshes(
        reference_mesh(),
        icosphere(1),
        config=PrepareConfig(levels=levels, steps=0),
        key=jax.random.key(0),
        progress=False,
    )
    cfg = Config(steps=steps)
    cpu0 = time.process_time()
    load = os.getloadavg()[0]
    result = train(tm, cfg, key=jax.random.key(0), levels=measured, progress=False)
    report.add(
        name=f"train: {measured} levels measured",
        seconds=result.seconds,
        cpu_s=time.process_time() - cpu0,
        load=load,
        gflops_ceiling=matmul_ceiling(1024),
    )
    per_step = {}
    total = 0.0
    for r in result.extra["levels"]:
        per_step[r.level] = r.seconds_per_step
        total += r.compile_seconds + Config().steps * r.seconds_per_step
        report.add(
            name=f"train level {r.level} (measured)",
            faces=r.faces,
            ms_per_step=1000 * r.seconds_per_step,
            compile_s=r.compile_seconds,
        )
    last = max(per_step)
    for level in range(measured, levels):
        f = len(tm.faces[level])
        t = per_step[last] * f / len(tm.faces[last])
        total += Config().steps * t
        report.add(
            name=f"train level {level} (projected)",
            faces=f,
            ms_per_step=1000 * t,
            basis=f"level {last} x faces ratio",
        )
    report.add(
        name=f"train: default run, {levels} levels x {Config().steps} steps (projected)",
        seconds=total,
        hours=total / 3600,
    )


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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--levels", type=int, default=5)
    ap.add_argument("--measured-levels", type=int, default=3)
    ap.add_argument("--measure", type=int, default=10, help="timed steps per measured level")
    ap.add_argument("--fit-iterations", type=int, default=200)
    ap.add_argument("--png", type=pathlib.Path, default=None)
    ap.add_argument("--skip", nargs="*", default=(), choices=("quality", "timing", "fit"))
    args = ap.parse_args()
    report = Report("dgts")
    if "fit" not in args.skip:
        fit_compare(report, args.fit_iterations)
        report.write()  # after every section, so a later failure keeps the earlier figures
    if "quality" not in args.skip:
        quality(report, args.png)
        report.write()
    if "timing" not in args.skip:
        timing(report, args.levels, args.measured_levels, args.measure)
    report.write()


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()

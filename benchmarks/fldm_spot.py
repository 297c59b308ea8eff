"""Benchmark: FLDM fidelity and diversity on Spot, with the shipped FL-VAE.

Run::

    .venv/bin/python benchmarks/fldm_spot.py            # the CPU preset (v-prediction), ~50 min on 2 cores
    .venv/bin/python benchmarks/fldm_spot.py --prediction epsilon   # the same with the paper's ε-prediction
    .venv/bin/python benchmarks/fldm_spot.py --quick    # a smoke run (tiny model, ~1 min)

Writes ``benchmarks/results/fldm_spot.{json,md}`` and ``fldm_spot.png`` (``fldm_spot_epsilon.*``
with ``--prediction epsilon``; ``--out`` to change the folder). The training copies and the resumable
training checkpoints (``train_v/``, ``train_epsilon/``) live under
``benchmarks/results/_work/fldm_spot[_quick]/`` (git-ignored, ``--work`` to change): a re-run reuses
the copies and resumes training where it stopped (``--steps N`` trains on to ``N``). ``--seed`` makes
the ``jax.random.key`` every random choice derives from.

What runs (Mitchel et al. 2024, §6.1 and §6.6):

1. ``n_copies`` re-triangulations of Spot (``../shared/data/spot``, or ``$JMESHTEX_SHARED_DATA``)
   with Spot's own vertex count (the texture scale follows mesh resolution, §6.6), encoded with the
   shipped FL-VAE (``jmeshtex.fl.load_pretrained`` + ``jmeshtex.fldm.fl_vae_encoder``);
2. ``jmeshtex.fldm.train`` (v-loss, or the paper's ε-loss with ``--prediction epsilon``; Adam)
   with the ``fldm.Config.cpu`` denoiser;
3. ``n`` samples with DDIM-50 on Spot itself, decoded to Spot's UV atlas
   (``jmeshtex.fldm.decode_samples``); the same noise through the *untrained* denoiser
   (``jmeshtex.fldm.init``: the initialisation training started from);
4. renders at fixed views (Spot turned y-up → z-up, one midpoint subdivision so that the face-flat
   renderer shows the texture at about the image's resolution) of: the exemplar (Spot's own texture),
   the FL-VAE reconstruction of the exemplar (encode Spot → decode its atlas: the fidelity the codec
   allows, and the *nearest training copy*, the memorisation ceiling), the mean colour of the
   exemplar (a texture-free baseline), *shuffled latents* (Spot's encoding permuted over vertices:
   the right marginal, no spatial structure), the trained and the untrained samples.

The notes give the fraction of the flat → reconstruction Gram gap the trained samples close, and
whether they beat both the flat colour and the shuffled latents (the issue's target for the CPU
preset: yes, yes, ≥ 0.5, with diversity LPIPS ≥ 0.1; a 3-hour CPU budget, not run in this session).

Table (one row per source):

- ``fidelity_gram``: mean over views (and samples) of the VGG Gram distance
  (:func:`jmeshtex.metrics.gram_distance`, relu1_1…relu4_1) between the source's render and the
  exemplar's render from the same view — lower is closer to the exemplar's texture statistics
  (stands in for SIFID, which has no offline weights);
- ``diversity_lpips``: mean over views and sample pairs of LPIPS-VGG between two samples' renders
  from the same view (higher = more diverse);
- ``*_std``: the standard deviation of the per-sample (per-pair) figures;
- ``latent_rms``: root mean square modulus of the sampled latents as the model sees them (scaled,
  eq. 38–39): the training latents' is 1 by construction, so a value far from 1 flags samples
  whose magnitude drifted (what ε-prediction with this small denoiser does).

Timing rows give every stage's wall time with the 1-minute load average when it ended: ``(this
call)`` for the run that wrote the table, ``(when built)`` for the cached dataset and training as
measured by the calls that did that work (kept in ``<work>/timings.json``). ``--ddpm`` adds a row of
DDPM-1000 samples of the trained model (same noise seed; about a minute per sample on 2 cores). The
config used is printed below the table. The ceilings line (matmul GFLOP/s, copy GB/s) is kept for the
format; it bounds the training and sampling timings, not the quality figures.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
from _harness import RESULTS, Report

from jmeshtex import Mesh
from jmeshtex.fldm import LOSS_NAMES, PREDICTIONS

HERE = pathlib.Path(__file__).resolve().parent
SHARED = HERE.parent / ".." / "shared" / "data"
VIEWS = ((15.0, 35.0), (15.0, 125.0), (15.0, 215.0), (15.0, 305.0))


def _load() -> float:
    return os.getloadavg()[0]


def spot_path() -> pathlib.Path:
    """Spot's folder, or exit with a message that says where it was looked for."""
    base = pathlib.Path(os.environ.get("JMESHTEX_SHARED_DATA", SHARED))
    spot = base / "spot"
    for name in ("spot_triangulated.obj", "spot_texture.png"):
        if not (spot / name).is_file():
            sys.exit(
                f"fldm_spot: {spot / name} not found. This benchmark needs Spot (../shared/data/spot "
                "with spot_triangulated.obj and spot_texture.png); point JMESHTEX_SHARED_DATA at the "
                "folder that holds spot/."
            )
    return spot


def presets(quick: bool, latent_dim: int, n_vertices: int, prediction: str = "v"):
    """``(fldm.Config, run settings)`` of the full benchmark or the ``--quick`` smoke run."""
    from jmeshtex import fldm

    if quick:
        cfg = fldm.Config.tiny(
            latent_channels=latent_dim,
            widths=(8, 16),
            hdim=2,
            n_copies=2,
            copy_vertices=400,
            steps=3,
            checkpoint_every=2,
            diffusion_steps=100,
            bucket=256,
            prediction=prediction,
        )
        run = dict(samples=2, views=VIEWS[:2], size=96, atlas=128, ddim_steps=3, subdivide=0)
    else:
        cfg = fldm.Config.cpu(
            latent_channels=latent_dim,
            n_copies=16,
            copy_vertices=n_vertices,
            steps=4000,
            checkpoint_every=50,
            prediction=prediction,
        )
        run = dict(samples=6, views=VIEWS, size=256, atlas=512, ddim_steps=50, subdivide=1)
    return cfg, run


def render_mesh_of(spot, subdivide: int):
    """``(vertices z-up, faces, uv)`` of Spot for rendering, midpoint-subdivided ``subdivide`` times."""
    from jmeshtex.geometry import subdivide_midpoint, subdivide_uv

    v, f, uv = np.asarray(spot.vertices, np.float64), spot.faces, spot.uv
    for _ in range(subdivide):
        s = subdivide_midpoint(v, f)
        v, f, uv = s.vertices, s.faces, subdivide_uv(uv)
    v = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)  # Spot is y-up, the renderer z-up
    return v, f, uv


def render_views(geom, texture: np.ndarray, views, size: int) -> np.ndarray:
    """``[len(views), size, size, 3]`` float32 renders in [0, 1] of Spot with ``texture``."""
    from jmeshtex.render import render_mesh

    v, f, uv = geom
    return (
        np.stack(
            [
                render_mesh(Mesh(v, f, uv=uv, texture=texture), view=view, size=(size, size))
                for view in views
            ]
        ).astype(np.float32)
        / 255.0
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="tiny smoke settings (about a minute)")
    ap.add_argument(
        "--out", type=pathlib.Path, default=RESULTS, help="folder for fldm_spot.{json,md,png}"
    )
    ap.add_argument(
        "--work", type=pathlib.Path, default=None, help="cache folder (copies, checkpoints)"
    )
    ap.add_argument(
        "--steps", type=int, default=None, help="training steps (default: the preset's)"
    )
    ap.add_argument(
        "--samples", type=int, default=None, help="samples per model (default: the preset's)"
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--ddpm", action="store_true", help="also DDPM-1000 samples of the trained model (slow)"
    )
    ap.add_argument(
        "--prediction",
        choices=PREDICTIONS,
        default="v",
        help="what the denoiser predicts (default: the CPU preset's v)",
    )
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    spot_dir = spot_path()  # fail before the heavy imports

    from jmeshtex import fl, fldm
    from jmeshtex.geometry import fill_unused_texels
    from jmeshtex.io import load_mesh
    from jmeshtex.metrics import gram_distance, load_vgg16, lpips
    from jmeshtex.render import render_grid

    name = "fldm_spot" + ("" if args.prediction == "v" else f"_{args.prediction}")
    report = Report(name, ceilings=not args.quick)
    work = args.work or RESULTS / "_work" / ("fldm_spot" + ("_quick" if args.quick else ""))
    spot = load_mesh(spot_dir / "spot_triangulated.obj", texture=spot_dir / "spot_texture.png")
    vae = fl.load_pretrained()
    cfg, run = presets(args.quick, vae.config.latent_dim, spot.num_vertices, args.prediction)
    cfg = cfg.replace(**({} if args.steps is None else {"steps": args.steps}))
    k_codec, k_data, k_train, k_sample = jax.random.split(jax.random.key(args.seed), 4)
    n = run["samples"] if args.samples is None else args.samples
    views, size = run["views"], run["size"]
    timings: dict[str, tuple[float, float]] = {}

    def stage(label: str, t0: float) -> None:
        timings[label] = (time.perf_counter() - t0, _load())
        print(f"[{label}] {timings[label][0]:.1f} s, load {timings[label][1]:.2f}", flush=True)

    # 1. training copies (cached)
    t0 = time.perf_counter()
    encode = fldm.fl_vae_encoder(vae, spot, key=k_codec)
    data = fldm.build_dataset(
        spot, cfg, encode=encode, key=k_data, cache_dir=work / "data", progress=False
    )
    stage("dataset", t0)
    # the cost of the cached work, as measured by the calls that did it (a re-run only loads it)
    record_path = work / "timings.json"
    record = json.loads(record_path.read_text()) if record_path.is_file() else {}
    if any(
        p.stat().st_mtime >= time.time() - timings["dataset"][0]
        for p in (work / "data").glob("copy_*.npz")
    ):
        record["dataset"] = {"seconds": timings["dataset"][0], "load": timings["dataset"][1]}

    # 2. training (resumable)
    t0 = time.perf_counter()
    train_key = f"train_{cfg.prediction}"
    result = fldm.train(
        data, cfg, key=k_train, checkpoint_dir=work / train_key, progress=not args.quick
    )
    stage("train", t0)
    steps_done = result.steps - (result.resumed_from or 0)  # in this call
    if steps_done:
        old = (
            record.get(train_key, {})
            if record.get(train_key, {}).get("steps", 0) < cfg.steps
            else {}
        )
        record[train_key] = {
            "seconds": old.get("seconds", 0.0) + result.seconds,
            "steps": old.get("steps", 0) + steps_done,
            "load": timings["train"][1],
        }
    from jmeshtex.io import atomic_write

    atomic_write(record_path, json.dumps(record, indent=2))
    losses = np.asarray(result.losses["loss"])
    k = max(1, min(50, len(losses) // 5))
    loss_first, loss_last = float(np.mean(losses[:k])), float(np.mean(losses[-k:]))

    # 3. samples on Spot itself, trained and untrained (same noise)
    t0 = time.perf_counter()
    geo = fldm.sampling_geometry(spot, result.model)
    untrained = fldm.init(data, cfg, key=k_train)  # the weights training started from
    z_tr = fldm.sample(
        result.model, geo, key=k_sample, num_samples=n, steps=run["ddim_steps"]
    ).latents
    z_un = fldm.sample(untrained, geo, key=k_sample, num_samples=n, steps=run["ddim_steps"]).latents
    z_ddpm = (
        fldm.sample(result.model, geo, key=k_sample, num_samples=n, method="ddpm").latents
        if args.ddpm
        else None
    )
    stage("sample", t0)

    # 4. decode to Spot's atlas; the FL-VAE reconstruction of the exemplar; the mean colour
    t0 = time.perf_counter()

    def atlases(latents):
        decoded = fldm.decode_samples(vae, spot, latents, size=run["atlas"])
        return [fill_unused_texels(d["texture"], d["valid"]) for d in decoded]

    recon_mu = np.asarray(fl.encode(vae, spot, key=k_codec).mu)
    tex = {
        "reconstruction": atlases(recon_mu[None]),
        "trained": atlases(z_tr),
        "untrained": atlases(z_un),
    }
    if z_ddpm is not None:
        tex["trained DDPM-1000"] = atlases(z_ddpm)
    mean_colour = np.broadcast_to(spot.texture[..., :3].reshape(-1, 3).mean(0), (8, 8, 3))
    tex["mean colour"] = [np.array(mean_colour)]
    # shuffled latents: the encoded exemplar's latents permuted over vertices (right marginal, no
    # spatial structure), decoded the same way
    perm = np.random.default_rng(args.seed).permutation(recon_mu.shape[0])
    tex["shuffled latents"] = atlases(recon_mu[perm][None])
    stage("decode", t0)

    # 5. renders at fixed views
    t0 = time.perf_counter()
    geom = render_mesh_of(spot, run["subdivide"])
    ref = render_views(geom, spot.texture[..., :3], views, size)
    renders = {src: [render_views(geom, t, views, size) for t in ts] for src, ts in tex.items()}
    stage("render", t0)

    # 6. metrics
    t0 = time.perf_counter()
    weights = load_vgg16()
    ref_j = jnp.asarray(ref)

    def gram(imgs: np.ndarray) -> float:
        return float(np.mean(np.asarray(gram_distance(jnp.asarray(imgs), ref_j, weights=weights))))

    def diversity(rs: list[np.ndarray]) -> list[float]:
        return [
            float(
                np.mean(np.asarray(lpips(jnp.asarray(rs[a]), jnp.asarray(rs[b]), weights=weights)))
            )
            for a in range(len(rs))
            for b in range(a + 1, len(rs))
        ]

    def latent_rms(z: np.ndarray) -> float:  # per sample over vertices and channels, then the mean
        return float(np.mean(np.sqrt(np.mean(np.abs(z * data.scale) ** 2, axis=(1, 2)))))

    # (source, renders, what, sampled latents or None)
    trained = f"trained samples (DDIM-{run['ddim_steps']})"
    untrained = f"untrained samples (DDIM-{run['ddim_steps']})"
    rows = [("exemplar (vs itself)", [ref], "Spot's own texture; the metric's zero", None)]
    rows += [
        (
            "nearest training copy (FL-VAE reconstruction)",
            renders["reconstruction"],
            "encode Spot → decode its atlas: the memorisation ceiling",
            None,
        )
    ]
    rows += [("mean colour", renders["mean colour"], "texture-free baseline", None)]
    rows += [
        (
            "shuffled latents",
            renders["shuffled latents"],
            "Spot's latents permuted over vertices: right marginal, no structure",
            None,
        )
    ]
    rows += [(trained, renders["trained"], f"{n} samples, {len(losses)} steps", z_tr)]
    if z_ddpm is not None:
        rows += [
            ("trained samples (DDPM-1000)", renders["trained DDPM-1000"], f"{n} samples", z_ddpm)
        ]
    rows += [(untrained, renders["untrained"], "same noise, initial weights", z_un)]
    quality = []
    for source, rs, what, z in rows:
        g = [gram(r) for r in rs]
        d = diversity(rs) if len(rs) > 1 else []
        quality.append(
            dict(
                table="quality",
                source=source,
                n=len(rs),
                fidelity_gram=float(np.mean(g)),
                fidelity_gram_std=float(np.std(g)),
                diversity_lpips=float(np.mean(d)) if d else "",
                diversity_lpips_std=float(np.std(d)) if d else "",
                latent_rms=latent_rms(z) if z is not None else "",
                what=what,
            )
        )
    stage("metrics", t0)

    # 7. the PNG grid (first view): exemplar, reconstruction, samples, untrained samples
    t0 = time.perf_counter()
    images = [ref[0], renders["reconstruction"][0][0]] + [r[0] for r in renders["trained"]]
    images += [r[0] for r in renders["untrained"]]
    titles = ["exemplar", "FL-VAE recon."] + [f"sample {i + 1}" for i in range(n)]
    titles += [f"untrained {i + 1}" for i in range(n)]
    args.out.mkdir(parents=True, exist_ok=True)
    render_grid(
        [(255 * np.clip(i, 0, 1)).astype(np.uint8) for i in images],
        args.out / f"{name}.png",
        titles=titles,
        columns=2 + n if n <= 6 else None,
    )
    stage("png", t0)

    for row in quality:
        report.add(**row, load=round(_load(), 2))
    tr = record.get(train_key, {})
    loss_name = LOSS_NAMES[cfg.prediction]
    report.add(
        table="training",
        source=loss_name,
        n=len(losses),
        loss_first=loss_first,
        loss_last=loss_last,
        seconds=tr.get("seconds", ""),
        steps_per_s=tr["steps"] / tr["seconds"] if tr.get("seconds") else "",
        load=round(tr["load"], 2) if "load" in tr else "",
        what=f"mean {loss_name} of the first / last {k} steps; seconds: the optimiser loop over all calls",
    )
    for label, key in (("dataset", "dataset"), ("train", train_key)):
        if key in record:
            report.add(
                table="timing",
                source=f"{label} (when built)",
                seconds=record[key]["seconds"],
                load=round(record[key]["load"], 2),
                what="measured by the call that did the work",
            )
    for label, (seconds, load) in timings.items():
        report.add(
            table="timing", source=f"{label} (this call)", seconds=seconds, load=round(load, 2)
        )
    total = time.perf_counter() - t_start
    report.add(table="timing", source="total (this call)", seconds=total, load=round(_load(), 2))
    vae_desc = {
        k: getattr(vae.config, k) for k in ("latent_dim", "num_samples", "features", "decoder")
    }
    report.config = {
        "fldm_config": cfg.to_dict(),
        "run": {
            **run,
            "views": [list(v) for v in views],
            "samples": n,
            "seed": args.seed,
            "quick": args.quick,
        },
        "fl_vae": vae_desc,
        "spot_vertices": spot.num_vertices,
    }
    by_source = {r["source"]: r["fidelity_gram"] for r in quality}
    ratio = by_source[trained] / max(by_source[untrained], 1e-12)
    flat, recon = (
        by_source["mean colour"],
        by_source["nearest training copy (FL-VAE reconstruction)"],
    )
    gap = (flat - by_source[trained]) / (flat - recon) if flat != recon else float("nan")
    beats = {b: by_source[trained] < by_source[b] for b in ("mean colour", "shuffled latents")}
    report.config["trained_over_untrained_gram"] = ratio
    report.config["flat_to_reconstruction_gram_gap_closed"] = gap
    report.config["trained_beats"] = beats
    report.notes = [
        f"trained / untrained fidelity_gram (same noise): {ratio:.3f}",
        "",
        f"fraction of the flat → reconstruction Gram gap the trained samples close: {gap:.3f} "
        f"(target ≥ 0.5); trained closer than the mean colour: {beats['mean colour']}, than the shuffled "
        f"latents: {beats['shuffled latents']}",
        "",
        f"config ({'--quick' if args.quick else 'full'}): `{json.dumps(cfg.to_dict())}`",
        "",
        f"run: {n} samples, DDIM-{run['ddim_steps']} (η = 0) on Spot ({spot.num_vertices} vertices), atlas "
        f"{run['atlas']}², {len(views)} views {list(views)} at {size}², {run['subdivide']} midpoint subdivision(s) "
        f"for rendering; FL-VAE `{vae_desc}`; seed {args.seed}.",
        "",
        "fidelity_gram: mean VGG Gram distance (relu1_1…relu4_1) of each render to the exemplar's render from "
        "the same view (lower = closer texture statistics); diversity_lpips: mean LPIPS-VGG between two samples' "
        "renders from the same view, over all pairs (higher = more diverse).",
    ]
    report.write(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

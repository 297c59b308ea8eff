"""Benchmark of the FL-VAE: the paper's Table-1 protocol, a held-out-image check, and throughput.

Reconstruction (paper Table 1, there on Google Scanned Objects at 30K vertices: FL-VAE 22.38 dB vs
FL-VAE (Bary.) 21.33 dB PSNR): every textured mesh of ``../shared/data`` (Spot; others with UVs and
a texture beside them are picked up, each skipped cleanly where absent) remeshed with
:func:`jmeshtex.geometry.remesh` to about 5K and 30K vertices; the latents live on the remeshed
surface (colours read from the original at closest points), every used texel of the mesh's own UV
atlas is decoded (three corner predictions blended) and compared with the original texture
resampled at the same texels:

- ``table="reconstruction"``, ``space="atlas"``: PSNR, DSSIM, LPIPS-VGG over the used texels;
- ``space="render"``: the same two atlases (unused texels filled from the nearest used one, so seams
  do not bleed) rendered from the evaluation rig (:func:`jmeshtex.metrics.evaluate_views`,
  ``--views`` azimuths at 20° elevation, ``--view-size`` px, Y up) and compared view by view,
  masked to the object;
- ``ppv``: texels of the atlas per latent vertex, at the atlas size (``ppv_atlas``) and at the
  texture's own resolution (``ppv_texture``) — the paper pre-trains at ≈ 26, its 30K inference
  meshes sit at ≈ 15–20;
- ``constant`` rows: the best constant colour (the mean of the used texels), the floor any model must
  beat; ``p1_oracle`` rows: the true colour sampled at each latent vertex, interpolated linearly
  (3 numbers per vertex where a latent has ``2d``); ``p1_fit`` rows: the per-vertex colours that
  minimise the squared error over the used texels (:func:`jmeshtex.fl.core.p1_baselines`) — a
  model that does not beat them carries no more than a vertex colour.

Held-out images (``table="held_out"``): the scikit-image photographs in
:data:`jmeshtex.fl.HELD_OUT_IMAGES` (never used by :func:`jmeshtex.fl.training_images`; the row's
``seen_in_training`` says whether the model's own training data had the image) as planar
meshes at 26 and 18 pixels per vertex, reconstructed in the atlas next to the best constant colour
and the two P1 codecs:
a model far above the constant on these but not on Spot suffers domain shift, one near the constant
on both is under-trained.

Models: both shipped ones by default (:func:`jmeshtex.fl.load_pretrained` with ``decoder="log"``
and ``"barycentric"``, the ablation, trained with the same data, steps and seed), or ``--models``.

Throughput: encoding (host one-ring sampling and the jitted encoder apart) at 30K vertices in
vertices/s, atlas decoding in texels/s, and training steps/s at the shipped configuration, each
next to the matmul and bandwidth ceilings measured in the same run. Every row carries the 1-minute
load average at the time it was taken (the machine may be shared; re-run on a quiet machine).

Usage::

    python benchmarks/fl_vae.py                      # 5K and 30K, atlas 512², LPIPS, renders
    python benchmarks/fl_vae.py --sizes 5000 --atlas 256 --no-lpips --views 2 --no-throughput  # quick
    python benchmarks/fl_vae.py --curve 250,500,1000   # log vs barycentric along one run each
"""

from __future__ import annotations

import argparse
import os
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np
from _harness import Report

from jmeshtex import fl, metrics
from jmeshtex.geometry import rasterize_uv

DATA = pathlib.Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
SPOT = DATA / "spot"
PAPER = {
    "log": 22.38,
    "barycentric": 21.33,
}  # PSNR at 30K vertices, Google Scanned Objects (Table 1)
#: images the shipped models (jmeshtex/fl/weights/README.md) were trained on
SHIPPED_TRAINING_IMAGES = (
    "astronaut",
    "brick",
    "camera",
    "chelsea",
    "coffee",
    "coins",
    "colorwheel",
    "grass",
    "gravel",
    "hubble_deep_field",
    "immunohistochemistry",
    "moon",
    "retina",
    "rocket",
)


def textured_meshes() -> dict[str, tuple[pathlib.Path, pathlib.Path]]:
    """``{name: (obj, texture)}`` of the textured meshes in ``../shared/data`` (empty where absent)."""
    out = {}
    if not DATA.is_dir():
        return out
    for obj in sorted(DATA.rglob("*.obj")):
        if b"\nvt " not in obj.read_bytes()[:2_000_000]:
            continue
        stem = obj.stem.replace("_triangulated", "")
        for tex in (
            obj.with_name(f"{stem}_texture.png"),
            obj.with_suffix(".png"),
            obj.with_suffix(".jpg"),
        ):
            if tex.exists():
                out[stem] = (obj, tex)
                break
    return out


def _fill_unused(texture: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Unused texels take the colour of the nearest used one (renders sample bilinearly across seams)."""
    from scipy.ndimage import distance_transform_edt

    _, (iy, ix) = distance_transform_edt(~valid, return_indices=True)
    return texture[iy, ix]


def render_metrics(mesh, r, *, views: int, size: int, lpips: bool) -> dict:
    """Render-space PSNR/DSSIM/LPIPS of a reconstruction against its target atlas (same rig, same UVs)."""
    rig = metrics.Protocol(azimuths=views, elevations=(20.0,), size=size, up="y")
    target = _fill_unused(r.target, r.valid)
    recon = _fill_unused(r.texture, r.valid)
    ref, _ = metrics.protocol_views(mesh.replace(texture=target), protocol=rig)
    names = ["psnr", "dssim"] + (["lpips"] if lpips else [])
    out = metrics.evaluate_views(
        mesh.replace(texture=recon), reference_images=ref, protocol=rig, metrics=names
    )
    const = metrics.flat_baseline(r.target, mask=r.valid)
    base = metrics.evaluate_views(
        mesh.replace(texture=_fill_unused(const, r.valid)),
        reference_images=ref,
        protocol=rig,
        metrics=names,
    )
    return {k: float(out[k]) for k in names}, {k: float(base[k]) for k in names}


def baseline_metrics(mesh, r, *, lpips: bool) -> dict[str, dict]:
    """Atlas metrics of the best constant colour and the two P1 codecs on ``r``'s latent mesh."""
    atlases = {"constant": metrics.flat_baseline(r.target, mask=r.valid)}
    atlases.update(fl.core.p1_baselines(mesh, r))
    return {
        name: fl.core.atlas_metrics(a, r.target, r.valid, lpips=lpips)
        for name, a in atlases.items()
    }


def vertex_p1_metrics(model, r, *, lpips: bool) -> dict:
    """Atlas metrics of the model's own colours at the vertices (``D(z_p, 0)``), P1-interpolated:
    what the latents give without the decoder's detail inside faces. Beside the P1 oracle (true
    colours at the vertices) it separates the decoder's error at the vertices from what it adds
    between them."""
    vertex_colors = np.asarray(fl.decode_vertex_colors(model, r.latent_mesh, r.latents), np.float64)
    row, col, face, bary = r.texels
    corners = np.asarray(r.latent_mesh.faces)[face]
    atlas = np.zeros_like(r.target)
    atlas[row, col] = np.clip(fl.core.p1_interpolate(vertex_colors, corners, bary), 0.0, 1.0)
    return fl.core.atlas_metrics(atlas, r.target, r.valid, lpips=lpips)


def held_out_rows(models: dict, report, *, size: int, lpips: bool) -> None:
    """Held-out photographs as planar meshes at 26 and 18 pixels per vertex (module docstring)."""
    rng = np.random.default_rng(0)
    for name, image in zip(fl.core.HELD_OUT_IMAGES, fl.held_out_images(max_size=size), strict=True):
        for ppv in (26.0, 18.0):
            mesh = fl.core.density_mesh(image, ppv, rng=rng)
            measured = image.shape[0] * image.shape[1] / mesh.num_vertices
            for decoder, model in models.items():
                t0 = time.perf_counter()
                r = fl.reconstruct(model, mesh, key=jax.random.key(0), size=size, lpips=lpips)
                report.add(
                    table="held_out",
                    image=name,
                    model=decoder,
                    vertices=mesh.num_vertices,
                    ppv_texture=round(measured, 2),
                    atlas=size,
                    seen_in_training=name in model_images(model),
                    **{k: round(v, 4) for k, v in r.metrics.items()},
                    **channel_kl(r.latents),
                    seconds=time.perf_counter() - t0,
                    load=load(),
                )
            for base, values in baseline_metrics(mesh, r, lpips=lpips).items():
                report.add(
                    table="held_out",
                    image=name,
                    model=base,
                    vertices=mesh.num_vertices,
                    ppv_texture=round(measured, 2),
                    atlas=size,
                    **{k: round(v, 4) for k, v in values.items()},
                )


def channel_kl(latents) -> dict:
    """Each latent channel's mean KL (nats) over the vertices, and how many exceed 0.1 nat."""
    kl = np.asarray(fl.core.kl_per_channel(latents)).mean(0)
    return {
        "kl_channels": " ".join(f"{x:.2f}" for x in kl),
        "channels_above_0p1": int((kl > 0.1).sum()),
    }


def model_images(model) -> tuple[str, ...]:
    """The scikit-image names a model's training saw (the stream mode's split, else the shipped pool)."""
    return (
        fl.core.TRAINING_IMAGES if model.config.pixels_per_vertex > 0 else SHIPPED_TRAINING_IMAGES
    )


def load() -> float:
    return os.getloadavg()[0]


#: KL-control variants of the ``--study`` mode (changes to ``Config.small``)
KL_VARIANTS = {
    "lambda=0.01": {},
    "warm-up": {"kl_warmup_steps": -1},  # -1: the run's first half
    "free bits 0.25": {"free_bits": 0.25},
    "lambda=1e-3": {"kl_weight": 1e-3},
}


def _held_out_quality(model, *, size: int = 96) -> dict:
    """Mean held-out atlas PSNR of ``model`` and of the P1 codecs (planar meshes at 26 ppv)."""
    rng = np.random.default_rng(0)
    rows = []
    for image in fl.held_out_images(max_size=size):
        mesh = fl.core.density_mesh(image, 26.0, rng=rng)
        r = fl.reconstruct(model, mesh, key=jax.random.key(0), size=size, lpips=False)
        base = baseline_metrics(mesh, r, lpips=False)
        rows.append(
            [r.metrics["psnr"], base["p1_oracle"]["psnr"], base["p1_fit"]["psnr"]]
            + [base["constant"]["psnr"]]
        )
    m = np.mean(rows, axis=0)
    return {"psnr": m[0], "p1_oracle_psnr": m[1], "p1_fit_psnr": m[2], "constant_psnr": m[3]}


def study(report, *, steps: int, variants: dict, base: dict) -> None:
    """Short training runs of ``Config.small(**base)`` per variant: per-channel KL, held-out PSNR
    next to the P1 codecs, CPU seconds per step (one run at a time)."""
    for name, changes in variants.items():
        changes = dict(changes)
        if changes.get("kl_warmup_steps") == -1:
            changes["kl_warmup_steps"] = max(1, steps // 2)
        config = fl.Config.small(
            steps=steps, warmup_steps=min(50, steps // 4), checkpoint_every=steps, **base
        ).replace(**changes)
        cpu0, t0 = time.process_time(), time.perf_counter()
        r = fl.train(None, config, key=jax.random.key(0), progress=False)
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - t0
        kl = [float(np.mean(r.losses[f"kl{c}"][-50:])) for c in range(config.latent_dim)]
        quality = _held_out_quality(r.model)
        report.add(
            table="study",
            variant=name,
            **{k: v for k, v in base.items()},
            steps=steps,
            kl_channels=" ".join(f"{x:.2f}" for x in kl),
            channels_above_0p1=sum(x > 0.1 for x in kl),
            l1_last50=round(float(np.mean(r.losses["l1"][-50:])), 4),
            **{k: round(float(v), 3) for k, v in quality.items()},
            cpu_s_per_step=round(cpu / steps, 3),
            wall_s=round(wall, 1),
            compile_s=round(r.compile_seconds, 1),
            load=load(),
        )


def curve(
    report, *, budgets: list[int], decoders: list[str], work: pathlib.Path, base: dict, out=None
):
    """One ``Config.small(**base)`` run per decoder, evaluated at each budget (held-out PSNR beside
    the P1 codecs, per-channel KL): the log decoder against its barycentric ablation as training
    goes on. Resumable: each run checkpoints in ``work/<decoder>`` and each budget's model is
    kept as ``work/<decoder>/step_NNNNN.npz``; a re-run with larger budgets continues the same runs
    (the learning-rate schedule is the preset's, so a budget is a point along one run)."""
    from jmeshtex.io import Checkpoints

    for decoder in decoders:
        config = fl.Config.small(decoder=decoder, checkpoint_every=min(budgets), **base)
        folder = work / decoder
        for budget in sorted(budgets):
            snapshot = folder / f"step_{budget:05d}.npz"
            cpu0, t0 = time.process_time(), time.perf_counter()
            kl = None
            if snapshot.is_file():
                model = fl.load(snapshot)
            else:
                with Checkpoints(folder) as ckpt:
                    done = ckpt.latest_step() or 0
                if done > budget:
                    print(f"[curve] {decoder}: the run is past {budget} steps without its snapshot")
                    continue
                r = fl.train(
                    None,
                    config,
                    key=jax.random.key(0),
                    checkpoint_dir=folder,
                    stop_after=budget - done,
                    progress=False,
                )
                model = r.model
                fl.save(model, snapshot)
                if len(r.losses["l1"]):
                    kl = [
                        float(np.mean(r.losses[f"kl{c}"][-50:])) for c in range(config.latent_dim)
                    ]
            train_cpu, train_wall = time.process_time() - cpu0, time.perf_counter() - t0
            quality = _held_out_quality(model)
            report.add(
                table="curve",
                decoder=decoder,
                steps=budget,
                **{k: round(float(v), 3) for k, v in quality.items()},
                kl_channels=" ".join(f"{x:.2f}" for x in kl) if kl else None,
                channels_above_0p1=sum(x > 0.1 for x in kl) if kl else None,
                train_cpu_s=round(train_cpu, 1),
                train_wall_s=round(train_wall, 1),
                load=load(),
            )
            print(f"[curve] {decoder} {budget}: {quality}", flush=True)
            report.write(out)


def step_profile(report, *, base: dict, steps: int = 6) -> None:
    """Where a training step's time goes: host batch building (meshes, one-ring sampling, colour
    lookup) against the jitted step, in CPU and wall seconds, at ``Config.small(**base)``."""
    config = fl.Config.small(**base)
    images = fl.training_images(max_size=config.max_image_size)
    n = config.batch_size * max(
        int(round(config.texture_size**2 / (config.pixels_per_vertex / config.density_spread))), 4
    )
    params = fl.init(config, key=jax.random.key(0)).params
    opt_state = fl.core.optimizer(config).init(params)
    train_step = fl.core.make_train_step(config)
    stages = {"meshes": [], "samples": [], "step": []}
    cpu = {k: [] for k in stages}
    for i in range(steps):
        rng = np.random.default_rng(i)
        c0, t0 = time.process_time(), time.perf_counter()
        # (training_meshes also builds each image's pyramid, which fl.train does once per run)
        meshes = fl.core.training_meshes(jax.random.key(i), config, images=images)
        c1, t1 = time.process_time(), time.perf_counter()
        batch = fl.core.mesh_batch(meshes, config, rng, num_vertices=n)
        c2, t2 = time.process_time(), time.perf_counter()
        params, opt_state, loss, aux = train_step(
            params, opt_state, batch, jax.random.key(i), np.int32(i)
        )
        jax.block_until_ready(loss)
        c3, t3 = time.process_time(), time.perf_counter()
        if i == 0:
            compile_s = t3 - t2
            continue
        for k, (a, b, ca, cb) in {
            "meshes": (t0, t1, c0, c1),
            "samples": (t1, t2, c1, c2),
            "step": (t2, t3, c2, c3),
        }.items():
            stages[k].append(b - a)
            cpu[k].append(cb - ca)
    for k in stages:
        report.add(
            table="step_profile",
            stage={
                "meshes": "host: textures + planar meshes",
                "samples": "host: one-ring sampling + colours + corner logs (mesh_batch)",
                "step": "jitted step (encoder, decoder, grad, Adam)",
            }[k],
            **{kk: v for kk, v in base.items()},
            padded_vertices=n,
            wall_s=round(float(np.median(stages[k])), 4),
            cpu_s=round(float(np.median(cpu[k])), 4),
            first_step_compile_s=round(compile_s, 1) if k == "step" else None,
            load=load(),
        )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="5000,30000", help="remeshed vertex counts")
    ap.add_argument("--atlas", type=int, default=512, help="atlas side in texels")
    ap.add_argument("--no-lpips", action="store_true")
    ap.add_argument(
        "--models", default=None, help="comma-separated model files (default: the two shipped ones)"
    )
    ap.add_argument(
        "--views",
        type=int,
        default=8,
        help="render views (azimuths at 20° elevation); 0: no renders",
    )
    ap.add_argument("--view-size", type=int, default=256, help="render side in pixels")
    ap.add_argument(
        "--held-out-size", type=int, default=192, help="held-out image side (0: skip that table)"
    )
    ap.add_argument("--no-throughput", action="store_true")
    ap.add_argument("--out", default=None)
    ap.add_argument(
        "--study",
        type=int,
        default=0,
        metavar="STEPS",
        help="instead of the tables: short Config.small runs of STEPS steps per KL variant "
        "(writes fl_vae_study)",
    )
    ap.add_argument(
        "--profile",
        action="store_true",
        help="instead of the tables: where a training step's time goes",
    )
    ap.add_argument(
        "--base",
        default="{}",
        help="JSON changes to Config.small for --study / --profile (e.g. texture_size; "
        "--profile also takes a list of them)",
    )
    ap.add_argument("--variants", default=None, help="comma-separated KL_VARIANTS names")
    ap.add_argument(
        "--curve",
        default=None,
        metavar="STEPS,...",
        help="instead of the tables: held-out quality of one Config.small run per decoder at these "
        "step budgets (resumable in --work; writes fl_vae_curve)",
    )
    ap.add_argument("--decoders", default="log,barycentric", help="decoders of --curve")
    ap.add_argument(
        "--tag", default=None, help="--curve writes fl_vae_curve_TAG (a variant beside the default)"
    )
    ap.add_argument(
        "--work", type=pathlib.Path, default=None, help="--curve's runs (default runs/fl_vae_curve)"
    )
    args = ap.parse_args()
    if args.curve:
        import json

        base = json.loads(args.base)
        report = Report("fl_vae_curve" + (f"_{args.tag}" if args.tag else ""))
        report.config = {"base": base, "budgets": args.curve}
        work = args.work or pathlib.Path(__file__).resolve().parents[1] / "runs" / "fl_vae_curve"
        curve(
            report,
            budgets=[int(b) for b in args.curve.split(",")],
            decoders=args.decoders.split(","),
            work=work,
            base=base,
            out=pathlib.Path(args.out) if args.out else None,
        )
        return
    if args.study or args.profile:
        import json

        base = json.loads(args.base)
        report = Report("fl_vae_study" if args.study else "fl_vae_profile")
        report.config = {"base": base, "study_steps": args.study}
        if args.profile:  # --base may be a list of changes: one profile each
            for one in base if isinstance(base, list) else [base]:
                step_profile(report, base=one)
        else:
            names = args.variants.split(",") if args.variants else list(KL_VARIANTS)
            study(report, steps=args.study, variants={n: KL_VARIANTS[n] for n in names}, base=base)
        report.write(pathlib.Path(args.out) if args.out else None)
        return
    report = Report("fl_vae")
    if args.models is None:
        loaded = [fl.load_pretrained(decoder=d) for d in ("log", "barycentric")]
    else:
        loaded = [fl.load(p) for p in args.models.split(",")]
    models = {m.config.decoder: m for m in loaded}
    sizes = [int(s) for s in args.sizes.split(",")]

    report.config = {
        "sizes": sizes,
        "atlas": args.atlas,
        "views": args.views,
        "view_size": args.view_size,
        "held_out_size": args.held_out_size,
        "lpips": not args.no_lpips,
        "models": {d: m.config.to_dict() for d, m in models.items()},
    }
    from jmeshtex.geometry import remesh
    from jmeshtex.io import load_mesh

    found = textured_meshes()
    if not found:
        print(f"skipping the reconstruction table: no textured mesh under {DATA}")
    for name, (obj, tex) in found.items():
        mesh = load_mesh(obj, texture=tex)
        native = rasterize_uv(mesh.uv, mesh.texture.shape[0]).face.shape[
            0
        ]  # used texels at the texture's size
        for n in sizes:
            t0 = time.perf_counter()
            latent = remesh(mesh, n_vertices=n, key=jax.random.key(0))
            t_remesh = time.perf_counter() - t0
            for decoder, model in models.items():
                t0 = time.perf_counter()
                r = fl.reconstruct(
                    model,
                    mesh,
                    key=jax.random.key(0),
                    size=args.atlas,
                    latent_mesh=latent,
                    lpips=not args.no_lpips,
                )
                common = dict(
                    table="reconstruction",
                    mesh=name,
                    vertices=latent.num_vertices,
                    atlas=args.atlas,
                    ppv_atlas=round(int(r.valid.sum()) / latent.num_vertices, 2),
                    ppv_texture=round(native / latent.num_vertices, 2),
                )
                report.add(
                    **common,
                    model=decoder,
                    space="atlas",
                    **{k: round(v, 4) for k, v in r.metrics.items()},
                    **channel_kl(r.latents),
                    paper_psnr_30k_gso=PAPER.get(decoder),
                    seconds=time.perf_counter() - t0,
                    remesh_s=round(t_remesh, 2),
                    load=load(),
                )
                report.add(
                    **common,
                    model=f"{decoder} at vertices, P1",
                    space="atlas",
                    **{
                        k: round(v, 4)
                        for k, v in vertex_p1_metrics(model, r, lpips=not args.no_lpips).items()
                    },
                )
                if args.views:
                    t0 = time.perf_counter()
                    rend, rend_const = render_metrics(
                        mesh, r, views=args.views, size=args.view_size, lpips=not args.no_lpips
                    )
                    report.add(
                        **common,
                        model=decoder,
                        space="render",
                        **{k: round(v, 4) for k, v in rend.items()},
                        seconds=time.perf_counter() - t0,
                        load=load(),
                    )
            for base, values in baseline_metrics(mesh, r, lpips=not args.no_lpips).items():
                report.add(
                    **common,
                    model=base,
                    space="atlas",
                    **{k: round(v, 4) for k, v in values.items()},
                )
            if args.views:
                report.add(
                    **common,
                    model="constant",
                    space="render",
                    **{k: round(v, 4) for k, v in rend_const.items()},
                )
    if args.held_out_size:
        held_out_rows(models, report, size=args.held_out_size, lpips=not args.no_lpips)
    if args.no_throughput:
        report.write(pathlib.Path(args.out) if args.out else None)
        return
    if (SPOT / "spot_triangulated.obj").exists():
        spot = load_mesh(SPOT / "spot_triangulated.obj", texture=SPOT / "spot_texture.png")

    # -------- throughput at the largest size (on a procedural sphere if Spot is absent)
    model = models.get("log", next(iter(models.values())))
    config = model.config
    n = max(sizes)
    if (SPOT / "spot_triangulated.obj").exists():
        mesh = remesh(spot, n_vertices=n, key=jax.random.key(1))
        colors = fl.core.surface_colors(spot)
    else:
        from jmeshtex import Mesh
        from jmeshtex.data import icosphere

        v, f = icosphere(6)
        mesh = Mesh(v, f, vertex_colors=0.5 + 0.5 * v)
        colors = fl.core.surface_colors(mesh)
    t0 = time.perf_counter()
    s = fl.core.one_ring_samples(
        mesh.vertices, mesh.faces, config.num_samples, rng=np.random.default_rng(0)
    )
    points = np.einsum("vsk,vskd->vsd", s.bary, mesh.vertices[mesh.faces[s.face]])
    rgb = colors.at_points(points.reshape(-1, 3)).reshape(*s.face.shape, 3)
    t_host = time.perf_counter() - t0
    t0 = time.perf_counter()
    jax.block_until_ready(fl.core.encode_one_rings(model, s, rgb).mu)
    t_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    jax.block_until_ready(fl.core.encode_one_rings(model, s, rgb).mu)
    t_enc = time.perf_counter() - t0
    report.add(
        table="throughput",
        what="encode: host one-ring sampling + colour lookup",
        vertices=mesh.num_vertices,
        seconds=t_host,
        per_s=mesh.num_vertices / t_host,
        unit="vertices/s",
        load=load(),
    )
    report.add(
        table="throughput",
        what=f"encode: jitted encoder (chunks of {config.encode_chunk})",
        vertices=mesh.num_vertices,
        seconds=t_enc,
        compile_s=max(t_first - t_enc, 0.0),
        per_s=mesh.num_vertices / t_enc,
        unit="vertices/s",
        load=load(),
    )
    report.add(
        table="throughput",
        what="encode Spot-30K total (sampling + encoder)",
        vertices=mesh.num_vertices,
        seconds=t_host + t_enc,
        load=load(),
    )
    if (SPOT / "spot_triangulated.obj").exists():
        texels = rasterize_uv(spot.uv, args.atlas)
        face, bary = texels.face, texels.bary
        from jmeshtex.geometry import surface_correspondence

        pts = np.einsum("nk,nkd->nd", bary, spot.vertices[spot.faces[face]])
        lface, lbary = surface_correspondence(mesh.vertices, mesh.faces, pts)
        mu = fl.core.encode_one_rings(model, s, rgb).mu
        fl.decode_points_in_faces(model, mesh, mu, lface[:1000], lbary[:1000])  # warm-up / compile
        t0 = time.perf_counter()
        fl.decode_points_in_faces(model, mesh, mu, lface, lbary)
        t_dec = time.perf_counter() - t0
        report.add(
            table="throughput",
            what="decode atlas texels (3 corner predictions blended)",
            texels=len(face),
            seconds=t_dec,
            per_s=len(face) / t_dec,
            unit="texels/s",
            load=load(),
        )

    # -------- training steps/s at the shipped configuration
    cfg = config.replace(steps=10)
    params = model.params
    pool = fl.core.planar_pool(
        fl.core.builtin_images(max_size=cfg.max_image_size, names=("brick", "astronaut", "coffee")),
        per_image=1,
        min_vertices=cfg.max_vertices,
        max_vertices=cfg.max_vertices,
        rng=np.random.default_rng(0),
    )
    batch = fl.core.mesh_batch(
        pool[: cfg.batch_size],
        cfg,
        np.random.default_rng(0),
        num_vertices=cfg.batch_size * cfg.max_vertices,
    )
    step = fl.core.make_train_step(cfg)
    state = (params, fl.core.optimizer(cfg).init(params))
    t0 = time.perf_counter()
    out = step(*state, batch, jax.random.key(0))
    jax.block_until_ready(out)
    t_first = time.perf_counter() - t0
    times = []
    for i in range(5):
        t0 = time.perf_counter()
        out = step(out[0], out[1], batch, jax.random.key(i))
        jax.block_until_ready(out)
        times.append(time.perf_counter() - t0)
    t_step = float(np.median(times))
    report.add(
        table="throughput",
        what=f"train step ({cfg.batch_size} planar meshes × {cfg.max_vertices} vertices, "
        f"S={cfg.num_samples})",
        seconds=t_step,
        compile_s=max(t_first - t_step, 0.0),
        per_s=1.0 / t_step,
        unit="steps/s",
        load=load(),
    )
    report.write(pathlib.Path(args.out) if args.out else None)


if __name__ == "__main__":
    jnp.zeros(())  # initialise the backend before timing
    main()

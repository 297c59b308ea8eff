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

The studies that train (KL variants, the decoder curve that produced the shipped weights, the
step profile) are standalone scripts in ``studies/`` (``studies/README.md``).
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

            # the columns that name a row (its model filled in per row, in this place)
            cell = dict(
                table="held_out",
                image=name,
                model=None,
                vertices=mesh.num_vertices,
                ppv_texture=round(measured, 2),
                atlas=size,
            )

            for decoder, model in models.items():
                t0 = time.perf_counter()
                r = fl.reconstruct(model, mesh, key=jax.random.key(0), size=size, lpips=lpips)
                report.add(
                    **(cell | {"model": decoder}),
                    seen_in_training=name in model_images(model),
                    **{k: round(v, 4) for k, v in r.metrics.items()},
                    **channel_kl(r.latents),
                    seconds=time.perf_counter() - t0,
                    load=load(),
                )
            for base, values in baseline_metrics(mesh, r, lpips=lpips).items():
                report.add(
                    **(cell | {"model": base}), **{k: round(v, 4) for k, v in values.items()}
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
    return fl.core.TRAINING_IMAGES if model.config.pixels_per_vertex > 0 else fl.core.BUILTIN_IMAGES


def load() -> float:
    return os.getloadavg()[0]


def reconstruction_rows(
    report: Report,
    models: dict,
    *,
    sizes: list[int],
    atlas: int,
    views: int,
    view_size: int,
    lpips: bool,
) -> None:
    """The Table-1 protocol on every textured mesh of ``../shared/data`` at each size: each model
    in the atlas (and rendered), its P1 at the latent vertices, and the baselines."""
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
                    size=atlas,
                    latent_mesh=latent,
                    lpips=lpips,
                )
                common = dict(
                    table="reconstruction",
                    mesh=name,
                    vertices=latent.num_vertices,
                    atlas=atlas,
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
                    **{k: round(v, 4) for k, v in vertex_p1_metrics(model, r, lpips=lpips).items()},
                )
                if views:
                    t0 = time.perf_counter()
                    rend, rend_const = render_metrics(
                        mesh, r, views=views, size=view_size, lpips=lpips
                    )
                    report.add(
                        **common,
                        model=decoder,
                        space="render",
                        **{k: round(v, 4) for k, v in rend.items()},
                        seconds=time.perf_counter() - t0,
                        load=load(),
                    )
            for base, values in baseline_metrics(mesh, r, lpips=lpips).items():
                report.add(
                    **common,
                    model=base,
                    space="atlas",
                    **{k: round(v, 4) for k, v in values.items()},
                )
            if views:
                report.add(
                    **common,
                    model="constant",
                    space="render",
                    **{k: round(v, 4) for k, v in rend_const.items()},
                )


def encode_decode_rows(report: Report, model, *, n: int, atlas: int) -> None:
    """Encoding (host sampling and the jitted encoder apart) and atlas decoding at ``n`` vertices
    of Spot (a procedural sphere if Spot is absent)."""
    from jmeshtex.geometry import remesh
    from jmeshtex.io import load_mesh

    config = model.config
    if (SPOT / "spot_triangulated.obj").exists():
        spot = load_mesh(SPOT / "spot_triangulated.obj", texture=SPOT / "spot_texture.png")
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
        mesh.vertices,
        mesh.faces,
        config.num_samples,
        rng=np.random.default_rng(0),
        center=config.experimental.token == "centre",
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
        texels = rasterize_uv(spot.uv, atlas)
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


def train_step_rows(report: Report, model) -> None:
    """Training steps/s at the shipped configuration."""
    config = model.config
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


def main(argv: list[str] | None = None) -> None:
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
    args = ap.parse_args(argv)
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
    lpips = not args.no_lpips
    reconstruction_rows(
        report,
        models,
        sizes=sizes,
        atlas=args.atlas,
        views=args.views,
        view_size=args.view_size,
        lpips=lpips,
    )
    if args.held_out_size:
        held_out_rows(models, report, size=args.held_out_size, lpips=lpips)
    if not args.no_throughput:
        model = models.get("log", next(iter(models.values())))
        encode_decode_rows(report, model, n=max(sizes), atlas=args.atlas)
        train_step_rows(report, model)
    report.write(pathlib.Path(args.out) if args.out else None)


if __name__ == "__main__":
    jnp.zeros(())  # initialise the backend before timing
    main()

"""Benchmark of the FL-VAE: a Table-1-like reconstruction table and throughput.

Reconstruction (paper Table 1, there on Google Scanned Objects at 30K vertices: FL-VAE 22.38 dB vs
FL-VAE (Bary.) 21.33 dB PSNR): ``../shared/data/spot`` remeshed with
:func:`jmeshtex.geometry.remesh` to about 5K and 30K vertices; the latents live on the remeshed
surface (colours read from the original at closest points), every used texel of Spot's original UV
atlas is decoded (three corner predictions blended) and compared with the original texture: PSNR,
DSSIM, LPIPS-VGG over the used texels. Both shipped models are used (:func:`jmeshtex.fl.load_pretrained`
with ``decoder="log"`` and ``"barycentric"``, the ablation), trained with the same data, steps and seed.

Throughput: encoding (host one-ring sampling and the jitted encoder apart) at 30K vertices in
vertices/s, atlas decoding in texels/s, and training steps/s at the shipped configuration, each
next to the matmul and bandwidth ceilings measured in the same run. Every row carries the 1-minute
load average at the time it was taken (the machine may be shared; re-run on a quiet machine).

Usage::

    python benchmarks/fl_vae.py                      # 5K and 30K, atlas 512², LPIPS
    python benchmarks/fl_vae.py --sizes 5000 --atlas 256 --no-lpips   # quick
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

from jmeshtex import fl
from jmeshtex.geometry import rasterize_uv

SPOT = pathlib.Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "spot"
PAPER = {"log": 22.38, "barycentric": 21.33}  # PSNR at 30K vertices, Google Scanned Objects


def load() -> float:
    return os.getloadavg()[0]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="5000,30000", help="remeshed vertex counts")
    ap.add_argument("--atlas", type=int, default=512, help="atlas side in texels")
    ap.add_argument("--no-lpips", action="store_true")
    ap.add_argument("--models", default=None, help="comma-separated model files (default: the two shipped ones)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    report = Report("fl_vae")
    if args.models is None:
        loaded = [fl.load_pretrained(decoder=d) for d in ("log", "barycentric")]
    else:
        loaded = [fl.load(p) for p in args.models.split(",")]
    models = {m.config.decoder: m for m in loaded}
    sizes = [int(s) for s in args.sizes.split(",")]

    if (SPOT / "spot_triangulated.obj").exists():
        from jmeshtex.geometry import remesh
        from jmeshtex.io import load_mesh

        spot = load_mesh(SPOT / "spot_triangulated.obj", texture=SPOT / "spot_texture.png")
        for n in sizes:
            t0 = time.perf_counter()
            latent = remesh(spot, n_vertices=n, key=jax.random.key(0))
            t_remesh = time.perf_counter() - t0
            for decoder, model in models.items():
                t0 = time.perf_counter()
                r = fl.reconstruct(model, spot, key=jax.random.key(0), size=args.atlas, latent_mesh=latent,
                                   lpips=not args.no_lpips)
                report.add(table="reconstruction", mesh="spot", vertices=latent.num_vertices, model=decoder,
                           atlas=args.atlas, texels=int(r.valid.sum()), **{k: round(v, 4) for k, v in r.metrics.items()},
                           paper_psnr_30k_gso=PAPER[decoder], seconds=time.perf_counter() - t0,
                           remesh_s=round(t_remesh, 2), load=load())
    else:
        print(f"skipping the reconstruction table: {SPOT} not found")

    # -------- throughput at the largest size (on a procedural sphere if Spot is absent)
    model = models.get("log", next(iter(models.values())))
    config = model.config
    n = max(sizes)
    if (SPOT / "spot_triangulated.obj").exists():
        mesh = remesh(spot, n_vertices=n, key=jax.random.key(1))
        colors = fl.surface_colors(spot)
    else:
        from jmeshtex import Mesh
        from jmeshtex.data import icosphere

        v, f = icosphere(6)
        mesh = Mesh(v, f, vertex_colors=0.5 + 0.5 * v)
        colors = fl.surface_colors(mesh)
    t0 = time.perf_counter()
    s = fl.one_ring_samples(mesh.vertices, mesh.faces, config.num_samples, rng=np.random.default_rng(0))
    points = np.einsum("vsk,vskd->vsd", s.bary, mesh.vertices[mesh.faces[s.face]])
    rgb = colors.at_points(points.reshape(-1, 3)).reshape(*s.face.shape, 3)
    t_host = time.perf_counter() - t0
    t0 = time.perf_counter()
    jax.block_until_ready(fl.encode_one_rings(model, s, rgb).mu)
    t_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    jax.block_until_ready(fl.encode_one_rings(model, s, rgb).mu)
    t_enc = time.perf_counter() - t0
    report.add(table="throughput", what="encode: host one-ring sampling + colour lookup", vertices=mesh.num_vertices,
               seconds=t_host, per_s=mesh.num_vertices / t_host, unit="vertices/s", load=load())
    report.add(table="throughput", what=f"encode: jitted encoder (chunks of {config.encode_chunk})",
               vertices=mesh.num_vertices, seconds=t_enc, compile_s=max(t_first - t_enc, 0.0),
               per_s=mesh.num_vertices / t_enc, unit="vertices/s", load=load())
    report.add(table="throughput", what="encode Spot-30K total (sampling + encoder)", vertices=mesh.num_vertices,
               seconds=t_host + t_enc, load=load())
    if (SPOT / "spot_triangulated.obj").exists():
        texels = rasterize_uv(spot.uv, args.atlas)
        face, bary = texels.face, texels.bary
        from jmeshtex.geometry import surface_correspondence

        pts = np.einsum("nk,nkd->nd", bary, spot.vertices[spot.faces[face]])
        lface, lbary = surface_correspondence(mesh.vertices, mesh.faces, pts)
        mu = fl.encode_one_rings(model, s, rgb).mu
        fl.decode_points_in_faces(model, mesh, mu, lface[:1000], lbary[:1000])  # warm-up / compile
        t0 = time.perf_counter()
        fl.decode_points_in_faces(model, mesh, mu, lface, lbary)
        t_dec = time.perf_counter() - t0
        report.add(table="throughput", what="decode atlas texels (3 corner predictions blended)", texels=len(face),
                   seconds=t_dec, per_s=len(face) / t_dec, unit="texels/s", load=load())

    # -------- training steps/s at the shipped configuration
    cfg = config.replace(steps=10)
    params = model.params
    pool = fl.planar_pool(fl.builtin_images(max_size=cfg.max_image_size, names=("brick", "astronaut", "coffee")),
                          per_image=1, min_vertices=cfg.max_vertices, max_vertices=cfg.max_vertices,
                          rng=np.random.default_rng(0))
    batch = fl.mesh_batch(pool[: cfg.batch_size], cfg, np.random.default_rng(0),
                          num_vertices=cfg.batch_size * cfg.max_vertices)
    step = fl.make_train_step(cfg)
    state = (params, fl.optimizer(cfg).init(params))
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
    report.add(table="throughput", what=f"train step ({cfg.batch_size} planar meshes × {cfg.max_vertices} vertices, "
        f"S={cfg.num_samples})", seconds=t_step, compile_s=max(t_first - t_step, 0.0),
        per_s=1.0 / t_step, unit="steps/s", load=load())
    report.write(pathlib.Path(args.out) if args.out else None)


if __name__ == "__main__":
    jnp.zeros(())  # initialise the backend before timing
    main()

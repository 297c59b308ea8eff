"""``jmeshtex fl pretrain|encode|reconstruct``: the FL-VAE of Field Latents (a thin layer over
:mod:`jmeshtex.fl`).

- ``pretrain`` trains an FL-VAE on planar meshes over images (``--images builtin`` = scikit-image's
  bundled images, or a folder), resumable in ``--out``;
- ``encode`` writes a mesh's latents (``mu``, ``log_sigma``) to an ``.npz``;
- ``reconstruct`` encodes a textured mesh (optionally remeshed to ``--vertices``) and writes the
  reconstructed texture atlas PNG, a side-by-side render and ``metrics.json`` (PSNR, DSSIM, LPIPS).
"""

from __future__ import annotations

import argparse
import json
import pathlib


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("fl", help="Field Latents VAE: pre-train, encode, reconstruct textures",
                       description="FL-VAE (Mitchel et al. 2024): textures as tangent-vector latents at vertices.")
    inner = p.add_subparsers(dest="fl_command", metavar="ACTION")

    t = inner.add_parser("pretrain", help="train an FL-VAE on planar meshes over images")
    t.add_argument("--images", default="builtin", metavar="DIR|builtin",
                   help="folder of PNG/JPEG images, or 'builtin' (scikit-image's bundled images)")
    t.add_argument("--out", type=pathlib.Path, required=True, metavar="DIR",
                   help="output folder (checkpoint.npz, log.json, fl_vae.npz); an existing run there resumes")
    t.add_argument("--steps", type=int, default=None, help="optimiser steps (default: FLVAEConfig.steps)")
    t.add_argument("--decoder", choices=("log", "barycentric"), default=None,
                   help="decoder variant (barycentric = the paper's ablation)")
    t.add_argument("--config", type=pathlib.Path, default=None, metavar="JSON",
                   help="FLVAEConfig fields as JSON (overridden by --steps/--decoder/--seed)")
    t.add_argument("--seed", type=int, default=None, help="PRNG seed")
    t.add_argument("--quiet", action="store_true", help="no progress bar")
    t.set_defaults(func=_pretrain)

    e = inner.add_parser("encode", help="encode a mesh's texture or vertex colours as latents")
    _mesh_args(e)
    e.add_argument("--out", type=pathlib.Path, required=True, metavar="FILE.npz", help="latents file")
    e.set_defaults(func=_encode)

    r = inner.add_parser("reconstruct", help="encode + decode a textured mesh's atlas, with metrics")
    _mesh_args(r)
    r.add_argument("--out", type=pathlib.Path, required=True, metavar="DIR", help="output folder")
    r.add_argument("--size", type=int, default=None, help="atlas side in texels (default: the texture's)")
    r.add_argument("--vertices", type=int, default=None,
                   help="remesh to about this many vertices first (latents on the remeshed surface)")
    r.add_argument("--no-lpips", action="store_true", help="skip LPIPS (a VGG-16 pass)")
    r.set_defaults(func=_reconstruct)
    p.set_defaults(func=lambda args: (p.print_help(), 1)[1])


def _mesh_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--mesh", type=pathlib.Path, required=True, metavar="M", help="mesh file (OBJ, PLY, OFF, GLB)")
    p.add_argument("--texture", type=pathlib.Path, default=None, metavar="T", help="texture image of the mesh")
    p.add_argument("--model", type=pathlib.Path, default=None, metavar="FILE.npz",
                   help="FL-VAE file from `fl pretrain` (default: the shipped pre-trained model)")
    p.add_argument("--seed", type=int, default=0, help="seed of the one-ring sampling (default 0)")


def _model(args):
    from ..fl import load_fl_vae, load_pretrained

    return load_pretrained() if args.model is None else load_fl_vae(args.model)


def _load(args):
    from ..io import load_mesh

    return load_mesh(args.mesh, texture=args.texture)


def _pretrain(args) -> int:
    from .._errors import MeshIOError
    from ..fl import FLVAEConfig, pretrain

    data = {}
    if args.config is not None:
        try:
            data = json.loads(args.config.read_text())
        except (OSError, ValueError) as err:
            raise MeshIOError(f"cannot read config {args.config}: {err}") from err
    for name in ("steps", "decoder", "seed"):
        if getattr(args, name) is not None:
            data[name] = getattr(args, name)
    config = FLVAEConfig.from_dict(data)
    result = pretrain(args.out, config, images=args.images, progress=not args.quiet)
    summary = {"out": str(args.out / "fl_vae.npz"), "steps": config.steps,
               "final_loss": float(result.losses[-50:].mean()) if len(result.losses) else None,
               "final_l1": float(result.l1[-50:].mean()) if len(result.l1) else None,
               "steps_per_second": result.steps_per_second}
    print(json.dumps(summary, indent=2))
    return 0


def _encode(args) -> int:
    import jax
    import numpy as np

    from ..fl import encode_mesh
    from ..io import atomic_save_npz

    params, config = _model(args)
    mesh = _load(args)
    lat = encode_mesh(params, config, mesh, key=jax.random.key(args.seed))
    atomic_save_npz(args.out, {"mu": np.asarray(lat.mu), "log_sigma": np.asarray(lat.log_sigma),
                               "vertices": mesh.vertices, "faces": mesh.faces})
    print(json.dumps({"out": str(args.out), "vertices": mesh.num_vertices, "latent_dim": config.latent_dim}))
    return 0


def _reconstruct(args) -> int:
    import jax

    from ..fl import reconstruct, side_by_side
    from ..geometry import remesh
    from ..render import write_png

    params, config = _model(args)
    mesh = _load(args)
    latent_mesh = None if args.vertices is None else remesh(mesh, n_vertices=args.vertices, seed=args.seed)
    result = reconstruct(params, config, mesh, key=jax.random.key(args.seed), size=args.size,
                         latent_mesh=latent_mesh, lpips=not args.no_lpips)
    args.out.mkdir(parents=True, exist_ok=True)
    write_png(args.out / "reconstructed_texture.png", (result.texture * 255).round().astype("uint8"))
    side_by_side(mesh, result, args.out / "side_by_side.png")
    metrics = {**result.metrics, "latent_vertices": result.latent_mesh.num_vertices,
               "decoder": config.decoder, "texels": int(result.valid.sum())}
    from ..io import atomic_write

    atomic_write(args.out / "metrics.json", json.dumps(metrics, indent=2).encode())
    print(json.dumps(metrics, indent=2))
    return 0

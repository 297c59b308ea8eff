"""``jmeshtex fl train|encode|reconstruct``: the FL-VAE of Field Latents (a thin layer over
:mod:`jmeshtex.fl`).

- ``train`` (alias ``pretrain``) trains an FL-VAE on planar meshes over images (``--images builtin``
  = scikit-image's bundled images, or a folder; ``--preset small|paper`` = ``Config.small()`` /
  ``Config.paper()`` of :class:`jmeshtex.fl.Config`, the stream of
  augmented crops and procedural textures at ≈ 26 pixels per vertex): ``--out/model.npz`` (:func:`jmeshtex.fl.save`),
  ``--out/loss_curve.png``, resumable from ``--out/checkpoints`` (run the same command again);
- ``encode`` writes a mesh's latents (``mu``, ``log_sigma``) to an ``.npz``;
- ``reconstruct`` encodes a textured mesh (optionally remeshed to ``--vertices``) and writes the
  reconstructed texture atlas PNG, a side-by-side render and ``metrics.json`` (PSNR, DSSIM, LPIPS),
  each beside the same metrics of its baselines: the P1 oracle, the least-squares P1 fit and the
  best flat colour (:func:`~jmeshtex.fl.core.baseline_metrics`).

Every mesh argument is a file or a procedural spec (``icosphere:3``, ``striped-sphere``, ...;
:func:`~jmeshtex.cli._common.load_mesh_spec`); ``--seed`` makes the ``key`` of the library call.
"""

from __future__ import annotations

import argparse
import json
import pathlib

from ._common import (
    MAX_SPEC_VERTICES,
    MAX_TEXTURE_SIZE,
    add_common,
    add_method,
    cached,
    check_checkpoints,
    int_in,
    load_mesh_spec,
)
from ._output import check_output_file, claim_args


def register(sub: argparse._SubParsersAction) -> None:
    inner = add_method(
        sub,
        "fl",
        help="Field Latents VAE: train, encode, reconstruct textures",
        description="FL-VAE (Mitchel et al. 2024): textures as tangent-vector latents at vertices.",
    )

    t = inner.add_parser(
        "train", aliases=["pretrain"], help="train an FL-VAE on planar meshes over images"
    )
    t.add_argument(
        "--images",
        default="builtin",
        metavar="DIR|builtin",
        help="folder of PNG/JPEG images, or 'builtin' (scikit-image's bundled images)",
    )
    add_common(t, out="output folder (model.npz, checkpoints/); an existing run there resumes")
    t.add_argument(
        "--steps",
        type=int_in(1, 10_000_000),
        default=None,
        help="optimiser steps (default: Config.steps)",
    )
    t.add_argument(
        "--decoder",
        choices=("log", "barycentric"),
        default=None,
        help="decoder variant (barycentric = the paper's ablation)",
    )
    t.add_argument(
        "--preset",
        choices=("small", "paper"),
        default=None,
        help="Config.small() (2 CPU cores) or Config.paper() (C=128, 8 layers; for a GPU); "
        "default: Config() (the shipped model's recipe)",
    )
    t.add_argument(
        "--config",
        type=pathlib.Path,
        default=None,
        metavar="JSON",
        help="jmeshtex.fl.Config fields as JSON, applied over the preset (overridden by --steps/--decoder)",
    )
    t.add_argument(
        "--stop-after",
        type=int_in(1),
        default=None,
        metavar="N",
        help="run at most N steps in this call (the schedule follows --steps; rerun to continue)",
    )
    t.set_defaults(func=cached(_train))

    e = inner.add_parser("encode", help="encode a mesh's texture or vertex colours as latents")
    _mesh_args(e)
    add_common(e, out="latents file (.npz)", quiet=False)
    e.set_defaults(func=cached(_encode))

    r = inner.add_parser(
        "reconstruct", help="encode + decode a textured mesh's atlas, with metrics"
    )
    _mesh_args(r)
    add_common(r, out="output folder", quiet=False)
    r.add_argument(
        "--size",
        type=int_in(8, MAX_TEXTURE_SIZE),
        default=None,
        help=f"atlas side in texels, at most {MAX_TEXTURE_SIZE} (default: the texture's)",
    )
    r.add_argument(
        "--vertices",
        type=int_in(4, MAX_SPEC_VERTICES),
        default=None,
        help="remesh to about this many vertices first (latents on the remeshed surface)",
    )
    r.add_argument("--no-lpips", action="store_true", help="skip LPIPS (a VGG-16 pass)")
    r.set_defaults(func=cached(_reconstruct))


def _mesh_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--mesh",
        required=True,
        metavar="M",
        help="mesh file (OBJ, PLY, OFF, GLB) or procedural spec (icosphere:3, striped-sphere, ...)",
    )
    p.add_argument(
        "--texture", type=pathlib.Path, default=None, metavar="T", help="texture image of the mesh"
    )
    p.add_argument(
        "--model",
        type=pathlib.Path,
        default=None,
        metavar="DIR",
        help="FL-VAE folder of `fl train` (default: the shipped pre-trained model)",
    )


def _model(args):
    from ..fl import load, load_pretrained

    return load_pretrained() if args.model is None else load(args.model)


def _train(args) -> int:
    import jax

    from .._errors import ConfigError, MeshIOError
    from ..fl import Config, save, train

    claim_args(args, "fl train", args.config, args.images)
    check_checkpoints(args.out / "checkpoints")
    data = {}
    if args.config is not None:
        try:
            data = json.loads(args.config.read_text())
        except (OSError, ValueError) as err:
            raise MeshIOError(f"cannot read config {args.config}: {err}") from err
        if not isinstance(data, dict):
            raise ConfigError(
                f"{args.config} must hold a JSON object of fl.Config fields, "
                f"got a {type(data).__name__}"
            )
    for name in ("steps", "decoder"):
        if getattr(args, name) is not None:
            data[name] = getattr(args, name)
    base = {"small": Config.small, "paper": Config.paper}.get(args.preset, Config)()
    config = base.replace(**data)
    result = train(
        args.images,
        config,
        key=jax.random.key(args.seed),
        progress=not args.quiet,
        checkpoint_dir=args.out / "checkpoints",
        loss_curve=args.out / "loss_curve.png",
        stop_after=args.stop_after,
    )
    loss, l1 = result.losses["loss"], result.losses["l1"]
    # each latent channel's KL in nats over the last 50 steps: near 0 means a collapsed channel
    kl = [
        float(result.losses[f"kl{c}"][-50:].mean())
        for c in range(config.latent_dim)
        if len(result.losses.get(f"kl{c}", ()))
    ]
    summary = {
        "out": str(args.out),
        "steps": result.steps,
        "final_loss": float(loss[-50:].mean()) if len(loss) else None,
        "final_l1": float(l1[-50:].mean()) if len(l1) else None,
        "steps_per_second": result.extra["steps_per_second"],
        "kl_channels": [round(x, 4) for x in kl] or None,
        "channels_above_0.1_nat": sum(x > 0.1 for x in kl) if kl else None,
        "preset": args.preset,
        "loss_curve": str(args.out / "loss_curve.png"),
    }
    save(
        result.model,
        args.out,
        extra={
            k: summary[k]
            for k in ("steps", "final_loss", "final_l1", "kl_channels", "channels_above_0.1_nat")
        }
        | {"seed": args.seed},
    )
    print(json.dumps(summary, indent=2))
    return 0


def _encode(args) -> int:
    import jax
    import numpy as np

    from ..fl import encode
    from ..io import atomic_save_npz

    check_output_file(args.out, (args.mesh, args.texture, args.model))
    model = _model(args)
    mesh = load_mesh_spec(args.mesh, texture=args.texture)
    lat = encode(model, mesh, key=jax.random.key(args.seed))
    if not (np.isfinite(np.asarray(lat.mu)).all() and np.isfinite(np.asarray(lat.log_sigma)).all()):
        from .._errors import InputError

        raise InputError(
            "encoding produced non-finite latents (NaN or inf): check the mesh's scale and its "
            "texture or colours; nothing was written"
        )
    atomic_save_npz(
        args.out,
        {
            "mu": np.asarray(lat.mu),
            "log_sigma": np.asarray(lat.log_sigma),
            "vertices": mesh.vertices,
            "faces": mesh.faces,
        },
    )
    print(
        json.dumps(
            {
                "out": str(args.out),
                "vertices": mesh.num_vertices,
                "latent_dim": model.config.latent_dim,
            }
        )
    )
    return 0


def _reconstruct(args) -> int:
    import jax

    from ..fl import reconstruct
    from ..fl.core import baseline_metrics, side_by_side
    from ..geometry import remesh
    from ..io import atomic_write, save_png

    claim_args(args, "fl reconstruct", args.mesh, args.texture, args.model)
    model = _model(args)
    mesh = load_mesh_spec(args.mesh, texture=args.texture)
    latent_mesh = (
        None
        if args.vertices is None
        else remesh(mesh, n_vertices=args.vertices, key=jax.random.key(args.seed))
    )
    result = reconstruct(
        model,
        mesh,
        key=jax.random.key(args.seed),
        size=args.size,
        latent_mesh=latent_mesh,
        lpips=not args.no_lpips,
    )
    args.out.mkdir(parents=True, exist_ok=True)
    save_png(result.texture, args.out / "reconstructed_texture.png")
    baselines = baseline_metrics(mesh, result, lpips=not args.no_lpips)
    side_by_side(mesh, result, args.out / "side_by_side.png", baselines=baselines)
    metrics = {
        **result.metrics,
        "latent_vertices": result.latent_mesh.num_vertices,
        "decoder": model.config.decoder,
        "texels": int(result.valid.sum()),
        "baselines": baselines,  # the same metrics of P1 oracle, P1 least-squares fit, flat colour
    }
    atomic_write(args.out / "metrics.json", json.dumps(metrics, indent=2).encode())
    print(json.dumps(metrics, indent=2))
    return 0

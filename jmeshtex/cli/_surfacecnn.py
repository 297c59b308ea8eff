"""``jmeshtex surfacecnn synthesize|stylize``: surface-aware texture synthesis with a pre-trained 2D
CNN run on the mesh (a thin layer over :mod:`jmeshtex.surfacecnn`).

``synthesize`` optimises a texture in the mesh's UV layout (unwrapped with xatlas when the mesh has
no UVs) whose VGG Gram statistics match an exemplar image; ``stylize`` transfers the style of an
image onto the mesh's existing texture. Both write the texture PNG, a textured OBJ, renders and a
JSON summary, and show a progress bar with the loss.
"""

from __future__ import annotations

import argparse
import pathlib


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("surfacecnn", help="texture synthesis with a pre-trained 2D CNN run on the mesh",
                       description="Surface-aware mesh texture synthesis (Kovács et al. 2024).")
    inner = p.add_subparsers(dest="surfacecnn_command", metavar="ACTION")
    s = inner.add_parser("synthesize", help="synthesise a texture matching an exemplar image")
    s.add_argument("--mesh", type=pathlib.Path, required=True, metavar="M", help="mesh file (UVs optional)")
    s.add_argument("--exemplar", type=pathlib.Path, required=True, metavar="IMG", help="exemplar image")
    _common(s)
    s.set_defaults(func=_synthesize)
    t = inner.add_parser("stylize", help="transfer an image's style onto the mesh's texture")
    t.add_argument("--mesh", type=pathlib.Path, required=True, metavar="M", help="mesh file with UVs")
    t.add_argument("--content", type=pathlib.Path, metavar="T",
                   help="content texture in the mesh's UV layout (default: the texture the mesh file references)")
    t.add_argument("--style", type=pathlib.Path, required=True, metavar="IMG", help="style image")
    t.add_argument("--content-weight", type=float, default=1.0, help="weight of the content term (default 1)")
    t.add_argument("--content-layer", default="relu4_2", help="feature map of the content term (default relu4_2)")
    _common(t)
    t.set_defaults(func=_stylize)
    p.set_defaults(func=lambda args: (p.print_help(), 1)[1])


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=pathlib.Path, required=True, metavar="DIR", help="output folder")
    p.add_argument("--size", type=int, default=512, help="texture resolution (default 512)")
    p.add_argument("--steps", type=int, default=500, help="optimisation steps (default 500)")
    p.add_argument("--seed", type=int, default=0, help="PRNG seed (default 0)")
    p.add_argument("--max-image-size", type=int, default=512,
                   help="exemplar/style images are downscaled to at most this many pixels per side (default 512)")
    p.add_argument("--layers", default=None,
                   help="comma-separated Gram layers, e.g. relu1_1,relu2_1 (default: every ReLU and pool)")
    p.add_argument("--pool", choices=("mean", "max"), default="mean", help="pooling (default mean, as the paper)")
    p.add_argument("--vgg19", type=pathlib.Path, default=None, metavar="FILE",
                   help="use VGG-19 weights from a .npz or Keras .h5 file (the paper's network)")
    p.add_argument("--resume", action="store_true",
                   help="continue from DIR/checkpoint.npz of an interrupted run (written every 50 steps)")
    p.add_argument("--repair", action="store_true",
                   help="repair the mesh first (drop degenerate/duplicate faces, split bow-tie vertices, re-orient)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _image(path: pathlib.Path, max_size: int):
    import numpy as np

    from ..io import load_texture

    image = load_texture(path)
    if image.shape[2] in (1, 2):
        image = np.repeat(image[..., :1], 3, axis=2)
    image = image[..., :3]
    scale = max_size / max(image.shape[:2])
    if scale < 1:
        import skimage.transform

        shape = (max(1, round(image.shape[0] * scale)), max(1, round(image.shape[1] * scale)))
        image = skimage.transform.resize(image, shape, anti_aliasing=True).astype(np.float32)
    return np.clip(image, 0.0, 1.0)


def _setup(args):
    from ..geometry import prepare_mesh, validate_mesh
    from ..io import load_mesh
    from ..surfacecnn import SurfaceCNNConfig, load_vgg19

    mesh = load_mesh(args.mesh, texture=getattr(args, "content", None))
    if args.repair:
        mesh, _ = prepare_mesh(mesh, repair=True)
    validate_mesh(mesh.vertices, mesh.faces)  # a clear typed error for a broken mesh before any work
    layers = tuple(x.strip() for x in args.layers.split(",") if x.strip()) if args.layers else None
    extra = {}
    if hasattr(args, "content_weight"):
        extra = {"content_weight": args.content_weight, "content_layer": args.content_layer}
    config = SurfaceCNNConfig(size=args.size, steps=args.steps, pool=args.pool, layers=layers, **extra)
    weights = load_vgg19(args.vgg19) if args.vgg19 else None
    return mesh, config, weights


def _checkpoint(args) -> pathlib.Path:
    """``DIR/checkpoint.npz``; without ``--resume`` a stale one is removed so the run starts afresh."""
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "checkpoint.npz"
    if not args.resume:
        path.unlink(missing_ok=True)
    return path


def _report(summary: dict, out: pathlib.Path) -> None:
    print(f"wrote {out / 'texture.png'}, {out / 'textured.obj'} and renders to {out}: loss "
          f"{summary['initial_loss']:.4g} -> {summary['final_loss']:.4g}, {summary['texels']} texels, "
          f"precompute {summary['atlas_s'] + summary['taps_s'] + summary['pyramid_s']:.1f} s, "
          f"optimisation {summary['optimize_s']:.1f} s")


def _synthesize(args: argparse.Namespace) -> int:
    import jax

    from ..surfacecnn import save_result, synthesize_texture

    mesh, config, weights = _setup(args)
    exemplar = _image(args.exemplar, args.max_image_size)
    result = synthesize_texture(mesh, exemplar, config=config, key=jax.random.key(args.seed), weights=weights,
                                progress=not args.quiet, checkpoint=_checkpoint(args))
    summary = save_result(result, args.out, exemplar=exemplar, title="synthesised")
    _report(summary, args.out)
    return 0


def _stylize(args: argparse.Namespace) -> int:
    from .._errors import InputError
    from ..surfacecnn import save_result, stylize_texture

    mesh, config, weights = _setup(args)
    if mesh.texture is None:
        raise InputError(f"{args.mesh} references no texture; give the content texture with --content")
    style = _image(args.style, args.max_image_size)
    result = stylize_texture(mesh, mesh.texture, style, config=config, weights=weights, progress=not args.quiet,
                             checkpoint=_checkpoint(args))
    summary = save_result(result, args.out, exemplar=style, title="stylised")
    _report(summary, args.out)
    return 0

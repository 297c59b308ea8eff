"""``jmeshtex surfacecnn synthesize|stylize``: surface-aware texture synthesis with a pre-trained 2D
CNN run on the mesh (a thin layer over :mod:`jmeshtex.surfacecnn`).

``synthesize`` optimises a texture in the mesh's UV layout (unwrapped with xatlas when the mesh has
no UVs) whose VGG Gram statistics match an exemplar image; ``stylize`` transfers the style of an
image onto the mesh's existing texture. Both write the result folder of
:func:`jmeshtex.surfacecnn.save` (texture PNG, textured OBJ, ``result.npz``, a JSON summary) and
the renders (``render_front.png``, ``render_back.png``, ``surfacecnn.png``, ``views.png``; ``--up``
names the mesh's up axis), and show a progress bar with the loss (``--quiet``: none).

Every mesh argument is a file or a procedural spec (``icosphere:3``, ``torus``, ...;
:func:`~jmeshtex.cli._common.load_mesh_spec`); ``--seed`` makes the ``key`` of the library call.
"""

from __future__ import annotations

import argparse
import json
import pathlib

from ..geometry import UP_AXES
from ._common import (
    add_common,
    add_method,
    cached,
    float_in,
    int_in,
    load_mesh_spec,
    procedural_mesh,
)
from ._output import claim_args, owns

#: the folder under ``--out`` that holds the resumable checkpoints
CHECKPOINTS = "checkpoints"


def register(sub: argparse._SubParsersAction) -> None:
    inner = add_method(
        sub,
        "surfacecnn",
        help="texture synthesis with a pre-trained 2D CNN run on the mesh",
        description="Surface-aware mesh texture synthesis (Kovács et al. 2024).",
    )
    s = inner.add_parser("synthesize", help="synthesise a texture matching an exemplar image")
    s.add_argument(
        "--mesh",
        required=True,
        metavar="M",
        help="mesh file (UVs optional) or procedural spec (icosphere:3, torus, ...)",
    )
    s.add_argument(
        "--exemplar", type=pathlib.Path, required=True, metavar="IMG", help="exemplar image"
    )
    _options(s)
    s.add_argument(
        "--unwrap",
        choices=("xatlas", "mesh"),
        default="xatlas",
        help="texture layout: xatlas (default, as the paper's tool: an even texel density) or mesh "
        "(the mesh file's own UVs; their texel-density spread is printed)",
    )
    s.set_defaults(func=cached(_synthesize))
    t = inner.add_parser("stylize", help="transfer an image's style onto the mesh's texture")
    t.add_argument("--mesh", required=True, metavar="M", help="mesh file with UVs")
    t.add_argument(
        "--content",
        type=pathlib.Path,
        metavar="T",
        help="content texture in the mesh's UV layout (default: the texture the mesh file references)",
    )
    t.add_argument("--style", type=pathlib.Path, required=True, metavar="IMG", help="style image")
    t.add_argument(
        "--content-weight",
        type=float,
        default=None,
        help="weight of the content term (default: the reference's 1000 for VGG-19, rescaled to "
        "≈0.30 for the embedded VGG-16)",
    )
    t.add_argument(
        "--content-layer",
        default="relu4_2",
        help="feature map of the content term (default relu4_2)",
    )
    _options(t)
    t.set_defaults(func=cached(_stylize))


def _options(p: argparse.ArgumentParser) -> None:
    add_common(p, out="output folder (texture, textured mesh, renders, result.npz, checkpoints/)")
    p.add_argument(
        "--up",
        default=None,
        choices=UP_AXES,
        metavar="AXIS",
        help=f"up axis of the mesh in renders: {'|'.join(UP_AXES)} (default: y for mesh files, the "
        "OBJ/glTF convention; z for procedural meshes)",
    )
    p.add_argument(
        "--size",
        type=int_in(8, 2048),
        default=512,
        help="texture resolution (default 512, the CPU preset; --size 1024 is the paper's)",
    )
    p.add_argument(
        "--steps", type=int_in(1, 10_000_000), default=500, help="optimisation steps (default 500)"
    )
    p.add_argument(
        "--exemplar-scale",
        type=float_in(1 / 64, 64),
        default=1.0,
        metavar="S",
        help="texels per exemplar pixel: the exemplar is resampled by S before matching (default 1:"
        " its native resolution, the paper's)",
    )
    p.add_argument(
        "--max-image-size",
        type=int_in(1, 16384),
        default=None,
        help="downscale exemplar/style images to at most this many pixels per side after "
        "--exemplar-scale (default: no limit)",
    )
    p.add_argument(
        "--layers",
        default=None,
        help="comma-separated Gram layers, e.g. relu1_1,relu2_1 (default: every ReLU and pool)",
    )
    p.add_argument(
        "--pool",
        choices=("mean", "max"),
        default="mean",
        help="pooling (default mean, as the paper)",
    )
    p.add_argument(
        "--frames",
        choices=("global", "smooth", "uv"),
        default="global",
        help="texel tangent frames: global (the paper's: x projected on the surface), smooth (the "
        "smoothest direction field) or uv (the UV layout's; jumps at seams, an ablation)",
    )
    p.add_argument(
        "--frame-smoothing",
        type=float_in(0.0, 64.0),
        default=None,
        metavar="TEXELS",
        help="radius in texels over which the global frames turn at creases (default: "
        "surfacecnn.Config's, 4; 0: the paper's frames, which turn at once)",
    )
    p.add_argument(
        "--vgg19",
        type=pathlib.Path,
        default=None,
        metavar="FILE",
        help="use VGG-19 weights from a .npz or Keras .h5 file (the paper's network)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help=f"continue from DIR/{CHECKPOINTS}/ of an interrupted run (written every 50 steps)",
    )
    p.add_argument(
        "--repair",
        action="store_true",
        help="repair the mesh first (drop degenerate/duplicate faces, split bow-tie vertices, re-orient)",
    )


def _image(path: pathlib.Path, max_size: int | None, scale: float = 1.0):
    """An RGB image in [0, 1], resampled by ``scale`` (texels per image pixel), then to at most
    ``max_size`` pixels per side (None: no limit)."""
    import numpy as np

    from ..io import load_texture

    image = load_texture(path)
    if image.shape[2] in (1, 2):
        image = np.repeat(image[..., :1], 3, axis=2)
    image = image[..., :3]
    if max_size is not None:
        scale = min(scale, max_size / max(image.shape[:2]))
    if scale != 1:
        import skimage.transform

        shape = (max(1, round(image.shape[0] * scale)), max(1, round(image.shape[1] * scale)))
        image = skimage.transform.resize(image, shape, anti_aliasing=True).astype(np.float32)
    return np.clip(image, 0.0, 1.0)


def render_up(args: argparse.Namespace) -> str:
    """The up axis of the renders: ``--up``, else ``"y"`` for a mesh file (the OBJ/glTF
    convention) and ``"z"`` for a procedural spec (jmeshtex's meshes are Z-up).

    Example:
      >>> render_up(argparse.Namespace(up=None, mesh="spot.obj")), render_up(
      ...     argparse.Namespace(up=None, mesh="torus"))
      ('y', 'z')
    """
    if args.up is not None:
        return args.up
    return "z" if procedural_mesh(args.mesh) is not None else "y"


def _setup(args):
    from ..geometry import prepare_mesh, validate_mesh
    from ..metrics import load_vgg19
    from ..surfacecnn import Config

    mesh = load_mesh_spec(args.mesh, texture=getattr(args, "content", None))
    if args.repair:
        mesh, _ = prepare_mesh(mesh, repair=True)
    validate_mesh(
        mesh.vertices, mesh.faces
    )  # a clear typed error for a broken mesh before any work
    unwrap = getattr(args, "unwrap", "mesh")  # stylize keeps the mesh's UVs
    if unwrap == "xatlas" or mesh.uv is None:
        _check_unwrap_scale(mesh, args.mesh)  # synthesize (Config.unwrap) unwraps
    else:
        from ..surfacecnn.core import texel_density_spread

        spread = texel_density_spread(mesh.vertices, mesh.faces, mesh.uv)
        print(
            f"{args.mesh}: its own UVs; texel density (world size of a texel) varies "
            f"{spread['ratio_p95_p5']:.2f}x between the 5th and 95th percentile of the surface "
            "(--unwrap xatlas evens it)"
        )
    layers = tuple(x.strip() for x in args.layers.split(",") if x.strip()) if args.layers else None
    extra = {}
    if hasattr(args, "content_weight"):
        extra = {"content_weight": args.content_weight, "content_layer": args.content_layer}
    config = Config(
        size=args.size,
        steps=args.steps,
        pool=args.pool,
        layers=layers,
        frames=args.frames,
        unwrap=unwrap,
        **extra,
        **({} if args.frame_smoothing is None else {"frame_smoothing": args.frame_smoothing}),
    )
    weights = load_vgg19(args.vgg19) if args.vgg19 else None
    return mesh, config, weights


#: the commands whose ``checkpoints/`` surfacecnn may resume from or delete
_OWNERS = ("surfacecnn synthesize", "surfacecnn stylize")


#: the bounding-box diagonals between which xatlas unwraps reliably (it loops forever at ~1e12 and
#: fails below ~1e-3: absolute tolerances inside it); coordinates may sit at most this far off centre
_UNWRAP_DIAGONAL = (1e-2, 1e6)
_UNWRAP_OFFSET = 1e4


def _check_unwrap_scale(mesh, spec) -> None:
    """Refuse, before xatlas runs, a mesh without UVs whose size or offset xatlas cannot unwrap."""
    import numpy as np

    from .._errors import InputError

    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    diagonal = float(np.linalg.norm(hi - lo))
    offset = float(np.abs((lo + hi) / 2).max())
    low, high = _UNWRAP_DIAGONAL
    if not low <= diagonal <= high or offset > _UNWRAP_OFFSET * diagonal:
        raise InputError(
            f"{spec} has no UVs, and its size (bounding-box diagonal {diagonal:.3g}, centre "
            f"{offset:.3g} from the origin) is outside what the UV unwrapper handles (diagonal "
            f"{low:g} to {high:g}, centre within {_UNWRAP_OFFSET:g} diagonals): rescale and centre "
            "the mesh (e.g. jmeshtex.geometry.rescale_to_mean_edge), or give it UVs"
        )


def _checkpoint(args) -> pathlib.Path:
    """``DIR/checkpoints``; without ``--resume`` a stale one of an earlier surfacecnn run in this
    folder is removed so the run starts afresh. Another command's ``checkpoints/`` is never deleted
    (nor resumed from): a typed error asks for another ``--out``."""
    import shutil

    from .._errors import InputError

    path = args.out / CHECKPOINTS
    if path.is_symlink() or (path.exists() and not path.is_dir()):
        raise InputError(
            f"{path} is a symbolic link or not a folder: refusing to write, delete or resume "
            "through it. Fix: remove it, or pick a new --out folder"
        )
    if path.exists() and not owns(args.out, CHECKPOINTS, _OWNERS):
        raise InputError(
            f"{path} was not written by jmeshtex surfacecnn: refusing to delete or resume from it. "
            "Fix: pick a new --out folder (or move that folder away)"
        )
    if not args.resume and path.is_dir():
        shutil.rmtree(path)
    return path


def _render(result, out: pathlib.Path, *, exemplar, title: str, up: str) -> list[pathlib.Path]:
    """The renders of a result: front and back views, the exemplar | views | texture panel and an
    orbit of four views (the library's :func:`jmeshtex.surfacecnn.save` writes data only)."""
    import numpy as np

    from .. import render
    from ..io import save_png

    mesh = result.mesh.replace(texture=result.texture)
    paths, views = [], []
    for name, view in (("render_front.png", (20.0, -60.0)), ("render_back.png", (20.0, 120.0))):
        image = render.render_mesh(
            mesh, view=view, size=(420, 400), title=f"{title} ({name[7:-4]})", up=up
        )
        save_png(image, out / name)
        paths.append(out / name)
        views.append(image)
    panels = [np.clip(np.asarray(exemplar, np.float32), 0, 1), *views, result.texture]
    titles = ["exemplar", None, None, "texture (UV layout)"]
    height = max(np.shape(v)[0] for v in views)
    # small images enlarged (nearest, integer factor) to the renders' height
    factors = [max(1, height // np.shape(pn)[0]) for pn in panels]
    panels = [np.repeat(np.repeat(pn, k, 0), k, 1) for pn, k in zip(panels, factors, strict=True)]
    render.render_grid(panels, out / "surfacecnn.png", titles=titles, columns=len(panels))
    paths.append(out / "surfacecnn.png")
    cameras = render.orbit_cameras(mesh, azimuths=4, elevations=(20.0,), size=(256, 256), up=up)
    orbit = render.render_views(mesh, cameras)
    render.figure(
        [(f"azimuth {90 * i}°", img) for i, img in enumerate(orbit)],
        columns=4,
        title=title,
        path=out / "views.png",
    )
    paths.append(out / "views.png")
    return paths


def _report(summary: dict, out: pathlib.Path) -> None:
    print(
        f"wrote {out / 'texture.png'}, {out / 'textured.obj'} and renders to {out}: loss "
        f"{summary['initial_loss']:.4g} -> {summary['final_loss']:.4g}, {summary['texels']} texels, "
        f"precompute {summary['atlas_s'] + summary['taps_s'] + summary['pyramid_s']:.1f} s, "
        f"optimisation {summary['optimize_s']:.1f} s"
    )


def _synthesize(args: argparse.Namespace) -> int:
    from ..surfacecnn import synthesize

    claim_args(args, "surfacecnn synthesize", args.mesh, args.exemplar, args.vgg19)
    checkpoint = _checkpoint(args)
    mesh, config, weights = _setup(args)
    exemplar = _image(args.exemplar, args.max_image_size, args.exemplar_scale)
    result = synthesize(mesh, exemplar, config, **_run_keywords(args, weights, checkpoint))
    return _save_and_report(result, args, exemplar, "synthesised")


def _stylize(args: argparse.Namespace) -> int:
    from .._errors import InputError
    from ..surfacecnn import stylize

    claim_args(args, "surfacecnn stylize", args.mesh, args.content, args.style, args.vgg19)
    checkpoint = _checkpoint(args)
    mesh, config, weights = _setup(args)
    if mesh.texture is None:
        raise InputError(
            f"{args.mesh} references no texture; give the content texture with --content"
        )
    style = _image(args.style, args.max_image_size, args.exemplar_scale)
    result = stylize(mesh, mesh.texture, style, config, **_run_keywords(args, weights, checkpoint))
    return _save_and_report(result, args, style, "stylised")


def _run_keywords(args: argparse.Namespace, weights, checkpoint) -> dict:
    """The keywords ``synthesize`` and ``stylize`` share: key, VGG weights, progress, checkpoints."""
    import jax

    return {
        "key": jax.random.key(args.seed),
        "weights": weights,
        "progress": not args.quiet,
        "checkpoint_dir": checkpoint,
    }


def _save_and_report(result, args: argparse.Namespace, exemplar, title: str) -> int:
    """Save ``result`` in ``--out``, render it beside ``exemplar`` and print its summary."""
    from ..surfacecnn import save

    summary = json.loads((save(result, args.out) / "summary.json").read_text())
    _render(result, args.out, exemplar=exemplar, title=title, up=render_up(args))
    _report(summary, args.out)
    return 0

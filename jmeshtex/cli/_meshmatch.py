"""``jmeshtex meshmatch transfer|paint|displace``: MeshMatch texture transfer (a thin layer over
:mod:`jmeshtex.meshmatch`).

``transfer`` synthesises the source's colours (vertex colours or UV texture) on the target and
writes the textured target, renders of source, target and the nearest-neighbour field, a JSON
summary and the result itself (:func:`jmeshtex.meshmatch.save`: read it back with
:func:`jmeshtex.meshmatch.load`); ``paint`` completes a partly painted mesh from its painted region
(a mask file: a ``.npy`` bool array per vertex, or a text file of painted vertex indices);
``displace`` moves the target along its normals by the source's geometric detail
(:func:`jmeshtex.meshmatch.transfer_displacement`). Mesh arguments are files or procedural names
(``icosphere:3``, ``torus``, ...).

``transfer`` and ``displace`` assume source and target in a common pose (the same orientation and
up axis, up to a per-axis scale and offset: :class:`jmeshtex.meshmatch.Config` ``aligned``);
``--no-aligned`` switches to the pose-free features (:meth:`jmeshtex.meshmatch.Config.intrinsic`:
HKS and ``n · up``) for meshes in different poses, and is the default of ``paint`` (``--aligned``
turns the pose prior on there). The flags the paper says must be tuned per example map one to
one onto :class:`jmeshtex.meshmatch.Config` fields: ``--up`` (``up``, with ``--no-aligned``;
``y`` for Y-up models, ``none`` to drop the ``n · up`` feature), ``--side`` (``side``, with
``--no-aligned``: the left/right axis of a symmetric model), ``--color-weight``,
``--shape-weight`` (one number, or a comma list from the finest level to the coarsest),
``--fan-radius``, ``--levels``, ``--steps``, ``--normal-weight``, ``--position-weight``,
``--propagation`` (``sequential``: the paper's breadth-first scan), ``--vote`` (``fan``: the paper's
footprint vote), ``--upsample`` (``offset``: the paper's geodesic-offset start), and ``--max-scale-ratio``
(``none``: transfer between meshes of different sizes on purpose).
"""

from __future__ import annotations

import argparse
import json
import pathlib

from ._common import add_common, add_method, cached, float_in, int_in, load_array, load_mesh_spec
from ._output import claim_args


def register(sub: argparse._SubParsersAction) -> None:
    inner = add_method(
        sub,
        "meshmatch",
        help="PatchMatch texture transfer between meshes (MeshMatch)",
        description="MeshMatch (Chen et al. 2012): non-parametric texture transfer.",
    )
    t = inner.add_parser("transfer", help="transfer a source mesh's texture onto a target mesh")
    t.add_argument(
        "--source",
        required=True,
        metavar="S",
        help="textured source mesh (a file, or a procedural name such as striped-sphere:3)",
    )
    t.add_argument(
        "--source-texture", type=pathlib.Path, metavar="T", help="texture image of the source"
    )
    t.add_argument(
        "--target", required=True, metavar="M", help="target mesh (a file or a procedural name)"
    )
    t.add_argument(
        "--correspondences",
        type=pathlib.Path,
        metavar="FILE",
        help="text file of 'source_vertex target_vertex' pairs, one per line",
    )
    t.add_argument(
        "--voted",
        action="store_true",
        help="output the finest level's vote (smoother) instead of each vertex's matched colour",
    )
    _options(t)
    t.set_defaults(func=cached(_transfer))
    q = inner.add_parser("paint", help="complete a partly painted mesh by example")
    q.add_argument(
        "--mesh",
        required=True,
        metavar="M",
        help="mesh with colours or texture (a file or a procedural name)",
    )
    q.add_argument(
        "--mask",
        type=pathlib.Path,
        required=True,
        metavar="MASK",
        help=".npy bool per vertex, or a text file of painted vertex indices",
    )
    q.add_argument("--texture", type=pathlib.Path, metavar="T", help="texture image of the mesh")
    _options(
        q
    )  # paint defaults to --no-aligned (paint_by_example: the position prior smears the paint)
    q.set_defaults(func=cached(_paint))
    d = inner.add_parser(
        "displace", help="transfer a source mesh's geometric detail onto a target mesh"
    )
    d.add_argument(
        "--source",
        required=True,
        metavar="S",
        help="detailed source mesh (a file or a procedural name)",
    )
    d.add_argument(
        "--target", required=True, metavar="M", help="target mesh (a file or a procedural name)"
    )
    d.add_argument(
        "--smoothing-steps",
        type=int_in(0, 10_000),
        default=10,
        metavar="N",
        help="Taubin pairs that define the source's smooth base (default 10)",
    )
    d.add_argument(
        "--voted",
        action="store_true",
        help="displace by the voted detail (smoother, lower) instead of the matched vertex's",
    )
    _options(d)
    d.set_defaults(func=cached(_displace))


#: the options every meshmatch action takes besides add_common's: one Config field each
_CONFIG_OPTIONS: tuple[tuple[str, dict], ...] = (
    (
        "--steps",
        dict(
            type=int_in(1, 100_000),
            default=None,
            help="PatchMatch iterations per level (Config.steps)",
        ),
    ),
    (
        "--up",
        dict(
            default=None,
            metavar="AXIS",
            help="with --no-aligned, up axis of the n·up shape feature: x, y, z, -x, -y, -z, a vector "
            "'a,b,c', or none (Config.up; default z; use y for Y-up models)",
        ),
    ),
    (
        "--side",
        dict(
            default=None,
            metavar="AXIS",
            help="with --no-aligned, a second axis for an n·side feature, e.g. the left/right axis of a "
            "symmetric model (Config.side; default none)",
        ),
    ),
    (
        "--color-weight",
        dict(
            type=float,
            default=None,
            metavar="W",
            help="colour term weight (Config.color_weight)",
        ),
    ),
    (
        "--shape-weight",
        dict(
            default=None,
            metavar="W[,W...]",
            help="shape term weight, or a comma list from the finest level to the coarsest (Config.shape_weight)",
        ),
    ),
    (
        "--fan-radius",
        dict(
            type=float_in(0.0, 64.0, open_low=True),
            default=None,
            metavar="R",
            help="outer fan radius in mean edge lengths, at most 64 (Config.fan_radius)",
        ),
    ),
    (
        "--levels",
        dict(
            type=int_in(1, 16),
            default=None,
            metavar="N",
            help="hierarchy levels (Config.levels)",
        ),
    ),
    (
        "--aligned",
        dict(
            action=argparse.BooleanOptionalAction,
            default=None,
            help="source and target share a pose and up axis (default): the whole normal and the per-axis "
            "standardised positions join the HKS as shape features (Config.aligned); --no-aligned: "
            "the pose-free features HKS + n·up (Config.intrinsic) for meshes in different poses",
        ),
    ),
    (
        "--normal-weight",
        dict(
            type=float,
            default=None,
            metavar="W",
            help="weight of each n·axis feature relative to the HKS (Config.normal_weight; default 2 "
            "aligned, 1 with --no-aligned)",
        ),
    ),
    (
        "--position-weight",
        dict(
            type=float,
            default=None,
            metavar="W",
            help="weight of the per-axis standardised positions (Config.position_weight; default 8; "
            "not with --no-aligned)",
        ),
    ),
    (
        "--propagation",
        dict(
            choices=("parallel", "sequential"),
            default=None,
            help="PatchMatch propagation: parallel sweeps (default) or the paper's sequential "
            "breadth-first scan (Config.propagation; slower)",
        ),
    ),
    (
        "--vote",
        dict(
            choices=("ring", "fan"),
            default=None,
            help="M-step vote: the one-ring (default) or the paper's fan footprint (Config.vote; slower)",
        ),
    ),
    (
        "--upsample",
        dict(
            choices=("copy", "offset"),
            default=None,
            help="finer level's start: the parent's match (default) or the paper's geodesic offset + "
            "re-vote (Config.upsample)",
        ),
    ),
    (
        "--max-scale-ratio",
        dict(
            default=None,
            metavar="X",
            help="largest source/target size ratio accepted, or none (Config.max_scale_ratio; default 2)",
        ),
    ),
)


def _options(p: argparse.ArgumentParser) -> None:
    """The shared options and the Config flags of :data:`_CONFIG_OPTIONS`."""
    add_common(p)
    for flag, keywords in _CONFIG_OPTIONS:
        p.add_argument(flag, **keywords)


def _parse_up(text: str):
    name = text.strip().lower()
    if name == "none":
        return None
    if "," in name:
        return tuple(float(x) for x in name.split(","))
    return name  # Config validates the axis name


def _parse_weights(text: str):
    """``--shape-weight``: one number, or a tuple from the finest level to the coarsest."""
    weights = tuple(float(x) for x in text.split(","))
    return weights[0] if len(weights) == 1 else weights


def _parse_ratio(text: str):
    """``--max-scale-ratio``: a number, or None for ``none``."""
    text = text.strip().lower()
    return None if text == "none" else float(text)


def _as_parsed(value):
    return value


#: how the text of a Config flag becomes its field's value (the others: as argparse parsed them)
_PARSERS = {
    "up": _parse_up,
    "side": _parse_up,
    "shape_weight": _parse_weights,
    "max_scale_ratio": _parse_ratio,
}


def _config(args, *, aligned: bool = True):
    """:class:`~jmeshtex.meshmatch.Config` from the flags given (unset flags keep the defaults;
    ``aligned``: the default of ``--aligned/--no-aligned``, False for ``paint``)."""
    from .._errors import InputError
    from ..meshmatch import Config

    fields = {} if aligned else {"aligned": False}
    if (args.aligned if args.aligned is not None else aligned) and (
        args.up is not None or args.side is not None
    ):
        raise InputError(
            "--up and --side set the pose-free n·up / n·side features: add --no-aligned (the aligned "
            "default uses the whole normal and the positions, which need no up axis, only that "
            "source and target share a pose)"
        )
    try:
        for flag, _ in _CONFIG_OPTIONS:
            name = flag[2:].replace("-", "_")  # the flag's dest, the Config field it sets
            if getattr(args, name) is not None:
                fields[name] = _PARSERS.get(name, _as_parsed)(getattr(args, name))
    except ValueError as err:
        raise InputError(f"bad number in a meshmatch flag: {err}") from err
    return Config(**fields)


def _key(args):
    import jax

    return jax.random.key(args.seed)


def _load_pairs(path: pathlib.Path):
    import numpy as np

    from .._errors import InputError, MeshIOError

    try:
        pairs = np.loadtxt(path, dtype=np.int64, ndmin=2)
    except (OSError, ValueError) as err:
        raise MeshIOError(f"cannot read correspondences {path}: {err}") from err
    if pairs.shape[1] != 2:
        raise InputError(f"{path}: correspondences need two columns (source vertex, target vertex)")
    return pairs


def _load_mask(path: pathlib.Path, num_vertices: int):
    import numpy as np

    from .._errors import MeshIOError

    try:
        if path.suffix == ".npy":
            mask = load_array(path, "mask")
            if (
                mask.dtype != bool
                and mask.shape == (num_vertices,)
                and set(np.unique(mask).tolist()) <= {0, 1}
            ):
                mask = mask.astype(bool)  # a 0/1 array per vertex
            return mask
        return np.loadtxt(path, dtype=np.int64, ndmin=1)
    except (OSError, ValueError) as err:
        raise MeshIOError(f"cannot read mask {path}: {err}") from err


def _write_outputs(out: pathlib.Path, source, result, title: str) -> dict:
    from .. import render
    from .._mesh import Mesh
    from ..io import atomic_write, save_mesh
    from ..meshmatch import save
    from ..meshmatch.core import nnf_colors

    target_mesh, match = result.mesh, result.match
    _check_finite(target_mesh.vertex_colors, "colours")
    _check_finite(match.voted, "voted colours")
    _check_finite(match.cost, "patch costs")

    out.mkdir(parents=True, exist_ok=True)
    size = (420, 380)
    geometry = Mesh(source.vertices, source.faces)
    src = (
        source
        if source.vertex_colors is None
        else geometry.replace(vertex_colors=source.vertex_colors)
    )
    images = [
        render.render_mesh(src, out / "source.png", size=size, title="source"),
        render.render_mesh(
            Mesh(target_mesh.vertices, target_mesh.faces, vertex_colors=target_mesh.vertex_colors),
            out / "target.png",
            size=size,
            title=title,
        ),
        render.render_mesh(
            Mesh(
                target_mesh.vertices, target_mesh.faces, vertex_colors=nnf_colors(source, match.nnf)
            ),
            out / "nnf.png",
            size=size,
            title="nearest-neighbour field",
        ),
    ]
    render.render_grid(images, out / "meshmatch.png", columns=3)
    # a textured OBJ brings its <stem>.mtl and <stem>.png: a stem apart from the renders' names
    if target_mesh.uv is not None:
        mesh_path, extra = (
            out / "target_textured.obj",
            {"texture": str(out / "target_textured.png")},
        )
    else:
        mesh_path, extra = out / "target.ply", {}
    save_mesh(target_mesh.replace(name="target"), mesh_path)
    save(result, out)
    summary = {
        "mesh": str(mesh_path),
        **extra,
        "renders": [str(out / n) for n in ("source.png", "target.png", "nnf.png", "meshmatch.png")],
        **{k: v for k, v in match.stats.items()},
    }
    atomic_write(out / "summary.json", json.dumps(summary, indent=2, default=float) + "\n")
    return summary


def _check_finite(values, what: str) -> None:
    """Refuse to write a result holding NaN or inf (exit 0 never comes with non-finite output)."""
    import numpy as np

    from .._errors import InputError

    if values is not None and not np.isfinite(np.asarray(values)).all():
        raise InputError(
            f"the result's {what} are not finite (NaN or inf): the meshes are out of the range "
            "MeshMatch computes in (check their scale, e.g. rescale to unit size); nothing was "
            "written"
        )


def _progress(args):
    return not args.quiet


def _transfer(args: argparse.Namespace) -> int:
    from ..geometry import validate_mesh
    from ..meshmatch import transfer

    claim_args(
        args,
        "meshmatch transfer",
        args.source,
        args.source_texture,
        args.target,
        args.correspondences,
    )
    source = load_mesh_spec(args.source, texture=args.source_texture)
    target = load_mesh_spec(args.target)
    for mesh in (source, target):
        validate_mesh(mesh.vertices, mesh.faces)  # a clear typed error before any work
    pairs = _load_pairs(args.correspondences) if args.correspondences else None
    result = transfer(
        source,
        target,
        key=_key(args),
        config=_config(args),
        correspondences=pairs,
        voted=args.voted,
        progress=_progress(args),
    )
    summary = _write_outputs(args.out, source, result, "target (transferred)")
    print(
        f"wrote {summary['mesh']} and renders to {args.out} in {result.match.stats['total_s']:.1f} s"
    )
    return 0


def _paint(args: argparse.Namespace) -> int:
    from ..meshmatch import paint_by_example

    claim_args(args, "meshmatch paint", args.mesh, args.texture, args.mask)
    mesh = load_mesh_spec(args.mesh, texture=args.texture)
    mask = _load_mask(args.mask, mesh.num_vertices)
    result = paint_by_example(
        mesh, mask, key=_key(args), config=_config(args, aligned=False), progress=_progress(args)
    )
    summary = _write_outputs(args.out, mesh, result, "painted by example")
    print(f"wrote {summary['mesh']} and renders to {args.out}")
    return 0


def _displace(args: argparse.Namespace) -> int:
    from .. import render
    from ..geometry import validate_mesh
    from ..io import atomic_write, save_mesh
    from ..meshmatch import save, transfer_displacement
    from ..meshmatch.core import detail_displacement

    claim_args(args, "meshmatch displace", args.source, args.target)
    source = load_mesh_spec(args.source)
    target = load_mesh_spec(args.target)
    for mesh in (source, target):
        validate_mesh(mesh.vertices, mesh.faces)
    result = transfer_displacement(
        source,
        target,
        key=_key(args),
        config=_config(args),
        smoothing_steps=args.smoothing_steps,
        voted=args.voted,
        progress=_progress(args),
    )
    _check_finite(result.mesh.vertices, "displaced vertices")
    _check_finite(result.match.cost, "patch costs")
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    size = (420, 380)
    detail = detail_displacement(source, smoothing_steps=args.smoothing_steps)
    images = [
        render.render_mesh(
            (source.vertices, source.faces),
            out / "source.png",
            size=size,
            title="source (detail)",
            scalars=detail,
        ),
        render.render_mesh(
            (target.vertices, target.faces), out / "target.png", size=size, title="target"
        ),
        render.render_mesh(
            (result.mesh.vertices, result.mesh.faces),
            out / "displaced.png",
            size=size,
            title="target (displaced)",
        ),
    ]
    render.render_grid(images, out / "meshmatch.png", columns=3)
    mesh_path = out / "displaced.ply"
    save_mesh(result.mesh.replace(name="displaced", uv=None, texture=None), mesh_path)
    save(result, out)
    summary = {
        "mesh": str(mesh_path),
        "voted": bool(args.voted),
        "renders": [
            str(out / n) for n in ("source.png", "target.png", "displaced.png", "meshmatch.png")
        ],
        **result.match.stats,
    }
    atomic_write(out / "summary.json", json.dumps(summary, indent=2, default=float) + "\n")
    print(f"wrote {mesh_path} and renders to {out} in {result.match.stats['total_s']:.1f} s")
    return 0

"""``jmeshtex meshmatch transfer|paint``: MeshMatch texture transfer (a thin layer over
:mod:`jmeshtex.meshmatch`).

``transfer`` synthesises the source's colours (vertex colours or UV texture) on the target and
writes the textured target, renders of source, target and the nearest-neighbour field, a JSON
summary and the result itself (:func:`jmeshtex.meshmatch.save`: read it back with
:func:`jmeshtex.meshmatch.load`); ``paint`` completes a partly painted mesh from its painted region
(a mask file: a ``.npy`` bool array per vertex, or a text file of painted vertex indices). Mesh
arguments are files or procedural names (``icosphere:3``, ``torus``, ...).
"""

from __future__ import annotations

import argparse
import json
import pathlib

from ._common import add_common, cached, load_mesh_spec


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("meshmatch", help="PatchMatch texture transfer between meshes (MeshMatch)",
                       description="MeshMatch (Chen et al. 2012): non-parametric texture transfer.")
    inner = p.add_subparsers(dest="meshmatch_command", metavar="ACTION")
    t = inner.add_parser("transfer", help="transfer a source mesh's texture onto a target mesh")
    t.add_argument("--source", required=True, metavar="S",
                   help="textured source mesh (a file, or a procedural name such as striped-sphere:3)")
    t.add_argument("--source-texture", type=pathlib.Path, metavar="T", help="texture image of the source")
    t.add_argument("--target", required=True, metavar="M", help="target mesh (a file or a procedural name)")
    t.add_argument("--correspondences", type=pathlib.Path, metavar="FILE",
                   help="text file of 'source_vertex target_vertex' pairs, one per line")
    _options(t)
    t.set_defaults(func=cached(_transfer))
    q = inner.add_parser("paint", help="complete a partly painted mesh by example")
    q.add_argument("--mesh", required=True, metavar="M",
                   help="mesh with colours or texture (a file or a procedural name)")
    q.add_argument("--mask", type=pathlib.Path, required=True, metavar="MASK",
                   help=".npy bool per vertex, or a text file of painted vertex indices")
    q.add_argument("--texture", type=pathlib.Path, metavar="T", help="texture image of the mesh")
    _options(q)
    q.set_defaults(func=cached(_paint))
    p.set_defaults(func=lambda args: (p.print_help(), 1)[1])


def _options(p: argparse.ArgumentParser) -> None:
    add_common(p)
    p.add_argument("--steps", type=int, default=None, help="PatchMatch iterations per level (Config.steps)")


def _config(args):
    from ..meshmatch import Config

    return Config() if args.steps is None else Config(steps=args.steps)


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
            mask = np.load(path, allow_pickle=False)
            if mask.dtype != bool and mask.shape == (num_vertices,) and set(np.unique(mask).tolist()) <= {0, 1}:
                mask = mask.astype(bool)  # a 0/1 array per vertex
            return mask
        return np.loadtxt(path, dtype=np.int64, ndmin=1)
    except (OSError, ValueError) as err:
        raise MeshIOError(f"cannot read mask {path}: {err}") from err


def _write_outputs(out: pathlib.Path, source, result, title: str) -> dict:
    from .. import render
    from ..io import save_mesh
    from ..meshmatch import nnf_colors, save

    target_mesh, match = result.mesh, result.match

    out.mkdir(parents=True, exist_ok=True)
    size = (420, 380)
    src_kw = ({"vertex_colors": source.vertex_colors} if source.vertex_colors is not None else
              {"uv": source.uv, "texture": source.texture} if source.texture is not None else {})
    images = [
        render.render_mesh(source.vertices, source.faces, out / "source.png", size=size, title="source", **src_kw),
        render.render_mesh(target_mesh.vertices, target_mesh.faces, out / "target.png", size=size, title=title,
                           vertex_colors=target_mesh.vertex_colors),
        render.render_mesh(target_mesh.vertices, target_mesh.faces, out / "nnf.png", size=size,
                           title="nearest-neighbour field", vertex_colors=nnf_colors(source, match.nnf)),
    ]
    render.render_grid(images, out / "meshmatch.png", columns=3)
    mesh_path = out / ("target.obj" if target_mesh.uv is not None else "target.ply")
    save_mesh(target_mesh.replace(name="target"), mesh_path)
    save(result, out)
    summary = {"mesh": str(mesh_path), "renders": [str(out / n) for n in ("source.png", "target.png", "nnf.png", "meshmatch.png")],
               **{k: v for k, v in match.stats.items()}}
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float) + "\n")
    return summary


def _progress(args):
    return not args.quiet


def _transfer(args: argparse.Namespace) -> int:
    from ..geometry import validate_mesh
    from ..meshmatch import transfer

    source = load_mesh_spec(args.source, texture=args.source_texture)
    target = load_mesh_spec(args.target)
    for mesh in (source, target):
        validate_mesh(mesh.vertices, mesh.faces)  # a clear typed error before any work
    pairs = _load_pairs(args.correspondences) if args.correspondences else None
    result = transfer(source, target, key=_key(args), config=_config(args), correspondences=pairs,
                              progress=_progress(args))
    summary = _write_outputs(args.out, source, result, "target (transferred)")
    print(f"wrote {summary['mesh']} and renders to {args.out} in {result.match.stats['total_s']:.1f} s")
    return 0


def _paint(args: argparse.Namespace) -> int:
    from ..meshmatch import paint_by_example

    mesh = load_mesh_spec(args.mesh, texture=args.texture)
    mask = _load_mask(args.mask, mesh.num_vertices)
    result = paint_by_example(mesh, mask, key=_key(args), config=_config(args), progress=_progress(args))
    summary = _write_outputs(args.out, mesh, result, "painted by example")
    print(f"wrote {summary['mesh']} and renders to {args.out}")
    return 0

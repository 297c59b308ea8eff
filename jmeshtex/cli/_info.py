"""``jmeshtex info MESH``: validate a mesh and print its statistics (a thin layer over
:func:`jmeshtex.io.load_mesh` and :func:`jmeshtex.geometry.mesh_statistics`).

Exit status 0 for a valid mesh; for an invalid one the statistics are still printed (and written
with ``--json`` / ``--render``), then the typed validation error is raised, which
:func:`jmeshtex.cli.main` prints as one line with exit status 2. Unreadable files exit 2 the same
way. What loading changed (polygon faces split into triangles) is printed as ``note:`` lines.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import warnings


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "info",
        help="validate a mesh file and print its statistics",
        description=(
            "Load a mesh (.obj, .ply, .off, .glb; UV seams merged by position; polygons split into "
            "triangles, with a note), validate it and print vertices, faces, components, boundary "
            "loops, genus, mean edge length, bounding box, UVs / texture / colours and the verdict. "
            "Exit status 2 if it is invalid."
        ),
    )
    p.add_argument(
        "mesh", metavar="MESH", help="mesh file, or a procedural name (icosphere:3, torus, ...)"
    )
    p.add_argument(
        "--json", type=pathlib.Path, metavar="PATH", help="also write the statistics as JSON"
    )
    p.add_argument(
        "--render", type=pathlib.Path, metavar="PNG", help="also render the mesh to a PNG"
    )
    p.add_argument(
        "--texture",
        type=pathlib.Path,
        metavar="IMAGE",
        help="texture image for meshes whose file names none",
    )
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from .._errors import JmeshtexError, MeshRepairWarning
    from ..geometry import mesh_statistics, validate_mesh
    from ..io import atomic_write
    from ._common import load_mesh_spec
    from ._output import check_output_file

    for flag, written in (("--json", args.json), ("--render", args.render)):
        if written is not None:  # a report never replaces the mesh it describes
            check_output_file(written, (args.mesh, args.texture), flag=flag)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MeshRepairWarning)
        mesh = load_mesh_spec(args.mesh, texture=args.texture)
    notes = []
    for w in caught:
        if issubclass(w.category, MeshRepairWarning):
            notes.append(str(w.message).removeprefix("load_mesh: "))
        else:  # not ours to swallow
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    stats = mesh_statistics(mesh)
    print(f"{args.mesh}")
    for line in str(stats).split("\n")[1:]:  # the first line repeats the name
        if not line.lstrip().startswith("error "):  # main prints the error itself
            print(line)
    for note in notes:
        print(f"  note: {note}")
    if args.json is not None:
        record = {"path": str(args.mesh), **stats.to_dict()}
        atomic_write(args.json, (json.dumps(record, indent=2) + "\n").encode())
        print(f"wrote {args.json}")
    if args.render is not None:
        _render(mesh, args.render)
        print(f"wrote {args.render}")
    if not stats.valid:
        validate_mesh(mesh.vertices, mesh.faces)  # raises the typed error: main prints it, exit 2
        raise JmeshtexError(stats.error)  # unreachable unless validation is not deterministic
    return 0


def _render(mesh, path: pathlib.Path) -> None:
    from .. import render
    from ._common import for_render

    render.render_mesh(
        for_render(mesh), path, title=mesh.name
    )  # in its own texture or vertex colours

"""Study: orientation across UV seams (issue 58), the surface CNN against UV-space 2D synthesis.

``python studies/surfacecnn_orientation.py [--meshes spot,cow,fandisk] [--exemplars stripes]
[--size 128] [--steps 150] [--methods surface,uv2d] [--frame-smoothing 4]
[--work runs/surfacecnn_quality]``: the protocol meshes' xatlas layouts with a stripes exemplar:
orientation across UV seams (:func:`jmeshtex.metrics.seam_orientation`) of the surface CNN and
UV-space 2D synthesis beside the seamless control and the colour seam ratio. Writes
``studies/results/surfacecnn_orientation.{md,json}`` (``_fs<r>`` added to the name for a frame
smoothing other than the library's default; ``--frame-smoothing 0``: the paper's frames);
``--figure MESH`` draws ``surfacecnn_orientation_<mesh>.png`` from the cells already run.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import time

import numpy as np
from _study import ROOT  # noqa: F401  (puts the benchmarks on the path)
from _surfacecnn import exemplar_image
from surfacecnn import (
    PROTOCOL_MESHES,
    cell_columns,
    orientation_control,
    protocol_exemplar,
    protocol_mesh,
    synthesize_cell,
)

from jmeshtex import Mesh
from jmeshtex.metrics import load_vgg16
from jmeshtex.surfacecnn import Config, prepare_surface
from jmeshtex.surfacecnn.core import (
    FRAME_SMOOTHING,
    default_layers,
    required_levels,
)


def _agreement(result, control) -> tuple[float, float]:
    """Mean ``|⟨ν_result, ν_control⟩|`` on the same face (both
    :class:`~jmeshtex.metrics.SeamOrientation`), over the faces of seam edges and over the other
    faces: whether the texture follows the control's (the frames') direction at seams as well as
    inside charts, without the edge comparison's first-order loss where the control itself turns."""
    pairs = result.edge_faces
    at_seam = np.zeros(len(result.normal), bool)
    at_seam[pairs[result.edge_seam].ravel()] = True
    both = (np.abs(result.normal).sum(axis=1) > 0) & (np.abs(control.normal).sum(axis=1) > 0)
    cos = np.abs(np.sum(result.normal * control.normal, axis=1))
    return float(cos[both & at_seam].mean()), float(cos[both & ~at_seam].mean())


def orientation(
    meshes,
    exemplars,
    size: int,
    steps: int,
    work: pathlib.Path,
    out: pathlib.Path | None,
    methods=("surface", "uv2d"),
    frame_smoothing: float = FRAME_SMOOTHING,
) -> None:
    """Orientation across UV seams (:func:`jmeshtex.metrics.seam_orientation`) of the surface CNN
    and of UV-space 2D synthesis on the protocol's xatlas layouts, beside the seamless control
    (:func:`orientation_control`) and the colour seam ratio; textures kept in ``work`` (a rerun
    only re-scores). Writes ``results/surfacecnn_orientation.{md,json}``."""
    import json

    from jmeshtex.geometry import tracer_geometry
    from jmeshtex.metrics import seam_orientation
    from jmeshtex.surfacecnn.core import seam_ratio

    weights = load_vgg16()
    levels = required_levels(weights, default_layers(weights))
    config = Config(size=size, steps=steps)
    rows = []
    for mesh_name in meshes:
        mesh = protocol_mesh(mesh_name, work)
        t0 = time.perf_counter()
        surface = prepare_surface(mesh, size=size, levels=levels, frame_smoothing=frame_smoothing)
        prep = time.perf_counter() - t0
        geometry = tracer_geometry(mesh.vertices, mesh.faces)
        laid = Mesh(mesh.vertices, mesh.faces, uv=surface.atlas.uv)
        control = seam_orientation(laid, orientation_control(mesh, surface, config))
        for ex_name in exemplars:
            exemplar = (
                exemplar_image(ex_name, 128) if ex_name == "stripes" else protocol_exemplar(ex_name)
            )
            row = {
                **cell_columns(mesh_name, ex_name, size, steps, surface),
                "prepare_s": prep,
                "frame_smoothing": frame_smoothing,
                "control": {
                    "seam": control.seam,
                    "seam_smooth": control.seam_at(0.0, 30.0),
                    "seam_crease": control.seam_at(30.0, 180.0),
                    "interior": control.interior,
                },
            }
            for method in methods:
                path = _texture_path(work, mesh_name, ex_name, size, steps, method, frame_smoothing)
                if path.is_file():
                    with np.load(path) as z:
                        texture, colors, loss, cpu = z["texture"], z["colors"], z["loss"], z["cpu"]
                else:
                    c0 = time.process_time()
                    # the 2D image does not depend on the mesh: one optimisation serves every mesh
                    shared = work / "uv2d" / f"{ex_name}_{size}_{steps}_orientation"
                    folder = shared if method == "uv2d" else None
                    r = synthesize_cell(method, mesh, exemplar, config, surface, weights, folder)
                    texture, colors, loss = r.texture, r.colors, r.final_loss
                    cpu = time.process_time() - c0
                    path.parent.mkdir(parents=True, exist_ok=True)
                    np.savez(path, texture=texture, colors=colors, loss=loss, cpu=cpu)
                o = seam_orientation(laid, texture)
                agree_seam, agree_inside = _agreement(o, control)
                seams = seam_ratio(
                    colors, surface.atlas, surface.pyramid.nearest[0], geometry=geometry
                )
                row[method] = {
                    "seam": o.seam,
                    "seam_smooth": o.seam_at(0.0, 30.0),
                    "seam_crease": o.seam_at(30.0, 180.0),
                    "interior": o.interior,
                    "agreement_seam_faces": agree_seam,
                    "agreement_other_faces": agree_inside,
                    "seam_edges": o.seam_edges,
                    "seam_ratio": float(seams["ratio"]),
                    "final_loss": float(loss),
                    "cpu_s": float(cpu),
                }
            print(json.dumps(row), flush=True)
            rows.append(row)
    lines = [
        "# surfacecnn orientation across UV seams\n",
        f"{size}² textures, {steps} steps, every ReLU and pool output of the embedded VGG-16, "
        f"global frames (x) heat-smoothed over {frame_smoothing:g} texels (0: the paper's), "
        "the protocol's xatlas layouts. Alignment: mean |cos| between the "
        "structure-tensor stripe normals of the two faces of an edge (disk of radius 6 texels in "
        "the face's chart), unfolded across the edge; seam edges vs interior edges; random line "
        "fields give 2/π = 0.637. Control: stripes along x (period 8 texels) baked into the same "
        "atlas, the seam alignment the layout allows. Seam ratio: colour difference across seams "
        "over inside charts. Seams < 30° / ≥ 30°: the seam alignment over seam edges whose faces "
        "meet at a dihedral angle below / above 30° (smooth seams / creases and coarse bends). "
        "Agreement: |cos| between the texture's and the control's stripe normals on the same "
        "face (the control's normal is the frames' projected x), over faces of seam edges and "
        "over the other faces.\n",
        "| mesh | exemplar | method | seam alignment | interior | seam / control seam | "
        "control seam / interior | seams < 30° / ≥ 30° dihedral (control) | agreement with the "
        "control: seam faces / other faces | seam ratio | loss | CPU-s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        c = r["control"]
        for method, label in (("surface", "surface CNN"), ("uv2d", "UV-space 2D")):
            if method not in r:
                continue
            m = r[method]
            lines.append(
                f"| {r['mesh']} | {r['exemplar']} | {label} | **{m['seam']:.3f}** | "
                f"{m['interior']:.3f} | {m['seam'] / c['seam']:.2f} | {c['seam']:.3f} / "
                f"{c['interior']:.3f} | {m['seam_smooth']:.3f} / {m['seam_crease']:.3f} "
                f"({c['seam_smooth']:.3f} / {c['seam_crease']:.3f}) | "
                f"{m['agreement_seam_faces']:.3f} / {m['agreement_other_faces']:.3f} | "
                f"{m['seam_ratio']:.3f} | {m['final_loss']:.4g} | "
                + (f"{m['cpu_s']:.0f} |" if np.isfinite(m["cpu_s"]) else "— |")
            )
    lines.append(
        "\nCPU-s: process CPU time of the call (a UV-space 2D run read back from the shared "
        "checkpoint costs only its scoring; — where the texture came from an earlier identical "
        "run whose time was not recorded)."
    )
    lines.append(f"\nLoad average at the end {os.getloadavg()[0]:.1f} (shared 2-core machine).")
    text = "\n".join(lines) + "\n"
    print(text)
    directory = out if out is not None else pathlib.Path(__file__).resolve().parent / "results"
    stem = "surfacecnn_orientation" + (
        "" if frame_smoothing == FRAME_SMOOTHING else f"_fs{frame_smoothing:g}"
    )
    (directory / f"{stem}.md").write_text(text)
    (directory / f"{stem}.json").write_text(json.dumps(rows, indent=1) + "\n")


def _texture_path(work, mesh_name, ex_name, size, steps, method, frame_smoothing) -> pathlib.Path:
    """Where a cell's texture is kept: the surface CNN's per frame smoothing, UV-space 2D's once."""
    tail = f"_fs{frame_smoothing:g}" if method == "surface" else ""
    return work / "orientation" / f"{mesh_name}_{ex_name}_{size}_{steps}_{method}{tail}.npz"


def orientation_figure(
    mesh_name: str, size: int, steps: int, work: pathlib.Path, out: pathlib.Path | None
) -> None:
    """Stripes on a protocol mesh from the orientation textures in ``work``: the surface CNN
    and UV-space 2D synthesis, a whole view and a close view across a UV seam (with the charts
    seen from the same camera), and both UV images. Writes
    ``results/surfacecnn_orientation_<mesh>.png``."""
    from jmeshtex import render
    from jmeshtex.metrics import seam_orientation, uv_charts

    mesh = protocol_mesh(mesh_name, work)
    tex = {}
    for method in ("surface", "uv2d"):
        path = _texture_path(work, mesh_name, "stripes", size, steps, method, FRAME_SMOOTHING)
        with np.load(path) as z:
            tex[method] = np.asarray(z["texture"], np.float64)
    up = PROTOCOL_MESHES[mesh_name][1]
    px = (384, 384)
    whole = render.orbit_cameras(mesh, azimuths=[60.0], elevations=(15.0,), up=up, size=px)[0]
    # the close view: the front-facing seam edge whose two faces have the most coherent stripes
    o = seam_orientation(mesh, tex["surface"])
    faces = np.asarray(mesh.faces)
    V = np.asarray(mesh.vertices, np.float64)
    centre = V[faces].mean(axis=1)
    n = np.cross(V[faces[:, 1]] - V[faces[:, 0]], V[faces[:, 2]] - V[faces[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    eye = np.asarray(whole.eye, np.float64)
    view = eye - centre
    facing = np.sum(n * view, axis=1) / np.linalg.norm(view, axis=1)
    pair = o.edge_faces
    score = np.where(
        o.edge_seam & np.isfinite(o.edge_alignment) & (facing[pair].min(axis=1) > 0.85),
        o.coherence[pair].min(axis=1),
        -1.0,
    )
    best = pair[int(np.argmax(score))]
    target = centre[best].mean(axis=0)
    normal = n[best].sum(axis=0)
    normal /= np.linalg.norm(normal)
    radius = float(np.linalg.norm(V - V.mean(axis=0), axis=1).max())
    close = render.look_at(
        target + 0.6 * radius * normal,
        target,
        up=up,
        half_height=0.3 * radius,
        size=px,
    )
    chart = uv_charts(faces, mesh.uv)
    palette = np.random.default_rng(1).uniform(0.25, 1.0, size=(chart.max() + 1, 3))
    big = lambda image: np.repeat(np.repeat(image, 3, axis=0), 3, axis=1)  # noqa: E731 (readable)
    panels = [("exemplar (stripes, period 8 px)", big(exemplar_image("stripes", 128)))]
    for method, label in (("surface", "surface CNN"), ("uv2d", "UV-space 2D")):
        textured = Mesh(mesh.vertices, mesh.faces, uv=mesh.uv, texture=tex[method])
        views = render.render_views(textured, [whole, close])
        panels += [(label, views[0]), (f"{label}, close to a seam", views[1])]
    panels.append(
        ("charts, same close view", render.render(mesh, close, face_colors=palette[chart]))
    )
    panels += [
        ("surface CNN, UV image", big(tex["surface"])),
        ("UV-space 2D, UV image", big(tex["uv2d"])),
    ]
    directory = out if out is not None else pathlib.Path(__file__).resolve().parent / "results"
    render.figure(
        panels,
        columns=4,
        title=f"{mesh_name}, stripes, {size}x{size} texels, {steps} steps",
        path=directory / f"surfacecnn_orientation_{mesh_name}.png",
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--meshes", default=",".join(PROTOCOL_MESHES))
    ap.add_argument("--exemplars", default="stripes")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument(
        "--work",
        type=pathlib.Path,
        default=pathlib.Path(__file__).resolve().parents[1] / "runs" / "surfacecnn_quality",
    )
    ap.add_argument("--out", type=pathlib.Path, default=None)
    ap.add_argument("--methods", default="surface,uv2d", help="surface, uv2d or both")
    ap.add_argument(
        "--frame-smoothing",
        type=float,
        default=FRAME_SMOOTHING,
        help="texels over which the frames turn at creases (0: the paper's frames)",
    )
    ap.add_argument("--figure", default=None, metavar="MESH", help="only the figure of one mesh")
    a = ap.parse_args(argv)
    if a.figure:
        orientation_figure(a.figure, a.size, a.steps, a.work, a.out)
    else:
        orientation(
            a.meshes.split(","),
            a.exemplars.split(","),
            a.size,
            a.steps,
            a.work,
            a.out,
            tuple(a.methods.split(",")),
            a.frame_smoothing,
        )


if __name__ == "__main__":
    main()

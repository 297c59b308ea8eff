"""Study: orientation across UV seams (issue 58), the surface CNN against UV-space 2D synthesis.

``python studies/surfacecnn_orientation.py [--meshes spot,cow,fandisk] [--exemplars stripes]
[--size 128] [--steps 150] [--methods surface,uv2d] [--frame-smoothing 4]
[--work runs/surfacecnn_quality]``: the protocol meshes' xatlas layouts with a stripes exemplar:
orientation across UV seams (:func:`jmeshtex.metrics.seam_orientation`) of the surface CNN and
UV-space 2D synthesis beside the seamless control and the colour seam ratio. Writes
``studies/results/surfacecnn_orientation.{md,json}`` (``_fs<r>`` added to the name for a frame
smoothing other than the library's default; ``--frame-smoothing 0``: the paper's frames);
``--figure MESH`` draws ``surfacecnn_orientation_<mesh>.png`` (or ``--figure-path``) from the
cells already run, with the seamless control beside them; ``--seam-sources MESH`` reads where a
surface-CNN cell's colour seam ratio comes from (``surfacecnn_seam_sources_<mesh>.{md,json}``).
The seams figure of ``docs/figures/surfacecnn_seams.png``: ``--meshes spot --size 512 --steps
150 --out runs/fig512``, then ``--figure spot --size 512 --steps 150 --figure-path
docs/figures/surfacecnn_seams.png``.
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


def _results_dir(out: pathlib.Path | None) -> pathlib.Path:
    """Where the results go: ``out`` (made if missing) or ``studies/results/``."""
    directory = out if out is not None else pathlib.Path(__file__).resolve().parent / "results"
    directory.mkdir(parents=True, exist_ok=True)
    return directory


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
    config = Config(size=size, steps=steps, frame_smoothing=frame_smoothing)
    rows = []
    for mesh_name in meshes:
        mesh = protocol_mesh(mesh_name, work)
        t0 = time.perf_counter()
        kept = [
            _texture_path(work, mesh_name, ex, size, steps, "surface", frame_smoothing).is_file()
            for ex in exemplars
        ]
        needs_pyramid = "surface" in methods and not all(kept)  # else only the atlas is read
        surface = prepare_surface(
            mesh,
            size=size,
            levels=levels if needs_pyramid else 0,
            frame_smoothing=config.frame_smoothing,
        )
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
    directory = _results_dir(out)
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
    mesh_name: str,
    size: int,
    steps: int,
    work: pathlib.Path,
    out: pathlib.Path | None,
    path: pathlib.Path | None = None,
    close: float = 0.3,
    uv2d_steps: int | None = None,
) -> pathlib.Path:
    """Stripes on a protocol mesh from the orientation textures in ``work``: the surface CNN, the
    seamless control (3D stripes baked into the same atlas) and UV-space 2D synthesis, a whole view
    and a close view across a UV seam (with the charts seen from the same camera), both UV images
    and a 4× crop of each. The close view looks at the front-facing seam edge whose two faces
    read the control's stripes most coherently (a choice by the layout alone, not by any
    synthesis), from ``0.6`` mesh radii away, ``close`` radii half-height. Writes ``path``
    (default ``results/surfacecnn_orientation_<mesh>.png``). ``uv2d_steps``: the UV-space 2D
    run's step count where it differs from the surface CNN's (named in its panels)."""
    from jmeshtex import render
    from jmeshtex.metrics import seam_orientation, uv_charts

    mesh = protocol_mesh(mesh_name, work)
    tex = {}
    runs = {"surface": steps, "uv2d": steps if uv2d_steps is None else uv2d_steps}
    for method, n in runs.items():
        texture = _texture_path(work, mesh_name, "stripes", size, n, method, FRAME_SMOOTHING)
        with np.load(texture) as z:
            tex[method] = np.asarray(z["texture"], np.float64)
    surface = prepare_surface(mesh, size=size, levels=0)  # the atlas (texel size) of the layout
    tex["control"] = orientation_control(mesh, surface, Config(size=size))
    up = PROTOCOL_MESHES[mesh_name][1]
    px = (max(384, min(size, 512)),) * 2
    whole = render.orbit_cameras(mesh, azimuths=[60.0], elevations=(15.0,), up=up, size=px)[0]
    o = seam_orientation(mesh, tex["control"])
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
    near = render.look_at(
        target + 0.6 * radius * normal, target, up=up, half_height=close * radius, size=px
    )
    chart = uv_charts(faces, mesh.uv)
    palette = np.random.default_rng(1).uniform(0.25, 1.0, size=(chart.max() + 1, 3))

    def fit(image, k):  # nearest-neighbour enlargement to about the panel size
        return np.repeat(np.repeat(image, k, axis=0), k, axis=1)

    exemplar = exemplar_image("stripes", 128)
    panels = [("exemplar (stripes, period 8 px)", fit(exemplar, max(1, px[0] // 128)))]
    views = {}
    for method in ("surface", "control", "uv2d"):
        textured = Mesh(mesh.vertices, mesh.faces, uv=mesh.uv, texture=tex[method])
        views[method] = render.render_views(textured, [whole, near])
    labels = {
        "surface": "surface CNN",
        "control": "seamless control (3D stripes)",
        "uv2d": "UV-space 2D" + ("" if runs["uv2d"] == steps else f" ({runs['uv2d']} steps)"),
    }
    panels += [
        (labels["surface"], views["surface"][0]),
        (f"{labels['surface']}, close to a seam", views["surface"][1]),
        ("charts, same close view", render.render(mesh, near, face_colors=palette[chart])),
        (labels["control"], views["control"][0]),
        ("control, close to the seam", views["control"][1]),
        (labels["uv2d"], views["uv2d"][0]),
        (f"{labels['uv2d']}, close to the seam", views["uv2d"][1]),
    ]
    k = max(1, px[0] // size)
    crop = slice(size // 2 - size // 8, size // 2 + size // 8)
    for method in ("surface", "uv2d"):
        panels += [
            (f"{labels[method]}, UV image", fit(tex[method], k)),
            (f"{labels[method]}, UV image, centre x4", fit(tex[method][crop, crop], 4 * k)),
        ]
    directory = _results_dir(out)
    path = path if path is not None else directory / f"surfacecnn_orientation_{mesh_name}.png"
    render.figure(
        panels,
        columns=4,
        title=f"{mesh_name}, stripes, {size}x{size} texels, {steps} steps, "
        f"frames smoothed over {FRAME_SMOOTHING:g} texels",
        path=path,
    )
    return path


def seam_sources(
    mesh_name: str, size: int, steps: int, work: pathlib.Path, out: pathlib.Path | None
) -> dict:
    """Where a surface-CNN cell's colour seam ratio comes from (``work``'s stripes texture): the
    ratio of the seamless control on the same atlas (what the layout alone gives: seam pairs
    need not be image neighbours, so they may lie farther apart than interior pairs), the mean
    surface distance of seam and interior pairs (texels), the ratio over seam pairs at smooth
    seams and at creases (faces' normals < / ≥ 30° apart), and how concentrated the excess over
    the interior mean is (share from the worst 5 % of seam pairs, from the worst 10 faces).
    Writes ``results/surfacecnn_seam_sources_<mesh>.{md,json}``."""
    import json

    from jmeshtex.geometry import tracer_geometry
    from jmeshtex.surfacecnn.core import seam_pairs

    mesh = protocol_mesh(mesh_name, work)
    path = _texture_path(work, mesh_name, "stripes", size, steps, "surface", FRAME_SMOOTHING)
    with np.load(path) as z:
        colors = np.asarray(z["colors"], np.float64)
    surface = prepare_surface(mesh, size=size, levels=0)
    atlas = surface.atlas
    if atlas.num_texels != len(colors):
        raise SystemExit(
            f"{path}: {len(colors)} texels, the layout in {work} has {atlas.num_texels}"
        )
    geometry = tracer_geometry(mesh.vertices, mesh.faces)
    seam, inner = seam_pairs(atlas, surface.pyramid.nearest[0], geometry)
    control = orientation_control(mesh, surface, Config(size=size)).reshape(size * size, 3)
    control = control[atlas.texel]
    V, F = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces)
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)

    def diffs(c, pairs):
        return np.linalg.norm(c[pairs[:, 0]] - c[pairs[:, 1]], axis=1)

    def dist(pairs):
        d = np.linalg.norm(atlas.point[pairs[:, 0]] - atlas.point[pairs[:, 1]], axis=1)
        return float(d.mean() / atlas.texel_size)

    d_seam, d_inner = diffs(colors, seam), diffs(colors, inner).mean()
    c_seam, c_inner = diffs(control, seam), diffs(control, inner).mean()
    cos = np.sum(n[atlas.face[seam[:, 0]]] * n[atlas.face[seam[:, 1]]], axis=1)
    crease = cos < np.cos(np.radians(30.0))
    excess = d_seam - d_inner
    worst = np.sort(excess)[::-1][: max(1, len(excess) // 20)]
    per_face = np.bincount(atlas.face[seam[:, 0]], weights=excess, minlength=len(F))
    row = {
        "mesh": mesh_name,
        "size": size,
        "steps": steps,
        "seam_pairs": len(seam),
        "interior_pairs": len(inner),
        "ratio": float(d_seam.mean() / d_inner),
        "control_ratio": float(c_seam.mean() / c_inner),
        "distance_seam": dist(seam),
        "distance_interior": dist(inner),
        "ratio_smooth": float(d_seam[~crease].mean() / d_inner),
        "ratio_crease": float(d_seam[crease].mean() / d_inner),
        "control_ratio_smooth": float(c_seam[~crease].mean() / c_inner),
        "control_ratio_crease": float(c_seam[crease].mean() / c_inner),
        "crease_share": float(crease.mean()),
        "worst_5pct_share": float(worst.sum() / excess.sum()),
        "worst_10_faces_share": float(np.sort(per_face)[::-1][:10].sum() / excess.sum()),
        "faces_with_seam_pairs": int((np.bincount(atlas.face[seam[:, 0]]) > 0).sum()),
    }
    text = "\n".join(
        [
            f"# where the colour seam ratio comes from: {mesh_name}, stripes\n",
            f"{size}² texels, {steps} steps, surface CNN with the default frames, the protocol's "
            "xatlas layout; control: 3D stripes along x (period 8 texels) baked into the same "
            "atlas (seamless by construction). Ratio: mean colour difference of seam pairs over "
            "interior pairs (`surfacecnn.core.seam_ratio`); creases: seam pairs whose faces' "
            "normals are ≥ 30° apart. Excess: a seam pair's difference minus the interior mean.\n",
            "| quantity | value |",
            "|---|---|",
            *(
                f"| {k} | {v:.3f} |" if isinstance(v, float) else f"| {k} | {v} |"
                for k, v in row.items()
            ),
        ]
    )
    print(text)
    directory = _results_dir(out)
    (directory / f"surfacecnn_seam_sources_{mesh_name}.md").write_text(text + "\n")
    (directory / f"surfacecnn_seam_sources_{mesh_name}.json").write_text(
        json.dumps(row, indent=1) + "\n"
    )
    return row


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
    ap.add_argument(
        "--seam-sources", default=None, metavar="MESH", help="where a cell's seam ratio comes from"
    )
    ap.add_argument("--uv2d-steps", type=int, default=None, help="the figure's UV-space 2D run")
    ap.add_argument("--figure-path", type=pathlib.Path, default=None, help="where it goes")
    ap.add_argument(
        "--close", type=float, default=0.3, help="close view's half-height (mesh radii)"
    )
    a = ap.parse_args(argv)
    if a.seam_sources:
        seam_sources(a.seam_sources, a.size, a.steps, a.work, a.out)
    elif a.figure:
        orientation_figure(
            a.figure, a.size, a.steps, a.work, a.out, a.figure_path, a.close, a.uv2d_steps
        )
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

"""Study: surface-CNN frames (global, smooth, UV) against UV-space 2D synthesis.

``python studies/surfacecnn_frames.py [--size 96] [--steps 150] [--exemplar brick|stripes]``: on
Spot (its own UVs) and an xatlas-unwrapped icosphere, the surface CNN with global, smooth and UV
frames against UV-space 2D synthesis (render SIFID-VGG / Gram, seam ratio, frame turn across
seams). Writes ``studies/results/surfacecnn_frames[_stripes].{md,json}``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import time

import jax
import numpy as np
from _study import ROOT  # noqa: F401  (puts the benchmarks on the path)
from _surfacecnn import PNG_DIR, exemplar_image
from surfacecnn import (
    SHARED,
    patch_scores,
)

from jmeshtex import Mesh
from jmeshtex.metrics import load_vgg16
from jmeshtex.surfacecnn import Config, prepare_surface, unwrap_uv
from jmeshtex.surfacecnn.core import (
    required_levels,
)

QUALITY_LAYERS = ("relu1_1", "relu1_2", "pool1", "relu2_1", "relu2_2", "pool2", "relu3_1")


def _quality_meshes():
    from jmeshtex import Mesh
    from jmeshtex.data import icosphere

    out = []
    spot = (
        pathlib.Path(os.environ.get("JMESHTEX_SHARED_DATA", SHARED))
        / "spot"
        / "spot_triangulated.obj"
    )
    if spot.is_file():
        from jmeshtex.io import load_mesh

        out.append(("spot (own UVs)", load_mesh(spot), "y"))
    v, f = icosphere(3)
    out.append(("icosphere3 + xatlas", Mesh(v, f, uv=unwrap_uv(v, f)), "z"))
    return out


def frames(size: int, steps: int, out: pathlib.Path | None, kind: str = "brick") -> None:
    import json

    from jmeshtex import render
    from jmeshtex.geometry import tracer_geometry
    from jmeshtex.metrics import Protocol, baseline_table
    from jmeshtex.surfacecnn import synthesize, synthesize_uv
    from jmeshtex.surfacecnn.core import frame_seam_turn, seam_ratio

    PNG_DIR.mkdir(parents=True, exist_ok=True)
    exemplar = exemplar_image(kind, 96 if kind == "brick" else 32)
    config = Config(size=size, steps=steps, layers=QUALITY_LAYERS)
    levels = required_levels(load_vgg16(), QUALITY_LAYERS)
    rows, lines = [], []
    for name, mesh, up in _quality_meshes():
        g = tracer_geometry(mesh.vertices, mesh.faces)
        turns = {
            fr: frame_seam_turn(mesh, frames=fr, geometry=g) for fr in ("uv", "global", "smooth")
        }
        protocol = Protocol(azimuths=4, elevations=(20.0,), size=192, up=up)
        panels = [("exemplar", exemplar)]
        for method, frames in (
            ("surface CNN, global frames", "global"),
            ("surface CNN, smooth frames", "smooth"),
            ("surface CNN, uv frames", "uv"),
            ("UV-space 2D synthesis", "global"),
        ):
            t0 = time.perf_counter()
            surface = prepare_surface(
                mesh, size=size, levels=levels, boundary=config.boundary, frames=frames
            )
            if method.startswith("UV"):
                r = synthesize_uv(
                    mesh, exemplar, config, key=jax.random.key(0), surface=surface, progress=False
                )
            else:
                r = synthesize(
                    mesh, exemplar, config, key=jax.random.key(0), surface=surface, progress=False
                )
            seconds = time.perf_counter() - t0
            seams = seam_ratio(r.colors, surface.atlas, surface.pyramid.nearest[0], geometry=g)
            table = baseline_table(
                Mesh(mesh.vertices, mesh.faces, uv=surface.atlas.uv, texture=r.texture),
                key=jax.random.key(1),
                exemplar=exemplar,
                protocol=protocol,
                metrics=("sifid", "gram"),
            )
            patches = patch_scores(
                Mesh(mesh.vertices, mesh.faces, uv=surface.atlas.uv),
                r.texture,
                exemplar,
                surface,
                None,
            )
            row = {
                "mesh": name,
                "method": method,
                "size": size,
                "steps": steps,
                "seconds": seconds,
                "seam_ratio": seams["ratio"],
                "seam_pairs": seams["seam_pairs"],
                "patches": patches,
                **{
                    f"{k}_{m}": v
                    for k, vals in table.rows.items()
                    for m, v in vals.items()
                    if m != "views"
                },
            }
            rows.append(row)
            print(json.dumps(row))
            views = render.render_views(
                Mesh(mesh.vertices, mesh.faces, uv=surface.atlas.uv, texture=r.texture),
                protocol.cameras(mesh),
            )
            tag = kind + "_" + name.split()[0] + "_" + method.replace(" ", "_").replace(",", "")
            render.figure(
                [(f"view {i}", im) for i, im in enumerate(views)] + [("texture", r.texture)],
                columns=5,
                title=f"{name}: {method}",
                path=PNG_DIR / f"{tag}.png",
            )
            panels.append((method, views[0]))
        render.figure(
            panels,
            columns=len(panels),
            title=name,
            path=PNG_DIR / f"{kind}_{name.split()[0]}_compare.png",
        )
        for fr, t in turns.items():
            rows.append(
                {
                    "mesh": name,
                    "frames": fr,
                    "seam_edges": len(t),
                    "turn_max_deg": float(np.degrees(t.max())),
                    "turn_median_deg": float(np.degrees(np.median(t))),
                }
            )
            print(json.dumps(rows[-1]))
    lines.append(
        "| mesh | method | seam ratio | sifid | gram | flat sifid | flat gram | permuted sifid | "
        "permuted gram | s |"
    )
    lines.append("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        if "method" in r:
            lines.append(
                f"| {r['mesh']} | {r['method']} | {r['seam_ratio']:.3f} | {r['result_sifid']:.4g} | "
                f"{r['result_gram']:.4g} | {r['flat_sifid']:.4g} | {r['flat_gram']:.4g} | "
                f"{r['permuted_sifid']:.4g} | {r['permuted_gram']:.4g} | {r['seconds']:.0f} |"
            )
    lines += [
        "",
        "Surface patches (32 geodesic patches of 32² at the texel scale, global frames, against "
        "exemplar crops; Gram on VGG-16 relu1_1…relu3_3, spectrum: log radial power L1):",
        "",
        "| mesh | method | patch Gram | spectrum | flat | permuted | initial | UV-tiled | floor | "
        "charts / patch |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        if "patches" in r:
            p = r["patches"]
            cells = " | ".join(
                f"{p[k]['gram']:.3g} / {p[k]['spectrum']:.3f}"
                for k in ("flat", "permuted", "initial", "uv_tiled", "floor")
            )
            lines.append(
                f"| {r['mesh']} | {r['method']} | {p['texture']['gram']:.3g} | "
                f"{p['texture']['spectrum']:.3f} | {cells} | {p['texture']['charts']:.2f} |"
            )
    lines += [
        "",
        "| mesh | frames | seam edges | max turn (°) | median turn (°) |",
        "| --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        if "frames" in r:
            lines.append(
                f"| {r['mesh']} | {r['frames']} | {r['seam_edges']} | {r['turn_max_deg']:.3g} | "
                f"{r['turn_median_deg']:.3g} |"
            )
    note = (
        f"\nsize {size}², {steps} steps, Gram layers {', '.join(QUALITY_LAYERS)} (VGG-16, embedded), exemplar "
        f"{kind} ({'skimage brick 96²' if kind == 'brick' else 'sine stripes 32², period 8'}), protocol: 4 views at elevation 20°, 192² (sifid/gram: VGG-16 features, not "
        "Inception). Seam ratio: mean colour difference across UV chart seams / inside charts (1 = seamless)."
    )
    text = "\n".join(lines) + "\n" + note + "\n"
    print(text)
    directory = out if out is not None else pathlib.Path(__file__).resolve().parent / "results"
    suffix = "" if kind == "brick" else f"_{kind}"
    (directory / f"surfacecnn_frames{suffix}.md").write_text(text)
    (directory / f"surfacecnn_frames{suffix}.json").write_text(json.dumps(rows, indent=1) + "\n")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--exemplar", choices=("brick", "stripes"), default="brick")
    ap.add_argument("--out", type=pathlib.Path, default=None)
    a = ap.parse_args(argv)
    frames(a.size, a.steps, a.out, a.exemplar)


if __name__ == "__main__":
    main()

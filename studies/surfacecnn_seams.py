"""Study: the surface CNN's coupling of chart-border texels across UV seams.

``python studies/surfacecnn_seams.py [--size 128] [--steps 150]``: Spot with its own UVs and with
xatlas, a grey brick exemplar at native resolution: synthesis without and with the coupling of
chart-border texels (unread share, seam chroma, render specks) and the surface-patch measure with
its baselines (:func:`jmeshtex.metrics.surface_patch_table`). Writes
``studies/results/surfacecnn_seams.{md,json}``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import time

import jax
import numpy as np
from _study import ROOT  # noqa: F401  (puts the benchmarks on the path)
from _surfacecnn import PNG_DIR
from surfacecnn import (
    benchmark_mesh,
    patch_scores,
    specks,
)

from jmeshtex.metrics import load_vgg16
from jmeshtex.surfacecnn import Config, prepare_surface, unwrap_uv
from jmeshtex.surfacecnn.core import (
    default_layers,
    required_levels,
    texel_density_spread,
)


def seams(size: int, steps: int, out: pathlib.Path | None) -> None:
    """Spot (own UVs and xatlas), a grey brick exemplar at native resolution (1 pixel = 1 texel):
    synthesis without and with texel coupling; unread share, seam chroma, specks, surface patches."""
    import json

    import skimage.data

    from jmeshtex import render
    from jmeshtex.geometry import tracer_geometry
    from jmeshtex.surfacecnn import synthesize
    from jmeshtex.surfacecnn.core import read_counts, seam_chroma, unread_share

    name, base = benchmark_mesh()
    grey = skimage.data.brick()[:256, :256].astype(np.float64) / 255.0
    exemplar = np.repeat(grey[..., None], 3, axis=2)
    weights = load_vgg16()
    levels = required_levels(weights, default_layers(weights))
    PNG_DIR.mkdir(parents=True, exist_ok=True)
    rows = []
    for unwrap in ("own", "xatlas"):
        mesh = base if unwrap == "own" else base.replace(uv=unwrap_uv(base.vertices, base.faces))
        g = tracer_geometry(mesh.vertices, mesh.faces)
        spread = texel_density_spread(mesh.vertices, mesh.faces, mesh.uv)["ratio_p95_p5"]
        cams = render.orbit_cameras(mesh, azimuths=4, elevations=(20.0,), size=(256, 256), up="y")
        unread_before = None
        panels = [("exemplar", exemplar)]
        for couple in (False, True):
            surface = prepare_surface(mesh, size=size, levels=levels, couple=couple)
            taps = surface.pyramid
            counts = read_counts(taps.nearest[0])
            if unread_before is None:
                unread_before = counts == 0
            shares = unread_share(
                type(
                    "T",
                    (),
                    {"nearest": taps.nearest[0], "bilinear": taps.bilinear, "tie": taps.tie},
                )
            )
            t0, c0 = time.perf_counter(), time.process_time()
            r = synthesize(
                mesh,
                exemplar,
                Config(size=size, steps=steps),
                key=jax.random.key(0),
                surface=surface,
                progress=False,
            )
            seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
            colors = np.asarray(r.colors, np.float64)
            chroma = colors.max(1) - colors.min(1)
            sc = seam_chroma(surface.atlas, colors, g)
            textured = r.mesh
            views = render.render_views(textured, cams, shading="unlit")
            specks = [specks(v) for v in views]
            table = patch_scores(textured, r.texture, exemplar, surface, weights)
            row = {
                "mesh": f"{name} ({unwrap} UVs)",
                "density_p95_p5": spread,
                "couple": couple,
                "size": size,
                "steps": steps,
                "seconds": seconds,
                "cpu_s": cpu,
                "final_loss": r.final_loss,
                "unread_nearest": shares["nearest"],
                "unread_either": shares["either"],
                "tied_share": 0.0
                if taps.tie is None
                else float(
                    1 - np.mean(taps.tie[1][:, 0] * (taps.tie[0][:, 0] == np.arange(len(chroma))))
                ),
                "chroma_border": sc["border"],
                "chroma_interior": sc["interior"],
                "chroma_ratio": sc["ratio"],
                "border_share": sc["border_share"],
                "chroma_unread_before": float(chroma[unread_before].mean()),
                "speck_abs": float(np.mean([s["abs"] for s in specks])),
                "speck_local": float(np.mean([s["local"] for s in specks])),
                "patches": table,
            }
            rows.append(row)
            print(json.dumps(row), flush=True)
            tag = f"seams_{unwrap}_{'coupled' if couple else 'loose'}"
            render.figure(
                [(f"view {i}", im) for i, im in enumerate(views)] + [("texture", r.texture)],
                columns=5,
                title=f"{row['mesh']}, coupling {'on' if couple else 'off'}",
                path=PNG_DIR / f"{tag}.png",
            )
            panels.append((f"coupling {'on' if couple else 'off'}", views[1]))
        render.figure(panels, columns=3, title=name, path=PNG_DIR / f"seams_{unwrap}_compare.png")
    lines = [
        "| mesh | coupling | unread (nearest) | tied | chroma border | chroma interior | ratio | "
        "chroma of texels unread before | speck px (chroma > 0.3) | speck px (local) | loss | s | CPU-s |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        lines.append(
            f"| {r['mesh']} | {'on' if r['couple'] else 'off'} | {r['unread_nearest']:.4f} | "
            f"{r['tied_share']:.3f} | {r['chroma_border']:.3f} | {r['chroma_interior']:.3f} | "
            f"{r['chroma_ratio']:.3f} | {r['chroma_unread_before']:.3f} | {r['speck_abs']:.4f} | "
            f"{r['speck_local']:.4f} | {r['final_loss']:.4g} | {r['seconds']:.0f} | {r['cpu_s']:.0f} |"
        )
    lines += [
        "",
        "Surface patches (32 patches of 32², geodesic, texel scale, global frames; Gram: VGG-16 "
        "relu1_1…relu3_3, the network the synthesis optimised; spectrum: log10 radial power L1, "
        "network-free):",
        "",
        "| mesh | coupling | row | patch Gram | spectrum L1 | charts / patch | off-chart px |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        for k, v in r["patches"].items():
            lines.append(
                f"| {r['mesh']} | {'on' if r['couple'] else 'off'} | {k} | {v['gram']:.4g} | "
                f"{v['spectrum']:.3f} | {v.get('charts', float('nan')):.2f} | "
                f"{v.get('off_chart', float('nan')):.3f} |"
            )
    note = (
        f"\n{name}, {size}² texels, {steps} steps, every ReLU and pool output of the embedded "
        "VGG-16, grey skimage brick 256² at native resolution (1 exemplar pixel = 1 texel). Chroma: "
        "max − min of RGB per texel (all colour is error on a grey exemplar); border: texels with an "
        "image 8-neighbour invalid or in another chart. Specks: 4 unlit 256² views at elevation 20°. "
        f"Texel-density spread p95/p5 per layout in the rows' json. Load average at the end "
        f"{os.getloadavg()[0]:.1f} (shared 2-core machine, nice 10)."
    )
    text = "\n".join(lines) + "\n" + note + "\n"
    print(text)
    directory = out if out is not None else pathlib.Path(__file__).resolve().parent / "results"
    (directory / "surfacecnn_seams.md").write_text("# surfacecnn seams\n\n" + text)
    (directory / "surfacecnn_seams.json").write_text(json.dumps(rows, indent=1) + "\n")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--out", type=pathlib.Path, default=None)
    a = ap.parse_args(argv)
    seams(a.size, a.steps, a.out)


if __name__ == "__main__":
    main()

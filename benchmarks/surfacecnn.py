"""Benchmark of the surface CNN: host precomputation and optimisation step time.

Mesh: Spot (../shared/data/spot, 5856 faces, its own UV atlas); without the shared data a
procedural icosphere(4) unwrapped with xatlas stands in (reported in the row names). ``--mesh cow``
or ``fandisk``: a held-in real mesh in the protocol's xatlas layout (``--unwrap`` applies to Spot).
Reports

- precomputation (atlas, level-0 exp-map taps, pooling pyramid with 5 levels) at 512² and 1024²,
  next to the target (≤ 15 s at 1024² on 2 cores; the paper: 1:44 for a 5K-triangle bunny at 1024²
  on a GPU workstation);
- one optimisation step (forward + backward of the full VGG-16 on the mesh, every ReLU and pool
  output in the Gram loss, Adam update) at 256² and 512², compile time apart, with the convolution
  FLOPs against the matmul ceiling of the same run;
- peak resident memory of the process and the bytes of the network arrays.

The machine is shared; record ``uptime`` with the numbers and re-run on a quiet machine. The
precomputation is single-threaded NumPy, so its process CPU time (``cpu_s``) approximates the wall
time of a quiet machine.

Quality section (``--quality``, issue 33's protocol): Spot, the cow and the fandisk (xatlas
layouts) × scikit-image brick, grass and immunohistochemistry at native 512², 512² textures, 500
steps, every VGG-16 ReLU and pool output; per cell the surface CNN and UV-space 2D synthesis with
the surface-patch measure and its baselines, the seam ratio and render specks. Cells resume from
``runs/surfacecnn_quality/``. Writes ``results/surfacecnn.quality.{md,json}``.

Frames section (``--frames``): on Spot (its own UVs) and an xatlas-unwrapped icosphere at 96², the
surface CNN with global, smooth and UV frames against UV-space 2D synthesis (render SIFID-VGG /
Gram, seam ratio, frame turn across seams). Writes ``results/surfacecnn_frames.{md,json}``.

Orientation section (``--orientation``, issue 58): the protocol meshes' xatlas layouts with a stripes
exemplar (default 128², 150 steps): orientation across UV seams (:func:`jmeshtex.metrics.seam_orientation`)
of the surface CNN and UV-space 2D synthesis beside the seamless control and the colour seam ratio.
Writes ``results/surfacecnn_orientation.{md,json}``.

Seams section (``--seams``): Spot with its own UVs and with xatlas, a grey brick exemplar at native
resolution: synthesis without and with the coupling of chart-border texels (unread share, seam
chroma, render specks) and the surface-patch measure with its baselines
(:func:`jmeshtex.metrics.surface_patch_table`). Writes ``results/surfacecnn_seams.{md,json}``.

Usage::

    python benchmarks/surfacecnn.py                       # precompute 512,1024; steps 256,512
    python benchmarks/surfacecnn.py --precompute 512 --steps 256
    python benchmarks/surfacecnn.py --mesh cow --steps 512,1024 --name surfacecnn_cow
    python benchmarks/surfacecnn.py --quality                       # the protocol (hours; resumes)
    python benchmarks/surfacecnn.py --quality --meshes spot --exemplars brick
    python benchmarks/surfacecnn.py --frames --size 96 --quality-steps 150 --exemplar stripes
    python benchmarks/surfacecnn.py --seams --size 128 --seam-steps 150
    python benchmarks/surfacecnn.py --orientation --size 128 --orientation-steps 150
"""

from __future__ import annotations

import argparse
import os
import pathlib
import resource
import time

import jax
import jax.numpy as jnp
import numpy as np
from _harness import Report, time_jax

from jmeshtex import Mesh
from jmeshtex.geometry import to_jax
from jmeshtex.metrics import load_vgg16
from jmeshtex.surfacecnn import Config, prepare_surface, unwrap_uv
from jmeshtex.surfacecnn.core import (
    default_layers,
    gram_targets,
    required_levels,
    style_loss,
    texel_density_spread,
)

SHARED = pathlib.Path(__file__).resolve().parents[1].parent / "shared" / "data"


def _mesh():
    spot = (
        pathlib.Path(os.environ.get("JMESHTEX_SHARED_DATA", SHARED))
        / "spot"
        / "spot_triangulated.obj"
    )
    if spot.is_file():
        from jmeshtex.io import load_mesh

        return "spot", load_mesh(spot)
    from jmeshtex.data import icosphere

    return "icosphere4+xatlas", icosphere(4)  # no UVs: unwrapped with xatlas


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _conv_flops(surface, weights) -> float:
    """Multiply-adds ×2 of every texel conv over the pyramid levels, forward only."""
    sizes = [len(r) for r in surface.pyramid.representative]
    level, total = 0, 0.0
    for name, (k, _) in zip(weights.names, weights.convs, strict=True):
        total += 2.0 * sizes[level] * 9 * k.shape[2] * k.shape[3]
        if name in weights.pools_after:
            level = min(level + 1, len(sizes) - 1)
    return total


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--precompute", default="512,1024", help="texture sizes for the precomputation")
    ap.add_argument("--steps", default="256,512", help="texture sizes for the optimisation step")
    ap.add_argument("--out", default=None)
    ap.add_argument(
        "--unwrap",
        choices=("xatlas", "mesh"),
        default="xatlas",
        help="texture layout: xatlas (default, the paper's) or the mesh's own UVs",
    )
    ap.add_argument("--repeats", type=int, default=5, help="timed steps per size (after one)")
    ap.add_argument(
        "--mesh",
        choices=("spot", "cow", "fandisk"),
        default="spot",
        help="spot (own UVs or xatlas) or a held-in real mesh of the protocol (its xatlas layout, "
        "kept in --work)",
    )
    ap.add_argument(
        "--work",
        type=pathlib.Path,
        default=pathlib.Path(__file__).resolve().parents[1] / "runs" / "surfacecnn_quality",
    )
    ap.add_argument("--name", default="surfacecnn", help="report name (results/NAME.md)")
    args = ap.parse_args()
    load = os.getloadavg()
    report = Report(args.name)
    print(f"load average {load}")
    if args.mesh == "spot":
        name, mesh = _mesh()
    else:
        name, mesh = args.mesh, _protocol_mesh(args.mesh, args.work)
    if args.mesh == "spot" and (args.unwrap == "xatlas" or mesh.uv is None):
        mesh = mesh.replace(uv=unwrap_uv(mesh.vertices, mesh.faces))
    spread = texel_density_spread(mesh.vertices, mesh.faces, mesh.uv)["ratio_p95_p5"]
    layout = "own UVs" if args.mesh == "spot" and args.unwrap == "mesh" else "xatlas"
    name = f"{name} ({layout}, density p95/p5 {spread:.2f})"
    weights = load_vgg16()
    layers = default_layers(weights)
    levels = required_levels(weights, layers)
    for size in [int(s) for s in args.precompute.split(",") if s]:
        t0, c0 = time.perf_counter(), time.process_time()
        surface = prepare_surface(mesh, size=size, levels=levels)
        total, cpu = time.perf_counter() - t0, time.process_time() - c0
        s = surface.seconds
        arrays_mb = (
            sum(np.asarray(a).nbytes for a in jax.tree.leaves(surface.pyramid.network_arrays()))
            / 2**20
        )
        print(
            f"{name} {size}²: {surface.atlas.num_texels} texels, {total:.2f} s wall, {cpu:.2f} s CPU "
            f"(atlas {s['atlas']:.2f}, taps {s['taps']:.2f}, pyramid {s['pyramid']:.2f}), arrays {arrays_mb:.0f} MB"
        )
        report.add(
            name=f"precompute {name} (target <= 15 s at 1024²)",
            size=f"{size}²",
            texels=surface.atlas.num_texels,
            seconds=total,
            cpu_s=cpu,
            atlas_s=s["atlas"],
            taps_s=s["taps"],
            pyramid_s=s["pyramid"],
            arrays_mb=arrays_mb,
            peak_rss_mb=_peak_mb(),
            load=load[0],
        )
    config = Config()
    optimizer_lr = config.learning_rate
    exemplar = np.random.default_rng(0).uniform(size=(256, 256, 3))
    for size in [int(s) for s in args.steps.split(",") if s]:
        surface = prepare_surface(mesh, size=size, levels=levels)
        arrays = to_jax(surface.pyramid.network_arrays(), jnp.float32)
        targets = gram_targets(exemplar, weights, layers=layers)
        import optax

        opt = optax.adam(optimizer_lr)
        x = jax.random.uniform(
            jax.random.key(0), (surface.atlas.num_texels, 3), jnp.float32, 0.0, 0.2
        )
        state = opt.init(x)

        def step(x, state, arrays, targets, opt=opt):
            loss, g = jax.value_and_grad(style_loss)(x, arrays, weights, targets)
            updates, state = opt.update(g, state, x)
            return jnp.clip(optax.apply_updates(x, updates), 0.0, 1.0), state, loss

        # the arrays are arguments, not constants of the compiled program (as in the library)
        compiled = jax.jit(step, static_argnames="opt")
        t = time_jax(compiled, x, state, arrays, targets, repeats=args.repeats, min_time=1.0)
        c0, w0 = time.process_time(), time.perf_counter()
        for _ in range(args.repeats):
            x, state, loss = compiled(x, state, arrays, targets)
            loss.block_until_ready()
        cpu_step = (time.process_time() - c0) / args.repeats
        wall_step = (time.perf_counter() - w0) / args.repeats
        flops = 3.0 * _conv_flops(surface, weights)  # forward + ~2× for the backward
        print(
            f"{name} {size}²: step {t.run_s:.3f} s (compile {t.compile_s:.1f} s), "
            f"{cpu_step:.2f} CPU-s per step"
        )
        report.add(
            name=f"optimisation step {name} (fwd+bwd VGG-16, {len(layers)} Gram layers, Adam)",
            size=f"{size}²",
            texels=surface.atlas.num_texels,
            seconds=t.run_s,
            cpu_s=cpu_step,
            wall_500_steps_min=500 * wall_step / 60,
            compile_s=t.compile_s,
            flops=flops,
            bound="flops",
            peak_rss_mb=_peak_mb(),
            load=os.getloadavg()[0],
        )
    report.write(pathlib.Path(args.out) if args.out else None)


# ---------------------------------------------------------------------------------------------
# quality: surface CNN against UV-space 2D synthesis, seams, frame jumps

QUALITY_LAYERS = ("relu1_1", "relu1_2", "pool1", "relu2_1", "relu2_2", "pool2", "relu3_1")
PNG_DIR = pathlib.Path("/tmp/round2/surfacecnn_png")


def _quality_meshes():
    from jmeshtex import Mesh
    from jmeshtex.data import icosphere
    from jmeshtex.surfacecnn import unwrap_uv

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


def _exemplar(kind: str, n: int) -> np.ndarray:
    """``brick`` (skimage's, grey) or ``stripes`` (a sine along the columns, period 8 pixels: smooth at
    texel scale, so colour jumps at seams stand out from the pattern's own variation)."""
    import skimage.data
    import skimage.transform

    if kind == "stripes":
        s = 0.5 + 0.5 * np.sin(2 * np.pi * np.arange(n) / 8.0)
        return np.repeat(np.repeat(s[None, :, None], n, 0), 3, 2)

    brick = skimage.data.brick().astype(np.float64) / 255.0
    brick = skimage.transform.resize(brick, (n, n), anti_aliasing=True)
    return np.repeat(brick[..., None], 3, axis=2)


def frames(size: int, steps: int, out: pathlib.Path | None, kind: str = "brick") -> None:
    import json

    from jmeshtex import render
    from jmeshtex.geometry import tracer_geometry
    from jmeshtex.metrics import Protocol, baseline_table
    from jmeshtex.surfacecnn import synthesize, synthesize_uv
    from jmeshtex.surfacecnn.core import frame_seam_turn, seam_ratio

    PNG_DIR.mkdir(parents=True, exist_ok=True)
    exemplar = _exemplar(kind, 96 if kind == "brick" else 32)
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
            patches = _patch_scores(
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


# ---------------------------------------------------------------------------------------------
# seams: coupling of chart-border texels (before/after) and the surface-patch measure


def _patch_scores(textured, texture, exemplar, surface, weights) -> dict:
    """:func:`jmeshtex.metrics.surface_patch_table` of a synthesis (32 patches at the texel scale;
    the initial-noise baseline drawn as the synthesis draws its start, uniform in [0, 0.2])."""
    from jmeshtex.metrics import surface_patch_table

    size = texture.shape[0]
    return surface_patch_table(
        textured,
        texture,
        exemplar,
        step=surface.atlas.texel_size,
        key=jax.random.key(5),
        num=32,
        initial=np.random.default_rng(0).uniform(0.0, 0.2, size=(size, size, 3)),
        valid=(surface.atlas.index_of >= 0).reshape(size, size),
        weights=weights,
    )


def _specks(image: np.ndarray) -> dict:
    """Speck share of an unlit render: object pixels (2-px eroded mask) whose chroma exceeds 0.3,
    and whose chroma exceeds its 7×7 median by 0.15 (isolated coloured dots)."""
    from scipy.ndimage import binary_erosion

    a = np.asarray(image, np.float64) / 255.0
    obj = binary_erosion(~(a.min(-1) > 0.99), iterations=2)
    c = a.max(-1) - a.min(-1)
    return {"abs": float((c[obj] > 0.3).mean()), "local": float(_speck_mask(a)[obj].mean())}


def _speck_mask(rgb: np.ndarray) -> np.ndarray:
    """Pixels whose chroma (max − min channel) exceeds its 7×7 median by 0.15: isolated dots."""
    from scipy.ndimage import median_filter

    chroma = rgb.max(-1) - rgb.min(-1)
    return chroma - median_filter(chroma, size=7) > 0.15


def seams(size: int, steps: int, out: pathlib.Path | None) -> None:
    """Spot (own UVs and xatlas), a grey brick exemplar at native resolution (1 pixel = 1 texel):
    synthesis without and with texel coupling; unread share, seam chroma, specks, surface patches."""
    import json

    import skimage.data

    from jmeshtex import render
    from jmeshtex.geometry import tracer_geometry
    from jmeshtex.surfacecnn import synthesize
    from jmeshtex.surfacecnn.core import read_counts, seam_chroma, unread_share

    name, base = _mesh()
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
            specks = [_specks(v) for v in views]
            table = _patch_scores(textured, r.texture, exemplar, surface, weights)
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


# ---------------------------------------------------------------------------------------------
# quality: the issue-33 protocol (real meshes, native-resolution exemplars, paper settings)

PROTOCOL_MESHES = {
    "spot": ("spot/spot_triangulated.obj", "y"),
    "cow": ("cow.obj", "y"),
    "fandisk": ("fandisk.obj", "y"),
}
PROTOCOL_EXEMPLARS = ("brick", "grass", "immunohistochemistry")


def protocol_exemplar(name: str) -> np.ndarray:
    """A scikit-image photograph at its native 512² (1 exemplar pixel = 1 texel), RGB in [0, 1]."""
    import skimage.data

    image = getattr(skimage.data, name)().astype(np.float64) / 255.0
    return image if image.ndim == 3 else np.repeat(image[..., None], 3, axis=2)


def _protocol_mesh(name: str, work: pathlib.Path) -> Mesh:
    """The shared mesh, unwrapped with xatlas once (the layout is kept in ``work`` so a resumed
    run optimises the same texels)."""
    from jmeshtex.geometry import prepare_mesh
    from jmeshtex.io import load_mesh

    path = work / f"{name}_xatlas.npz"
    if path.is_file():
        with np.load(path) as z:
            return Mesh(z["vertices"], z["faces"], uv=z["uv"])
    base = load_mesh(
        pathlib.Path(os.environ.get("JMESHTEX_SHARED_DATA", SHARED)) / PROTOCOL_MESHES[name][0]
    )
    base, _ = prepare_mesh(base.replace(uv=None, texture=None), repair=True)  # the cow: a bow-tie
    mesh = Mesh(base.vertices, base.faces, uv=unwrap_uv(base.vertices, base.faces))
    work.mkdir(parents=True, exist_ok=True)
    np.savez(
        path,
        vertices=np.asarray(mesh.vertices),
        faces=np.asarray(mesh.faces),
        uv=np.asarray(mesh.uv),
    )
    return mesh


def _protocol_cell(mesh_name, mesh, up, surface, geometry, ex_name, size, steps, weights, work):
    """One (mesh, exemplar) cell: the surface CNN and UV-space 2D synthesis with the same
    settings, each scored by seams, specks and surface patches; resumable (checkpoints and the
    finished row in ``work``). The 2D image does not depend on the mesh, so one run per exemplar
    (``work/uv2d/<exemplar>_<size>_<steps>``) serves every mesh's cell."""
    import json

    from jmeshtex import render
    from jmeshtex.io import atomic_write
    from jmeshtex.metrics import seam_orientation
    from jmeshtex.surfacecnn import synthesize, synthesize_uv
    from jmeshtex.surfacecnn.core import seam_ratio

    cell = work / f"{mesh_name}_{ex_name}_{size}_{steps}"
    done = cell / "row.json"
    if done.is_file():
        return json.loads(done.read_text())
    exemplar = protocol_exemplar(ex_name)
    config = Config(size=size, steps=steps)
    cams = render.orbit_cameras(mesh, azimuths=4, elevations=(20.0,), size=(size, size), up=up)
    row = {
        "mesh": mesh_name,
        "exemplar": ex_name,
        "size": size,
        "steps": steps,
        "texels": int(surface.atlas.num_texels),
        "texel_density_spread": _layout_spread(mesh_name, work),
    }
    laid = Mesh(mesh.vertices, mesh.faces, uv=surface.atlas.uv)
    control = seam_orientation(laid, _orientation_control(mesh, surface, config))
    row["orientation_control"] = {"seam": control.seam, "interior": control.interior}
    panels = [("exemplar", exemplar)]
    folders = {"surface": cell / "surface", "uv2d": work / "uv2d" / f"{ex_name}_{size}_{steps}"}
    for method, run in (("surface", synthesize), ("uv2d", synthesize_uv)):
        resumed = folders[method].is_dir() and any(folders[method].iterdir())
        t0, c0 = time.perf_counter(), time.process_time()
        r = run(
            mesh,
            exemplar,
            config,
            key=jax.random.key(0),
            surface=surface,
            weights=weights,
            progress=False,
            checkpoint_dir=folders[method],
        )
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        np.save(cell / f"{method}_texture.npy", np.asarray(r.texture, np.float32))
        seams = seam_ratio(r.colors, surface.atlas, surface.pyramid.nearest[0], geometry=geometry)
        textured = Mesh(mesh.vertices, mesh.faces, uv=surface.atlas.uv, texture=r.texture)
        views = render.render_views(textured, cams, shading="unlit")
        specks = [_specks(v) for v in views]
        patches = _patch_scores(textured, r.texture, exemplar, surface, weights)
        orient = seam_orientation(textured, r.texture)
        row[method] = {
            "seconds": wall,
            "cpu_s": cpu,
            "resumed": resumed,  # the times are then those of the last call only
            "final_loss": float(r.final_loss),
            "loss_500_over_250": float(r.losses[-1] / r.losses[len(r.losses) // 2]),
            "seam_ratio": float(seams["ratio"]),
            "orientation_seam": orient.seam,
            "orientation_interior": orient.interior,
            "speck_abs": float(np.mean([s["abs"] for s in specks])),
            "speck_local": float(np.mean([s["local"] for s in specks])),
            "patches": patches,
        }
        print(
            json.dumps(
                {
                    "cell": cell.name,
                    "method": method,
                    **{k: v for k, v in row[method].items() if k != "patches"},
                }
            ),
            flush=True,
        )
        panels += [(f"{method} view {i}", views[i]) for i in (0, 1)]
    row["peak_rss_mb"] = _peak_mb()
    render.figure(
        panels,
        columns=5,
        title=f"{mesh_name}, {ex_name}, {size}x{size} texels, {steps} steps",  # the font has no ²
        path=cell / "figure.png",
    )
    atomic_write(done, (json.dumps(row, indent=1) + "\n").encode())
    return row


def quality(
    meshes, exemplars, size: int, steps: int, work: pathlib.Path, out: pathlib.Path | None
) -> None:
    """The issue-33 protocol: every (mesh, exemplar) cell at ``size``² and ``steps`` steps, every
    VGG-16 ReLU and pool output, xatlas layouts, exemplars at native resolution. The report lists
    every finished cell (:func:`finished_rows`), in protocol order."""
    from jmeshtex.geometry import tracer_geometry

    weights = load_vgg16()
    levels = required_levels(weights, default_layers(weights))
    for mesh_name in meshes:
        mesh = _protocol_mesh(mesh_name, work)
        surface, geometry = None, None
        for ex_name in exemplars:
            cell = work / f"{mesh_name}_{ex_name}_{size}_{steps}" / "row.json"
            if surface is None and not cell.is_file():
                surface = prepare_surface(mesh, size=size, levels=levels)
                geometry = tracer_geometry(mesh.vertices, mesh.faces)
            _protocol_cell(
                mesh_name,
                mesh,
                PROTOCOL_MESHES[mesh_name][1],
                surface,
                geometry,
                ex_name,
                size,
                steps,
                weights,
                work,
            )
    record = pathlib.Path(__file__).resolve().parent / "results" / "surfacecnn.quality.json"
    rows = finished_rows(work, record, size, steps)
    spreads = {}
    for row in rows:
        if row["mesh"] not in spreads:
            spreads[row["mesh"]] = row.get("texel_density_spread") or _layout_spread(
                row["mesh"], work
            )
    tiled_baseline(rows, work)
    speck_texels(rows, work)
    _write_quality(rows, spreads, size, steps, out)


def _orientation_control(mesh: Mesh, surface, config: Config) -> np.ndarray:
    """The seamless control of the orientation measure on ``surface``'s layout: stripes along the
    frames' world vector (their normal is the projected ``frame_vector``, the direction a
    column-sine exemplar's stripe normal takes under the ``"global"`` frames), period 8 texels."""
    from jmeshtex.metrics import stripe_texture

    laid = Mesh(mesh.vertices, mesh.faces, uv=surface.atlas.uv)
    return stripe_texture(
        laid,
        surface.atlas.size,
        direction=config.frame_vector,
        period=8.0 * surface.atlas.texel_size,
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
    meshes, exemplars, size: int, steps: int, work: pathlib.Path, out: pathlib.Path | None
) -> None:
    """Orientation across UV seams (:func:`jmeshtex.metrics.seam_orientation`) of the surface CNN
    and of UV-space 2D synthesis on the protocol's xatlas layouts, beside the seamless control
    (:func:`_orientation_control`) and the colour seam ratio; textures kept in ``work`` (a rerun
    only re-scores). Writes ``results/surfacecnn_orientation.{md,json}``."""
    import json

    from jmeshtex.geometry import tracer_geometry
    from jmeshtex.metrics import seam_orientation
    from jmeshtex.surfacecnn import synthesize, synthesize_uv
    from jmeshtex.surfacecnn.core import seam_ratio

    weights = load_vgg16()
    levels = required_levels(weights, default_layers(weights))
    config = Config(size=size, steps=steps)
    rows = []
    for mesh_name in meshes:
        mesh = _protocol_mesh(mesh_name, work)
        t0 = time.perf_counter()
        surface = prepare_surface(mesh, size=size, levels=levels)
        prep = time.perf_counter() - t0
        geometry = tracer_geometry(mesh.vertices, mesh.faces)
        laid = Mesh(mesh.vertices, mesh.faces, uv=surface.atlas.uv)
        control = seam_orientation(laid, _orientation_control(mesh, surface, config))
        for ex_name in exemplars:
            exemplar = (
                _exemplar(ex_name, 128) if ex_name == "stripes" else protocol_exemplar(ex_name)
            )
            row = {
                "mesh": mesh_name,
                "exemplar": ex_name,
                "size": size,
                "steps": steps,
                "texels": int(surface.atlas.num_texels),
                "prepare_s": prep,
                "control": {
                    "seam": control.seam,
                    "seam_smooth": control.seam_at(0.0, 30.0),
                    "seam_crease": control.seam_at(30.0, 180.0),
                    "interior": control.interior,
                },
            }
            for method, run in (("surface", synthesize), ("uv2d", synthesize_uv)):
                path = work / "orientation" / f"{mesh_name}_{ex_name}_{size}_{steps}_{method}.npz"
                if path.is_file():
                    with np.load(path) as z:
                        texture, colors, loss, cpu = z["texture"], z["colors"], z["loss"], z["cpu"]
                else:
                    c0 = time.process_time()
                    # the 2D image does not depend on the mesh: one optimisation serves every mesh
                    shared = work / "uv2d" / f"{ex_name}_{size}_{steps}_orientation"
                    r = run(
                        mesh,
                        exemplar,
                        config,
                        key=jax.random.key(0),
                        surface=surface,
                        weights=weights,
                        progress=False,
                        **({"checkpoint": shared} if method == "uv2d" else {}),
                    )
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
        "global frames (x), the protocol's xatlas layouts. Alignment: mean |cos| between the "
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
    (directory / "surfacecnn_orientation.md").write_text(text)
    (directory / "surfacecnn_orientation.json").write_text(json.dumps(rows, indent=1) + "\n")


def orientation_figure(
    mesh_name: str, size: int, steps: int, work: pathlib.Path, out: pathlib.Path | None
) -> None:
    """Stripes on a protocol mesh from the ``--orientation`` textures in ``work``: the surface CNN
    and UV-space 2D synthesis, a whole view and a close view across a UV seam (with the charts
    seen from the same camera), and both UV images. Writes
    ``results/surfacecnn_orientation_<mesh>.png``."""
    from jmeshtex import render
    from jmeshtex.metrics import seam_orientation, uv_charts

    mesh = _protocol_mesh(mesh_name, work)
    tex = {}
    for method in ("surface", "uv2d"):
        path = work / "orientation" / f"{mesh_name}_stripes_{size}_{steps}_{method}.npz"
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
    panels = [("exemplar (stripes, period 8 px)", big(_exemplar("stripes", 128)))]
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


def speck_texels(rows: list[dict], work: pathlib.Path) -> None:
    """Adds to each row whose textures are in ``work`` where its speck texels lie: the share of
    valid texels whose chroma exceeds its 7×7 median by 0.15 (the render measure, in texture
    space), within 2 texels of a chart border and deeper inside. Seam specks crowd the border; a
    recipe's colour noise does not care."""
    from scipy.ndimage import distance_transform_edt

    from jmeshtex.surfacecnn.core import texture_atlas

    for row in rows:
        cell = work / f"{row['mesh']}_{row['exemplar']}_{row['size']}_{row['steps']}"
        if "speck_texels" in row["surface"] or not (cell / "uv2d_texture.npy").is_file():
            continue
        mesh, n = _protocol_mesh(row["mesh"], work), row["size"]
        atlas = texture_atlas(mesh.vertices, mesh.faces, mesh.uv, size=n)
        valid = np.zeros(n * n, bool)
        valid[atlas.texel] = True
        valid = valid.reshape(n, n)
        border = valid & (distance_transform_edt(valid) <= 2)
        for method in ("surface", "uv2d"):
            speck = _speck_mask(np.load(cell / f"{method}_texture.npy").astype(np.float64))
            row[method]["speck_texels"] = {
                "border": float(speck[border].mean()),
                "inside": float(speck[valid & ~border].mean()),
            }


def tiled_baseline(rows: list[dict], work: pathlib.Path) -> None:
    """Adds to each row the seam ratio and speck share of the exemplar tiled in UV space (the patch
    table's ``uv_tiled`` baseline: seams break it, patches barely see it; its specks are the
    exemplar's own colour detail, the floor of the speck measure) on the cell's layout, with the
    cell's views. Rows of an earlier session gain it here, after a check that the layout is the
    cell's (same texel count)."""
    from jmeshtex import render
    from jmeshtex.geometry import tracer_geometry
    from jmeshtex.metrics import seam_orientation, tiled_exemplar
    from jmeshtex.surfacecnn.core import seam_ratio

    layouts = {}
    for row in rows:
        if "uv_tiled" in row:
            continue
        name, n = row["mesh"], row["size"]
        if (name, n) not in layouts:
            mesh = _protocol_mesh(name, work)
            surface = prepare_surface(mesh, size=n, levels=0)
            cams = render.orbit_cameras(
                mesh, azimuths=4, elevations=(20.0,), size=(n, n), up=PROTOCOL_MESHES[name][1]
            )
            layouts[name, n] = (mesh, surface, tracer_geometry(mesh.vertices, mesh.faces), cams)
        mesh, surface, geometry, cams = layouts[name, n]
        if surface.atlas.num_texels != row["texels"]:
            raise SystemExit(
                f"{name}: the xatlas layout in {work} has {surface.atlas.num_texels} texels, "
                f"the cell was scored on {row['texels']}: not the same layout"
            )
        tiled = tiled_exemplar(protocol_exemplar(row["exemplar"]), (n, n))  # the patch table's
        colors = tiled.reshape(n * n, 3)[surface.atlas.texel]
        seams = seam_ratio(colors, surface.atlas, surface.pyramid.nearest[0], geometry=geometry)
        textured = Mesh(mesh.vertices, mesh.faces, uv=surface.atlas.uv, texture=tiled)
        specks = [_specks(v) for v in render.render_views(textured, cams, shading="unlit")]
        orient = seam_orientation(textured, tiled)
        row["uv_tiled"] = {
            "seam_ratio": float(seams["ratio"]),
            "orientation_seam": orient.seam,
            "orientation_interior": orient.interior,
            "speck_abs": float(np.mean([s["abs"] for s in specks])),
            "speck_local": float(np.mean([s["local"] for s in specks])),
        }


def finished_rows(work: pathlib.Path, record: pathlib.Path, size: int, steps: int) -> list[dict]:
    """Every finished protocol cell at ``size``² and ``steps`` steps, in protocol order: the row in
    ``work`` where there is one, else the committed row in ``record`` (a cell finished in an
    earlier session whose work folder is gone)."""
    import json

    committed = {}
    if record.is_file():
        for r in json.loads(record.read_text()):
            committed[(r["mesh"], r["exemplar"], r["size"], r["steps"])] = r
    rows = []
    for mesh_name in PROTOCOL_MESHES:
        for ex_name in PROTOCOL_EXEMPLARS:
            done = work / f"{mesh_name}_{ex_name}_{size}_{steps}" / "row.json"
            if done.is_file():
                rows.append(json.loads(done.read_text()))
            elif (mesh_name, ex_name, size, steps) in committed:
                rows.append(committed[mesh_name, ex_name, size, steps])
    return rows


def _layout_spread(mesh_name: str, work: pathlib.Path) -> float:
    """The p95/p5 texel-density spread of the protocol's xatlas layout of ``mesh_name``."""
    mesh = _protocol_mesh(mesh_name, work)
    return float(texel_density_spread(mesh.vertices, mesh.faces, mesh.uv)["ratio_p95_p5"])


def _orientation_cell(row: dict, m: dict) -> str:
    """``seam / interior (control seam / interior; uv_tiled seam / interior)`` or — for a cell
    scored before the orientation measure."""
    if "orientation_seam" not in m:
        return "—"
    c, t = row.get("orientation_control", {}), row.get("uv_tiled", {})
    control = f"{c['seam']:.3f} / {c['interior']:.3f}" if c else "—"
    tiled = (
        f"{t['orientation_seam']:.3f} / {t['orientation_interior']:.3f}"
        if "orientation_seam" in t
        else "—"
    )
    return f"{m['orientation_seam']:.3f} / {m['orientation_interior']:.3f} ({control}; {tiled})"


def _write_quality(rows, spreads, size, steps, out):
    import json

    baselines = ("flat", "permuted", "initial", "uv_tiled", "floor")
    lines = [
        "# surfacecnn quality\n",
        f"Protocol of issue 33: {size}² textures, {steps} steps (Adam 0.1 halved every 200), every "
        "ReLU and pool output of the embedded VGG-16, xatlas layouts, exemplars at native 512² "
        "(1 exemplar pixel = 1 texel). Surface patches: 32 geodesic patches of 32² texels in the "
        "synthesis frames against exemplar crops; cells read patch Gram / log radial spectrum L1 "
        "(network-free). Seam ratio: mean colour difference across chart seams over inside charts "
        "(in brackets: the exemplar tiled in UV space on the same layout). "
        "Specks: share of object pixels of 4 unlit views (one pixel ≈ one texel) whose chroma "
        "exceeds its 7×7 median by 0.15 (in brackets: the UV-tiled exemplar's, the exemplar's own "
        "colour detail). UV-space 2D runs once per exemplar (its image does not depend on the "
        'mesh): the cells after the first read it back, so their cost reads "resumed".\n',
        "| mesh | exemplar | method | patch Gram / spectrum | "
        + " | ".join(baselines)
        + " | charts / patch | seam ratio (uv_tiled) | orientation seam / interior (control; "
        "uv_tiled) | specks (uv_tiled) | loss | CPU-s | wall s |",
        "|---|---|---|---|" + "---|" * len(baselines) + "---|---|---|---|---|---|---|",
    ]
    for r in rows:
        for method, label in (("surface", "surface CNN"), ("uv2d", "UV-space 2D")):
            m = r[method]
            p = m["patches"]
            cells = " | ".join(f"{p[k]['gram']:.3g} / {p[k]['spectrum']:.3f}" for k in baselines)
            lines.append(
                f"| {r['mesh']} | {r['exemplar']} | {label} | **{p['texture']['gram']:.3g} / "
                f"{p['texture']['spectrum']:.3f}** | {cells} | {p['texture']['charts']:.2f} | "
                f"{m['seam_ratio']:.3f} ({r['uv_tiled']['seam_ratio']:.3f}) | "
                f"{_orientation_cell(r, m)} | "
                f"{m['speck_local']:.4f} ({r['uv_tiled']['speck_local']:.4f}) | "
                f"{m['final_loss']:.4g} | "
                + (
                    f"{m['cpu_s']:.0f} | {m['seconds']:.0f} |"
                    if not m.get("resumed")
                    else "resumed | resumed |"  # spread over sessions: the last call's is no cost
                )
            )
    lines.append(
        "\nOrientation: mean alignment |cos| of the structure-tensor stripe normals of the two "
        "faces of each seam edge / interior edge (jmeshtex.metrics.seam_orientation; random line "
        "fields 0.637), beside a seamless control (3D stripes along x, period 8 texels, baked "
        "into the same atlas) and the UV-tiled exemplar; — where a cell was scored before the "
        "measure existed."
    )
    kept = [r for r in rows if "speck_texels" in r["surface"]]
    if kept:
        lines += [
            "",
            "Where the specks lie, in texture space (valid texels whose chroma exceeds its 7×7 "
            "median by 0.15; cells whose textures were kept): within 2 texels of a chart border / "
            "deeper inside.",
            "",
            "| mesh | exemplar | surface CNN | UV-space 2D |",
            "|---|---|---|---|",
        ]
        for r in kept:
            s, u = r["surface"]["speck_texels"], r["uv2d"]["speck_texels"]
            lines.append(
                f"| {r['mesh']} | {r['exemplar']} | {s['border']:.4f} / {s['inside']:.4f} | "
                f"{u['border']:.4f} / {u['inside']:.4f} |"
            )
    lines += ["", "| mesh | texel-density spread p95/p5 (xatlas) |", "|---|---|"]
    lines += [f"| {k} | {v:.2f} |" for k, v in spreads.items()]
    lines.append(f"\nLoad average at the end {os.getloadavg()[0]:.1f} (shared 2-core machine).")
    text = "\n".join(lines) + "\n"
    print(text)
    directory = out if out is not None else pathlib.Path(__file__).resolve().parent / "results"
    (directory / "surfacecnn.quality.md").write_text(text)
    (directory / "surfacecnn.quality.json").write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    import sys

    def orientation_parser(flag: str, **kwargs) -> argparse.ArgumentParser:
        """The arguments --orientation and --orientation-figure share."""
        parser = argparse.ArgumentParser()
        parser.add_argument(flag, **kwargs)
        parser.add_argument("--size", type=int, default=128)
        parser.add_argument("--orientation-steps", type=int, default=150)
        parser.add_argument(
            "--work",
            type=pathlib.Path,
            default=pathlib.Path(__file__).resolve().parents[1] / "runs" / "surfacecnn_quality",
        )
        parser.add_argument("--out", type=pathlib.Path, default=None)
        return parser

    if "--orientation-figure" in sys.argv:
        fa = orientation_parser("--orientation-figure", default="spot").parse_args()
        orientation_figure(fa.orientation_figure, fa.size, fa.orientation_steps, fa.work, fa.out)
    elif "--orientation" in sys.argv:
        op = orientation_parser("--orientation", action="store_true")
        op.add_argument("--meshes", default=",".join(PROTOCOL_MESHES))
        op.add_argument("--exemplars", default="stripes")
        oa = op.parse_args()
        orientation(
            oa.meshes.split(","),
            oa.exemplars.split(","),
            oa.size,
            oa.orientation_steps,
            oa.work,
            oa.out,
        )
    elif "--seams" in sys.argv:
        sp = argparse.ArgumentParser()
        sp.add_argument("--seams", action="store_true")
        sp.add_argument("--size", type=int, default=128)
        sp.add_argument("--seam-steps", type=int, default=150)
        sp.add_argument("--out", default=None)
        sa = sp.parse_args()
        seams(sa.size, sa.seam_steps, pathlib.Path(sa.out) if sa.out else None)
    elif "--frames" in sys.argv:
        qp = argparse.ArgumentParser()
        qp.add_argument("--frames", action="store_true")
        qp.add_argument("--size", type=int, default=96)
        qp.add_argument("--quality-steps", type=int, default=150)
        qp.add_argument("--exemplar", choices=("brick", "stripes"), default="brick")
        qp.add_argument("--out", default=None)
        qa = qp.parse_args()
        frames(qa.size, qa.quality_steps, pathlib.Path(qa.out) if qa.out else None, qa.exemplar)
    elif "--quality" in sys.argv:
        qp = argparse.ArgumentParser()
        qp.add_argument("--quality", action="store_true")
        qp.add_argument("--meshes", default=",".join(PROTOCOL_MESHES))
        qp.add_argument("--exemplars", default=",".join(PROTOCOL_EXEMPLARS))
        qp.add_argument("--size", type=int, default=512)
        qp.add_argument("--quality-steps", type=int, default=500)
        qp.add_argument(
            "--work",
            type=pathlib.Path,
            default=pathlib.Path(__file__).resolve().parents[1] / "runs" / "surfacecnn_quality",
            help="resumable cells (checkpoints, textures, finished rows)",
        )
        qp.add_argument("--out", default=None)
        qa = qp.parse_args()
        quality(
            qa.meshes.split(","),
            qa.exemplars.split(","),
            qa.size,
            qa.quality_steps,
            qa.work,
            pathlib.Path(qa.out) if qa.out else None,
        )
    else:
        main()

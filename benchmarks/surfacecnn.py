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

The one-change-at-a-time studies (frames, seams, orientation across seams) are standalone scripts
in ``studies/`` (``studies/README.md``).

Usage::

    python benchmarks/surfacecnn.py                       # precompute 512,1024; steps 256,512
    python benchmarks/surfacecnn.py --precompute 512 --steps 256
    python benchmarks/surfacecnn.py --mesh cow --steps 512,1024 --name surfacecnn_cow
    python benchmarks/surfacecnn.py --quality                       # the protocol (hours; resumes)
    python benchmarks/surfacecnn.py --quality --meshes spot --exemplars brick
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


def benchmark_mesh():
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


def peak_mb() -> float:
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
        name, mesh = benchmark_mesh()
    else:
        name, mesh = args.mesh, protocol_mesh(args.mesh, args.work)
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
            peak_rss_mb=peak_mb(),
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
            peak_rss_mb=peak_mb(),
            load=os.getloadavg()[0],
        )
    report.write(pathlib.Path(args.out) if args.out else None)


# ---------------------------------------------------------------------------------------------
# quality: surface CNN against UV-space 2D synthesis, seams, frame jumps


# ---------------------------------------------------------------------------------------------
# seams: coupling of chart-border texels (before/after) and the surface-patch measure


def patch_scores(textured, texture, exemplar, surface, weights) -> dict:
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


def specks(image: np.ndarray) -> dict:
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


# ---------------------------------------------------------------------------------------------
# quality: the issue-33 protocol (real meshes, native-resolution exemplars, paper settings)

PROTOCOL_MESHES = {
    "spot": ("spot/spot_triangulated.obj", "y"),
    "cow": ("cow.obj", "y"),
    "fandisk": ("fandisk.obj", "y"),
}
#: the three photographs of issue 33 and an oriented exemplar (issue 58: orientation across seams)
PROTOCOL_EXEMPLARS = ("brick", "grass", "immunohistochemistry", "stripes")


def protocol_exemplar(name: str) -> np.ndarray:
    """A scikit-image photograph at its native 512² (1 exemplar pixel = 1 texel), RGB in [0, 1];
    ``"stripes"``: 512² grey stripes, a sine along the columns with a period of 8 pixels (the
    orientation study's exemplar at the protocol's size)."""
    import skimage.data

    if name == "stripes":
        s = 0.5 + 0.5 * np.sin(2 * np.pi * np.arange(512) / 8.0)
        return np.repeat(np.repeat(s[None, :, None], 512, 0), 3, 2)

    image = getattr(skimage.data, name)().astype(np.float64) / 255.0
    return image if image.ndim == 3 else np.repeat(image[..., None], 3, axis=2)


def protocol_mesh(name: str, work: pathlib.Path) -> Mesh:
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


def cell_columns(mesh_name: str, ex_name: str, size: int, steps: int, surface) -> dict:
    """The columns that name a protocol cell: its mesh, exemplar, texture size, steps and texels."""
    return {
        "mesh": mesh_name,
        "exemplar": ex_name,
        "size": size,
        "steps": steps,
        "texels": int(surface.atlas.num_texels),
    }


def synthesize_cell(method, mesh, exemplar, config, surface, weights, checkpoint_dir=None):
    """A protocol cell's optimisation: ``method`` ``"surface"`` (the surface CNN) or ``"uv2d"``
    (UV-space 2D synthesis) from key 0, quiet, resumable in ``checkpoint_dir``."""
    from jmeshtex.surfacecnn import synthesize, synthesize_uv

    run = {"surface": synthesize, "uv2d": synthesize_uv}[method]
    return run(
        mesh,
        exemplar,
        config,
        key=jax.random.key(0),
        surface=surface,
        weights=weights,
        progress=False,
        checkpoint_dir=checkpoint_dir,
    )


def _protocol_cell(
    mesh_name,
    mesh,
    up,
    surface,
    geometry,
    ex_name,
    size,
    steps,
    weights,
    work,
    methods=("surface", "uv2d"),
):
    """One (mesh, exemplar) cell: the surface CNN and UV-space 2D synthesis with the same
    settings, each scored by seams, specks and surface patches; resumable (checkpoints and the
    finished row in ``work``). The 2D image does not depend on the mesh, so one run per exemplar
    (``work/uv2d/<exemplar>_<size>_<steps>``) serves every mesh's cell. ``methods``: a study that
    changes only the surface CNN runs ``("surface",)`` in its own ``work``."""
    import json

    from jmeshtex import render
    from jmeshtex.io import atomic_write
    from jmeshtex.metrics import seam_orientation
    from jmeshtex.surfacecnn.core import seam_ratio

    cell = work / f"{mesh_name}_{ex_name}_{size}_{steps}"
    done = cell / "row.json"
    if done.is_file():
        return json.loads(done.read_text())
    exemplar = protocol_exemplar(ex_name)
    config = Config(size=size, steps=steps)
    cams = render.orbit_cameras(mesh, azimuths=4, elevations=(20.0,), size=(size, size), up=up)
    row = cell_columns(mesh_name, ex_name, size, steps, surface)
    row["frames"] = {"frames": config.frames, "frame_smoothing": config.frame_smoothing}
    row["texel_density_spread"] = _layout_spread(mesh_name, work)
    laid = Mesh(mesh.vertices, mesh.faces, uv=surface.atlas.uv)
    control = seam_orientation(laid, orientation_control(mesh, surface, config))
    row["orientation_control"] = {"seam": control.seam, "interior": control.interior}
    panels = [("exemplar", exemplar)]
    folders = {"surface": cell / "surface", "uv2d": work / "uv2d" / f"{ex_name}_{size}_{steps}"}
    for method in methods:
        folder = folders[method]
        resumed = folder.is_dir() and any(folder.iterdir())
        t0, c0 = time.perf_counter(), time.process_time()
        r = synthesize_cell(method, mesh, exemplar, config, surface, weights, folder)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        np.save(cell / f"{method}_texture.npy", np.asarray(r.texture, np.float32))
        seams = seam_ratio(r.colors, surface.atlas, surface.pyramid.nearest[0], geometry=geometry)
        textured = Mesh(mesh.vertices, mesh.faces, uv=surface.atlas.uv, texture=r.texture)
        views = render.render_views(textured, cams, shading="unlit")
        view_specks = [specks(v) for v in views]
        patches = patch_scores(textured, r.texture, exemplar, surface, weights)
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
            "speck_abs": float(np.mean([s["abs"] for s in view_specks])),
            "speck_local": float(np.mean([s["local"] for s in view_specks])),
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
    row["peak_rss_mb"] = peak_mb()
    render.figure(
        panels,
        columns=5,
        title=f"{mesh_name}, {ex_name}, {size}x{size} texels, {steps} steps",  # the font has no ²
        path=cell / "figure.png",
    )
    atomic_write(done, (json.dumps(row, indent=1) + "\n").encode())
    return row


def run_cells(
    meshes, exemplars, size: int, steps: int, work: pathlib.Path, methods=("surface", "uv2d")
) -> None:
    """Every (mesh, exemplar) protocol cell at ``size``² and ``steps`` steps in ``work``,
    resumable; ``methods`` as :func:`_protocol_cell`'s."""
    from jmeshtex.geometry import tracer_geometry

    weights = load_vgg16()
    levels = required_levels(weights, default_layers(weights))
    for mesh_name in meshes:
        mesh = protocol_mesh(mesh_name, work)
        surface, geometry = None, None
        for ex_name in exemplars:
            if (work / f"{mesh_name}_{ex_name}_{size}_{steps}" / "row.json").is_file():
                continue
            if surface is None:
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
                methods,
            )


def quality(
    meshes, exemplars, size: int, steps: int, work: pathlib.Path, out: pathlib.Path | None
) -> None:
    """The issue-33 protocol: every (mesh, exemplar) cell at ``size``² and ``steps`` steps, every
    VGG-16 ReLU and pool output, xatlas layouts, exemplars at native resolution. The report lists
    every finished cell (:func:`finished_rows`), in protocol order."""
    run_cells(meshes, exemplars, size, steps, work)
    rows = finished_rows(work, size, steps)
    spreads = {}
    for row in rows:
        if row["mesh"] not in spreads:
            spreads[row["mesh"]] = row.get("texel_density_spread") or _layout_spread(
                row["mesh"], work
            )
    tiled_baseline(rows, work)
    speck_texels(rows, work)
    _write_quality(rows, spreads, size, steps, out)


def orientation_control(mesh: Mesh, surface, config: Config) -> np.ndarray:
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
        mesh, n = protocol_mesh(row["mesh"], work), row["size"]
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
            mesh = protocol_mesh(name, work)
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
        view_specks = [specks(v) for v in render.render_views(textured, cams, shading="unlit")]
        orient = seam_orientation(textured, tiled)
        row["uv_tiled"] = {
            "seam_ratio": float(seams["ratio"]),
            "orientation_seam": orient.seam,
            "orientation_interior": orient.interior,
            "speck_abs": float(np.mean([s["abs"] for s in view_specks])),
            "speck_local": float(np.mean([s["local"] for s in view_specks])),
        }


def finished_rows(work: pathlib.Path, size: int, steps: int) -> list[dict]:
    """Every protocol cell at ``size``² and ``steps`` steps finished in ``work`` (this run's
    resumable cells), in protocol order. No row comes from an earlier results file: a cell whose
    work folder is gone is run again."""
    import json

    rows = []
    for mesh_name in PROTOCOL_MESHES:
        for ex_name in PROTOCOL_EXEMPLARS:
            done = work / f"{mesh_name}_{ex_name}_{size}_{steps}" / "row.json"
            if done.is_file():
                rows.append(json.loads(done.read_text()))
    return rows


def _layout_spread(mesh_name: str, work: pathlib.Path) -> float:
    """The p95/p5 texel-density spread of the protocol's xatlas layout of ``mesh_name``."""
    mesh = protocol_mesh(mesh_name, work)
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


def _frames_words(row: dict) -> str:
    """The tangent frames a cell was synthesised with (``Config.frames``, ``frame_smoothing``)."""
    f = row.get("frames")
    if f is None:
        return "not recorded (cells finished before issue 58's frame smoothing: the paper's frames)"
    return f"{f['frames']}, smoothed over {f['frame_smoothing']:g} texels"


def _write_quality(rows, spreads, size, steps, out):
    import json

    baselines = ("flat", "permuted", "initial", "uv_tiled", "floor")
    frames = sorted({_frames_words(r) for r in rows})
    lines = [
        "# surfacecnn quality\n",
        f"Tangent frames of the cells: {'; '.join(frames)}.\n",
        f"Protocol of issue 33: {size}² textures, {steps} steps (Adam 0.1 halved every 200), every "
        "ReLU and pool output of the embedded VGG-16, xatlas layouts, exemplars at native 512² "
        "(three photographs and 8-pixel stripes; 1 exemplar pixel = 1 texel). Surface patches: 32 geodesic patches of 32² texels in the "
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


def quality_main(argv: list[str] | None = None) -> None:
    qp = argparse.ArgumentParser(description="the quality protocol (issue 33)")
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
    qa = qp.parse_args(argv)
    quality(
        qa.meshes.split(","),
        qa.exemplars.split(","),
        qa.size,
        qa.quality_steps,
        qa.work,
        pathlib.Path(qa.out) if qa.out else None,
    )


if __name__ == "__main__":
    import sys

    if "--quality" in sys.argv:
        quality_main()
    else:
        main()

"""Benchmark: a 512² view of a 100K-face textured torus — visibility and shading timed apart.

Run: ``.venv/bin/python benchmarks/render.py [--quick] [--out DIR]``. Writes
``benchmarks/results/render.{json,md}``.

Rows:

- ``visibility (NumPy z-buffer)``: :func:`jmeshtex.render.rasterize` at 2×2 supersampling
  (1024² samples), host NumPy;
- ``visibility (Embree rays)``: the same buffer by ray casting one ray per sample through Embree
  (the ``embreex`` wheel trimesh uses; scene build included), when ``embreex`` is importable — it is
  not a jmeshtex dependency;
- ``shading (JAX, jit)``: :func:`jmeshtex.render.shade` (trimmed-down: trilinear mip-mapped texture,
  smooth Lambert + Blinn-Phong, 2×2 box filter), compile time apart;
- ``total render()``: the public call end to end (uint8 out);
- ``old matplotlib path``: the removed renderer (flat-shaded ``Poly3DCollection``, painter's
  algorithm, one colour per face), re-implemented here only, on the same mesh (``--old-faces N``:
  on an N-face torus, the figure for the benchmark mesh is then a linear projection and says so),
  next to the new ``render()`` on that mesh;
- scaling rows: visibility and shading at several face counts (512²) and image sizes (100K faces).

Every wall time has the process CPU time next to it: the reference machine is shared, so wall
times include waiting for a core; the load average is in the config.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
from _harness import Report, Size, size_label, time_jax

from jmeshtex import Mesh
from jmeshtex.data import torus
from jmeshtex.geometry import vertex_normals
from jmeshtex.render import (
    Lighting,
    camera_lighting,
    orbit_cameras,
    rasterize,
    render,
    shade,
    texture_lod,
)


def textured_torus(faces: int):
    """A torus with about ``faces`` faces, UVs from its two angles and a procedural 512² texture."""
    n_minor = int(round(np.sqrt(faces / 2 / 1.25)))
    n_major = int(round(faces / 2 / n_minor))
    mesh = torus(n_major, n_minor)
    v, f = mesh.vertices, mesh.faces
    u = (np.arctan2(v[:, 1], v[:, 0]) / (2 * np.pi)) % 1.0
    rho = np.hypot(v[:, 0], v[:, 1])
    w = (np.arctan2(v[:, 2], rho - 1.0) / (2 * np.pi)) % 1.0
    uv = np.stack([u, w], axis=-1)[f]
    for k in range(2):  # faces across the seam: continue past 1 instead of wrapping back to 0
        span = uv[..., k].max(axis=1) - uv[..., k].min(axis=1)
        uv[..., k] = np.where(
            (span[:, None] > 0.5) & (uv[..., k] < 0.5), uv[..., k] + 1.0, uv[..., k]
        )
    y, x = np.mgrid[0:512, 0:512] / 512.0
    tex = np.stack(
        [
            0.5 + 0.5 * np.sin(40 * x),
            ((x * 16).astype(int) + (y * 8).astype(int)) % 2 * 0.8 + 0.1,
            0.5 + 0.5 * np.cos(25 * y),
        ],
        axis=-1,
    ).astype(np.float32)
    return v, f, uv, tex


def wall_cpu(fn, *args, repeats: int = 3):
    """Median wall and CPU seconds of ``repeats`` calls after a warm-up call."""
    fn(*args)
    walls, cpus = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn(*args)
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return float(np.median(walls)), float(np.median(cpus))


def embree_visibility(v, f, cam, s):
    """One ray per sample through Embree; returns the face id buffer (``-1`` background)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene=scene, vertices=v[f].astype(np.float32))
    W, H = cam.width * s, cam.height * s
    r, u, w = cam.frame()
    cols, rows = np.meshgrid(np.arange(W), np.arange(H))
    x = ((cols.ravel() + 0.5) / W * 2 - 1) * cam.half_height * W / H
    y = (1 - (rows.ravel() + 0.5) / H * 2) * cam.half_height
    origins = (cam.eye + x[:, None] * r + y[:, None] * u).astype(np.float32)
    dirs = np.broadcast_to(w, origins.shape).astype(np.float32)
    out = scene.run(origins, dirs, output=1)
    return out["primID"].reshape(H, W)


def old_matplotlib(v, f, colors, size=(512, 512), view=(25.0, -60.0)):
    """The removed renderer, kept here to time it: flat shading, painter's algorithm on Agg."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    e, a = np.radians(view[0] + 30), np.radians(view[1] - 35)
    light = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    c = np.clip(colors * (0.35 + 0.65 * np.abs(n @ light))[:, None], 0, 1)
    fig = Figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1), projection="3d")
    ax.set_proj_type("ortho")
    ax.view_init(elev=view[0], azim=view[1])
    ax.set_axis_off()
    center = 0.5 * (v.min(0) + v.max(0))
    rad = float(np.linalg.norm(v - center, axis=1).max())
    for i, setter in enumerate((ax.set_xlim, ax.set_ylim, ax.set_zlim)):
        setter(center[i] - rad, center[i] + rad)
    ax.set_box_aspect((1, 1, 1), zoom=1.55)
    ax.add_collection3d(
        Poly3DCollection(v[f], facecolors=c, edgecolors=c, linewidths=0.3, zsort="average")
    )
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def shade_inputs(v, f, uv, tex, cam, s):
    """The arrays :func:`render` hands :func:`shade` (float32), built with the public API."""
    vis = rasterize(v, f, cam, supersample=s)
    lod = jnp.asarray(texture_lod(v, f, uv, tex.shape[:2], cam, supersample=s), jnp.float32)
    light = Lighting(*(jnp.asarray(x, jnp.float32) for x in camera_lighting(cam)))
    normals = jnp.asarray(vertex_normals(v, f)[f], jnp.float32)
    args = (jnp.asarray(vis.face), jnp.asarray(vis.bary, jnp.float32), normals, light)
    kw = dict(uv=jnp.asarray(uv, jnp.float32), texture=jnp.asarray(tex), lod=lod, supersample=s)
    return vis, args, kw


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer sizes, no ceilings")
    ap.add_argument("--faces", type=int, default=100_000)
    ap.add_argument(
        "--old-faces",
        type=int,
        default=None,
        help="time the old matplotlib path on a torus of this many faces (default: the same mesh)",
    )
    ap.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes (5K faces, 128-256 px): checks the script runs",
    )
    ap.add_argument(
        "--out", type=pathlib.Path, default=None, help="results folder (default benchmarks/results)"
    )
    args = ap.parse_args()
    if args.smoke:
        args.quick, args.faces = True, 5_000
    report = Report("render", ceilings=not args.quick)
    report.config = {
        "faces": args.faces,
        "quick": args.quick,
        "loadavg_start": os.getloadavg(),
        "supersample": 2,
        "size": [512, 512],
    }
    s = 2

    v, f, uv, tex = textured_torus(args.faces)
    cam = orbit_cameras((v, f), azimuths=[-60.0], elevations=(25.0,), size=(512, 512))[0]
    label = Size(f"{size_label(len(f))} faces, 512² (1024² samples)", faces=len(f))
    wall, cpu = wall_cpu(lambda: rasterize(v, f, cam, supersample=s))
    report.add(name="visibility (NumPy z-buffer)", size=label, seconds=wall, cpu_s=cpu)
    vis_wall = wall
    try:
        import embreex  # noqa: F401

        wall, cpu = wall_cpu(lambda: embree_visibility(v, f, cam, s))
        ours = rasterize(v, f, cam, supersample=s).face
        agree = float((ours == embree_visibility(v, f, cam, s)).mean())
        report.add(
            name="visibility (Embree rays)",
            size=label,
            seconds=wall,
            cpu_s=cpu,
            agree_with_zbuffer=agree,
        )
    except ImportError:
        report.notes.append("Embree row left out: `embreex` is not importable in this environment.")

    vis, sargs, skw = shade_inputs(v, f, uv, tex, cam, s)
    fn = lambda *a: shade(*a, **skw)  # noqa: E731
    t = time_jax(fn, *sargs, repeats=3, min_time=0.0)
    _, shade_cpu = wall_cpu(lambda: jax.block_until_ready(fn(*sargs)))
    report.add(
        name="shading (JAX, jit)",
        size=label,
        seconds=t.run_s,
        cpu_s=shade_cpu,
        compile_s=t.compile_s,
    )
    shade_wall = t.run_s
    wall, cpu = wall_cpu(lambda: render(Mesh(v, f, uv=uv, texture=tex), cam))
    report.add(
        name="total render()",
        size=label,
        seconds=wall,
        cpu_s=cpu,
        sum_of_parts=vis_wall + shade_wall,
    )

    old_faces = len(f) if args.old_faces is None else args.old_faces
    ov, of, ouv, otex = textured_torus(old_faces) if old_faces != len(f) else (v, f, uv, tex)
    colors = np.full((len(of), 3), 0.7)
    t0, c0 = time.perf_counter(), time.process_time()
    old_matplotlib(ov, of, colors)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    row = dict(
        name="old matplotlib path",
        size=Size(f"{size_label(len(of))} faces, 512²", faces=len(of)),
        seconds=wall,
        cpu_s=cpu,
    )
    if len(of) != len(f):
        row["projected_100K_s"] = wall * len(f) / len(of)
        report.notes.append(
            f"old matplotlib path timed on {len(of)} faces; `projected_100K_s` is a linear "
            "projection to the benchmark mesh, not a measurement."
        )
    new_wall, _ = wall_cpu(lambda: render((ov, of), cam.replace(), face_colors=colors), repeats=1)
    row["new_render_same_mesh_s"] = new_wall
    report.add(**row)

    face_counts = [5_000, 20_000, 100_000] if args.quick else [5_000, 20_000, 100_000, 400_000]
    if args.smoke:
        face_counts = [2_000, 5_000]
    for nf in face_counts:
        mv, mf, muv, mtex = textured_torus(nf)
        mcam = orbit_cameras((mv, mf), azimuths=[-60.0], elevations=(25.0,), size=(512, 512))[0]
        vwall, vcpu = wall_cpu(lambda: rasterize(mv, mf, mcam, supersample=s), repeats=2)  # noqa: B023
        _, a2, kw2 = shade_inputs(mv, mf, muv, mtex, mcam, s)
        t2 = time_jax(lambda *a: shade(*a, **kw2), *a2, repeats=2, min_time=0.0)  # noqa: B023
        report.add(
            name="scaling: faces",
            size=Size(f"{size_label(len(mf))} faces, 512²", faces=len(mf)),
            seconds=vwall + t2.run_s,
            visibility_s=vwall,
            visibility_cpu_s=vcpu,
            shading_s=t2.run_s,
        )
    sizes = [256, 512, 1024] if args.quick else [256, 512, 1024, 2048]
    if args.smoke:
        sizes = [128, 256]
    for px in sizes:
        pcam = cam.replace(size=(px, px))
        vwall, vcpu = wall_cpu(lambda: rasterize(v, f, pcam, supersample=s), repeats=2)  # noqa: B023
        _, a2, kw2 = shade_inputs(v, f, uv, tex, pcam, s)
        t2 = time_jax(lambda *a: shade(*a, **kw2), *a2, repeats=2, min_time=0.0)  # noqa: B023
        report.add(
            name="scaling: pixels",
            size=Size(f"{size_label(len(f))} faces, {px}²", pixels=px * px),
            seconds=vwall + t2.run_s,
            visibility_s=vwall,
            visibility_cpu_s=vcpu,
            shading_s=t2.run_s,
        )
    report.config["loadavg_end"] = os.getloadavg()
    report.config["python"] = sys.version.split()[0]
    report.notes.append(
        "Wall times on a shared machine include waiting for a core (see loadavg in the "
        "JSON config); `cpu_s` is this process's CPU time over the same call."
    )
    report.notes.append(f"jax devices: {jax.devices()}")
    report.write(args.out)


if __name__ == "__main__":
    main()

"""``jmeshtex demo``: run the host geometry and every method on embedded data; write PNGs and a report.

The demo is a list of :class:`Step` s. Each step reads and fills a shared dictionary (meshes,
fields), returns a one-line summary, and is timed. Adding a step is one line in :data:`STEPS` (plus
its function): the geometry steps fill fields that the render step draws, the equivariance step
runs a selection of ``jmeshtex verify``, and each method adds a stage that writes its own PNGs into
a subfolder.

From Python::

    from jmeshtex.cli._demo import run_demo
    out = run_demo("my-demo", quick=True)      # -> the folder holding demo.png and report.txt
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import pathlib
import platform
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from .._errors import InputError

DEFAULT_OUT = "jmeshtex-demo"
PANEL_SIZE = (420, 380)


@dataclasses.dataclass(frozen=True)
class Step:
    """One demo step: ``run(ctx) -> summary`` (a one-line result for the report)."""

    name: str
    run: Callable[[dict[str, Any]], str]


def _meshes(ctx: dict[str, Any]) -> str:
    from .. import data

    quick = ctx["quick"]
    ctx["torus"] = data.torus(32, 16) if quick else data.torus(72, 36)
    gv, gf = data.grid(6) if quick else data.grid(12)
    gv[:, 2] = (
        0.12 * np.sin(2.0 * np.pi * gv[:, 0]) * np.cos(np.pi * gv[:, 1])
    )  # a gentle bend to see
    ctx["grid"] = data.grid(6).replace(vertices=gv, faces=gf)
    return ", ".join(
        f"{name} {ctx[name].num_vertices} V / {ctx[name].num_faces} F" for name in ("torus", "grid")
    )


def _subdivide(ctx: dict[str, Any]) -> str:
    from ..geometry import subdivide_midpoint

    v, f = ctx["grid"]
    fine = subdivide_midpoint(v, f)
    ctx["grid"] = ctx["grid"].replace(vertices=fine.vertices, faces=fine.faces)
    return f"grid 1→4: {len(v)} → {len(fine.vertices)} V, {len(f)} → {len(fine.faces)} F"


def _boundary(ctx: dict[str, Any]) -> str:
    from ..geometry import boundary_loops

    v, f = ctx["grid"]
    loops = boundary_loops(f, len(v))
    ctx["boundary"] = np.concatenate(
        [np.stack([loop, np.roll(loop, -1)], axis=1) for loop in loops]
    )
    return f"grid: {len(loops)} boundary loop(s), {len(ctx['boundary'])} edges; torus: {len(boundary_loops(ctx['torus'].faces))}"


def _validate(ctx: dict[str, Any]) -> str:
    from ..geometry import mesh_statistics, validate_mesh

    parts = []
    for name in ("torus", "grid"):
        validate_mesh(*ctx[name])
        st = mesh_statistics(ctx[name])
        parts.append(
            f"{name}: valid, χ = {st.euler_characteristic}, genus {st.genus}, {st.boundary_loops} boundary loop(s)"
        )
    return "; ".join(parts)


def _one_ring(ctx: dict[str, Any]) -> str:
    from ..geometry import one_ring_neighborhood

    v, f = ctx["torus"]
    nb = one_ring_neighborhood(v, f)
    degree = nb.mask.sum(axis=1)
    return f"torus: K = {nb.index.shape[1]} slots, degree {degree.min()}–{degree.max()}, area {nb.area.sum():.4g}"


def _frames(ctx: dict[str, Any]) -> str:
    from ..geometry import tangent_frames

    v, f = ctx["torus"]
    frames = tangent_frames(v, f)
    ctx["x_axes"], ctx["x_axes_label"] = frames.x, "tangent frames: x-axes"
    return f"torus: {len(frames.x)} orthonormal frames"


def _sample(ctx: dict[str, Any]) -> str:
    import jax

    from ..geometry import sample_surface

    v, f = ctx["torus"]
    samples = sample_surface(v, f, 10 * len(v), key=jax.random.key(0))
    return f"torus: {len(samples.point)} area-uniform points"


def _knn(ctx: dict[str, Any]) -> str:
    from ..geometry import geodesic_knn_neighborhood

    v, f = ctx["torus"]
    nb = geodesic_knn_neighborhood(v, f, k=8)
    radius = np.abs(nb.log[:, -1])
    return f"torus: [{nb.index.shape[0]}, {nb.index.shape[1]}] slots, geodesic radius of slot 8: {radius.min():.3g}–{radius.max():.3g} mean edges"


def _hierarchy(ctx: dict[str, Any]) -> str:
    from ..geometry import mesh_hierarchy

    v, f = ctx["torus"]
    h = mesh_hierarchy(v, f)
    return f"torus: {h.num_levels} levels, vertices " + " → ".join(str(len(x)) for x in h.vertices)


def _hks(ctx: dict[str, Any]) -> str:
    from ..geometry import heat_kernel_signature, hks_times, laplacian_eigenpairs

    v, f = ctx["torus"]
    ev = laplacian_eigenpairs(v, f, k=30 if ctx["quick"] else 100)
    times = hks_times(ev.values)
    hks = heat_kernel_signature(v, f, times=times, eigenpairs=ev)
    column = 2  # a short time: the signature follows curvature (outer rim vs inner hole)
    ctx["hks"], ctx["hks_time"] = hks[:, column], times[column]
    return f"torus: {len(ev.values)} eigenpairs, λ_1 = {ev.values[1]:.4g}, HKS [{len(v)}, {len(times)}]"


def _tangent_axes(ctx: dict[str, Any]) -> str:
    from ..geometry import face_frame_to_world, trace_from_vertices

    v, f = ctx["torus"]
    n = len(v)
    # exp_p(0 · e^{i0}) keeps the start wedge face and the gauge's x direction in its frame
    start = trace_from_vertices(v, f, np.arange(n), np.ones(n, complex), 0.0)
    axes = face_frame_to_world(v, f, start.face, start.direction)
    if "x_axes" not in ctx:
        ctx["x_axes"], ctx["x_axes_label"] = axes, "gauge x-axes (via the tracer)"
        return f"torus: {n} unit x-axes of the intrinsic vertex gauges"
    # the frames project the same reference edge onto the vertex tangent plane: a small angle apart
    cos = np.sum(axes * ctx["x_axes"], axis=1) / np.linalg.norm(axes, axis=1)
    return f"torus: tracer gauge vs tangent_frames x-axes, max angle {np.degrees(np.arccos(np.clip(cos, -1, 1))).max():.2f}°"


def _trace(ctx: dict[str, Any]) -> str:
    from ..geometry import mean_edge_length, trace_from_vertices, tracer_geometry

    v, f = ctx["torus"]
    n_dirs = 8
    vertex = np.repeat(np.arange(len(v)), n_dirs)
    direction = np.exp(2j * np.pi * np.tile(np.arange(n_dirs), len(v)) / n_dirs)
    geometry = tracer_geometry(v, f)
    t0 = time.perf_counter()
    result = trace_from_vertices(
        v, f, vertex, direction, 3.0 * mean_edge_length(v, f), geometry=geometry
    )
    seconds = time.perf_counter() - t0
    return f"torus: {len(vertex)} geodesics of 3 mean edges, {len(vertex) / max(seconds, 1e-9):,.0f} traces/s, {int(result.stopped.sum())} stopped"


def _render(ctx: dict[str, Any]) -> str:
    from ..render import figure, render_mesh

    tv, tf = ctx["torus"]
    gv, gf = ctx["grid"]
    view = (35.0, -60.0)
    panels, titles = (
        [render_mesh((tv, tf), view=view, size=PANEL_SIZE)],
        [f"torus ({len(tv)} vertices)"],
    )
    if "hks" in ctx:
        panels.append(
            render_mesh(
                (tv, tf), scalars=np.log(ctx["hks"]), cmap="magma", view=view, size=PANEL_SIZE
            )
        )
        titles.append(f"log HKS, t = {ctx['hks_time']:.3g}")
    if "x_axes" in ctx:
        panels.append(
            render_mesh(
                (tv, tf), vectors=ctx["x_axes"], max_arrows=600, view=(55.0, -60.0), size=PANEL_SIZE
            )
        )
        titles.append(ctx["x_axes_label"])
    if "boundary" in ctx:
        panels.append(
            render_mesh((gv, gf), edges=ctx["boundary"], view=(50.0, -60.0), size=PANEL_SIZE)
        )
        titles.append(f"grid ({len(gv)} vertices) and its boundary")
    path = ctx["out"] / "demo.png"
    figure(list(zip(titles, panels, strict=True)), columns=min(len(panels), 2), path=path)
    return f"{len(panels)} panels → {path.name}"


#: the full demo's equivariance selection: one check per method and the core operators, each under
#: the transform that tests it most directly (``jmeshtex verify`` runs the whole registry)
VERIFY_SELECTION: tuple[tuple[str, str], ...] = (
    ("geometry.one_ring.log", "fold"),
    ("ops.field_conv", "gauge"),
    ("ops.field_conv", "rotate_corners"),
    ("negative.complex_bias", "gauge"),  # a known-bad operator: the check must flag it
    ("dgts.discriminator", "rotate_corners"),
    ("fl.decoder", "gauge"),
    ("fldm.sampler", "gauge"),
    ("meshmatch.fan_descriptor", "gauge"),
    ("surfacecnn.first_layer", "gauge"),
)
QUICK_VERIFY_SELECTION: tuple[tuple[str, str], ...] = (
    ("ops.field_conv", "gauge"),
    ("negative.complex_bias", "gauge"),
)


def _verify(ctx: dict[str, Any]) -> str:
    """A selection of ``jmeshtex verify`` in float64: :data:`VERIFY_SELECTION` (quick:
    :data:`QUICK_VERIFY_SELECTION`), one check per method and the core operators."""
    import jax
    import jax.numpy as jnp

    from .. import testing
    from ..io import atomic_write

    selection = QUICK_VERIFY_SELECTION if ctx["quick"] else VERIFY_SELECTION
    hook = ctx.get("progress")
    was_x64 = jax.config.jax_enable_x64
    jax.config.update(
        "jax_enable_x64", True
    )  # for this step only: the method stages run in float32
    try:
        testing.load_entries()
        results = []
        for i, (name, transform) in enumerate(selection):
            if hook is not None:
                hook(f"{i + 1}/{len(selection)} {name} × {transform}")
            results += testing.run_registry([name], dtypes=(jnp.float64,), transforms=[transform])
    finally:
        jax.config.update("jax_enable_x64", was_x64)
    table = testing.format_table(results)
    atomic_write(ctx["out"] / "verify.txt", table + "\n")
    failed = sum(r.passed is False for r in results)
    if failed:
        raise RuntimeError(f"equivariance check failed:\n{table}")
    transforms = sorted({t for _, t in selection})
    return f"{len(results)} checks ({', '.join(transforms)}), {failed} failed → verify.txt"


def method_stage(folder: str) -> Callable[[dict[str, Any]], str]:
    """A demo step that runs ``jmeshtex.cli._stages.<folder>.demo_stage(out / folder, quick=...)``.

    ``folder`` names a method (``"dgts"``): its stage module in ``jmeshtex/cli/_stages/`` has a
    ``demo_stage(out_dir, *, quick, progress) -> dict`` that trains/runs a tiny
    configuration on the embedded data and writes its PNGs into ``out_dir``; the dict's
    ``"summary"`` (or else its scalar entries) becomes the report line. ``progress`` is the demo's
    hook (status lines shown on its bar; None with ``--no-progress``).
    """

    def run(ctx: dict[str, Any]) -> str:
        from . import _stages

        stage = getattr(_stages, folder).demo_stage
        result = stage(ctx["out"] / folder, quick=ctx["quick"], progress=ctx.get("progress"))
        if "summary" in result:
            text = str(result["summary"])
        else:
            text = ", ".join(
                f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                for k, v in result.items()
                if isinstance(v, (int, float, str))
            )
        return f"{text} → {folder}/"

    return run


# The demo, in order.
STEPS: list[Step] = [
    Step("procedural meshes", _meshes),
    Step("validate_mesh / mesh_statistics", _validate),
    Step("subdivide_midpoint", _subdivide),
    Step("boundary_loops", _boundary),
    Step("one_ring_neighborhood (log maps + transport)", _one_ring),
    Step("tangent_frames", _frames),
    Step("geodesic_knn_neighborhood (k = 8)", _knn),
    Step("mesh_hierarchy", _hierarchy),
    Step("heat_kernel_signature", _hks),
    Step("trace_from_vertices (gauge x-axes)", _tangent_axes),
    Step("trace_from_vertices (throughput)", _trace),
    Step("sample_surface", _sample),
    Step("render", _render),
    Step("equivariance (jmeshtex verify, selection)", _verify),
    Step("MeshMatch", method_stage("meshmatch")),
    Step("DGTS (shipped knobs model, transfer)", method_stage("dgts")),
    Step("Field Latents (FL-VAE encode/decode)", method_stage("fl")),
    Step(
        "Field Latent Diffusion (shipped Spot model: sample, inpaint, transfer)",
        method_stage("fldm"),
    ),
    Step("surface-aware texture synthesis (VGG-16 on texels)", method_stage("surfacecnn")),
]


def output_folder(out: str | os.PathLike, *, force: bool = False) -> pathlib.Path:
    """The folder to write into: ``out`` if it is new, empty, or ``force``; else a fresh ``out/run-N``.

    Example:
      >>> import tempfile
      >>> with tempfile.TemporaryDirectory() as d:
      ...     first = output_folder(d)
      ...     _ = (first / "report.txt").write_text("x")
      ...     output_folder(d).name, output_folder(d, force=True) == first
      ('run-1', True)
    """
    out = pathlib.Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder: pick another path")
    if not out.exists() or force or not any(out.iterdir()):
        return out
    n = 1
    while (out / f"run-{n}").exists():
        n += 1
    return out / f"run-{n}"


def run_demo(
    out: str | os.PathLike = DEFAULT_OUT,
    *,
    quick: bool = False,
    force: bool = False,
    progress: bool = True,
) -> pathlib.Path:
    """Run every :data:`STEPS` entry, write ``demo.png`` and ``report.txt``; return the folder.

    The folder is claimed like every command's ``--out`` (:mod:`jmeshtex.cli._output`: a lock, the
    owner manifest; with ``force`` files already there are kept and never replaced)."""
    from ._output import claim_output, release

    folder = output_folder(out, force=force)
    claim_output(folder, command="demo", overwrite=force)  # lock, manifest, foreign files kept
    try:
        return _run_steps(folder, quick=quick, progress=progress)
    finally:
        release(folder)


def _run_steps(folder: pathlib.Path, *, quick: bool, progress: bool) -> pathlib.Path:
    from tqdm import tqdm

    from .. import __version__

    ctx: dict[str, Any] = {"quick": quick, "out": folder}
    t_start, c_start = time.perf_counter(), time.process_time()
    from .. import geometry, render  # noqa: F401  (imports are timed apart from the steps)

    rows: list[tuple[str, float, float, str]] = [
        (
            "imports",
            time.perf_counter() - t_start,
            time.process_time() - c_start,
            "jmeshtex.geometry, jmeshtex.render",
        )
    ]
    bar = tqdm(
        STEPS, desc="jmeshtex demo", unit="step", file=sys.stderr, disable=not progress, leave=False
    )
    for step in bar:
        label = step.name[:40]
        bar.set_postfix_str(label)
        if progress:  # status lines from inside the step: the bar's postfix (and clock) move
            ctx["progress"] = lambda text, label=label: bar.set_postfix_str(f"{label}: {text}"[:90])
        t0, c0 = time.perf_counter(), time.process_time()
        summary = step.run(ctx)
        rows.append((step.name, time.perf_counter() - t0, time.process_time() - c0, summary))
    total, cpu_total = time.perf_counter() - t_start, time.process_time() - c_start

    width = max(len(name) for name, _, _, _ in rows)
    lines = [
        f"jmeshtex {__version__} demo ({'quick' if quick else 'full'}), {time.strftime('%Y-%m-%d %H:%M:%S')}",
        f"python {platform.python_version()}, {platform.platform()}, {os.cpu_count()} CPUs",
        f"output: {folder.resolve()}",
        "",
        *(
            f"{name}: {ctx[name].num_vertices} vertices, {ctx[name].num_faces} faces"
            for name in ("torus", "grid")
            if name in ctx
        ),
        "",
        f"{'step':<{width}}  {'seconds':>8}  {'cpu s':>8}  result",
        *(f"{name:<{width}}  {s:8.3f}  {c:8.3f}  {summary}" for name, s, c, summary in rows),
        "",
        f"total: {total:.2f} s (process CPU time {cpu_total:.2f} s)",
    ]
    from ..io import atomic_write

    atomic_write(folder / "report.txt", "\n".join(lines) + "\n")
    return folder


def _main(args: argparse.Namespace) -> int:
    folder = run_demo(args.out, quick=args.quick, force=args.force, progress=not args.no_progress)
    print(f"jmeshtex demo: wrote {folder / 'demo.png'} and {folder / 'report.txt'}")
    print((folder / "report.txt").read_text(encoding="utf-8"), end="")
    return 0


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "demo",
        help="run the geometry and every method on embedded data; write PNGs and report.txt",
        description="Run the host geometry (subdivision, boundaries, HKS, tracer, ...) on a procedural "
        "torus and grid, an equivariance selection, and a tiny run of every method (MeshMatch, DGTS, "
        "surface CNN, FL-VAE, FLDM) on procedural meshes and scikit-image images; write a picture "
        "(demo.png), one folder of PNGs per method and a timing report (report.txt). "
        "An existing non-empty --out folder is never overwritten: the demo writes into a fresh "
        "run-N subfolder unless --force is given.",
    )
    parser.add_argument(
        "--out", default=DEFAULT_OUT, help=f"output folder (default: ./{DEFAULT_OUT})"
    )
    parser.add_argument(
        "--quick", action="store_true", help="small meshes and spectra (a few seconds)"
    )
    parser.add_argument(
        "--force", action="store_true", help="write into --out even if it is not empty"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(func=_main)

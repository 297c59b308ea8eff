"""``jmeshtex dgts prepare|train|transfer|interpolate``: a thin layer over :mod:`jmeshtex.dgts`.

- ``prepare --reference R --template T --levels L --out DIR``: multi-scale training meshes
  (``DIR/training.npz``, ``DIR/level_XX.obj``, ``DIR/reference.obj``, ``DIR/levels.png``).
- ``train DIR``: trains the hierarchy into ``DIR/model`` (resumes after the last complete level),
  then writes a sample generated from the template (``DIR/model/sample.obj`` / ``.png``).
- ``transfer --model DIR --target M --start-level l --samples n --out OUT``: ``OUT/sample_XX.obj``
  and ``OUT/transfer.png`` (coloured by displacement along the normal).
- ``interpolate --model DIR --target M --frames n --out OUT``: ``OUT/frame_XX.obj`` and
  ``OUT/interpolate.png``.

Meshes are files (``.obj``/``.ply``/``.off``/``.glb``) or procedural names: ``icosahedron``,
``icosphere:N``, ``torus``, ``torus:NMAJOR:NMINOR``, ``bumpy-sphere``, ``grid:N``.

Compiled programs are kept in JAX's persistent compilation cache, so a second ``train`` or
``transfer`` with the same sizes skips most compilation: ``$JMESHTEX_JAX_CACHE`` (a folder; ``0`` or
empty turns the cache off), by default ``$XDG_CACHE_HOME/jmeshtex/jax`` (``~/.cache/jmeshtex/jax``).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib

from .._errors import InputError


def compilation_cache() -> pathlib.Path | None:
    """Turn on JAX's persistent compilation cache in the folder the module docstring names.

    Returns:
      The folder, or None when ``JMESHTEX_JAX_CACHE`` is ``0`` or empty.
    """
    import jax

    env = os.environ.get("JMESHTEX_JAX_CACHE")
    if env is not None and env.strip() in ("", "0"):
        return None
    if env is None:
        base = os.environ.get("XDG_CACHE_HOME") or pathlib.Path.home() / ".cache"
        folder = pathlib.Path(base) / "jmeshtex" / "jax"
    else:
        folder = pathlib.Path(env)
    folder.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
    return folder


def _cached(func):
    """A subcommand handler that enables the compilation cache first."""

    def run(args):
        compilation_cache()
        return func(args)

    return run


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("dgts", help="DGTS: learn a geometric texture from one mesh, transfer it to any mesh",
                       description="Deep Geometric Texture Synthesis (Hertz et al. 2020) on the CPU.")
    dsub = p.add_subparsers(dest="dgts_command", metavar="STEP")

    q = dsub.add_parser("prepare", help="fit a template to the reference at every level (training meshes)")
    q.add_argument("--reference", required=True, help="reference mesh file or procedural name")
    q.add_argument("--template", default="icosphere:1", help="template mesh file or name (default icosphere:1)")
    q.add_argument("--levels", type=int, default=4, help="number of levels (default 4)")
    q.add_argument("--iterations", type=int, default=None, help="Adam steps per level (default: PrepareConfig)")
    q.add_argument("--samples", type=int, default=None, help="surface samples at level 0")
    q.add_argument("--out", required=True, type=pathlib.Path, help="output folder")
    q.add_argument("--no-progress", action="store_true", help="no progress bar")
    q.set_defaults(func=_cached(_prepare))

    t = dsub.add_parser("train", help="train the generator hierarchy (WGAN-GP), resumable")
    t.add_argument("dir", type=pathlib.Path, metavar="DIR", help="folder written by `dgts prepare`")
    t.add_argument("--iterations", type=int, default=None, help="iterations per level (default 2000)")
    t.add_argument("--layers", type=int, default=None, help="layers per network (default 7)")
    t.add_argument("--features", type=int, nargs=3, default=None, metavar=("START", "MIN", "MAX"),
                   help="width schedule (default 32 32 128)")
    t.add_argument("--levels", type=int, default=None, help="train only the first N levels")
    t.add_argument("--shared-levels", type=int, default=0, metavar="N",
                   help="pad levels 0..N-1 to one size so equal-width levels share one compiled step (default 0)")
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--no-progress", action="store_true", help="no progress bar")
    t.set_defaults(func=_cached(_train))

    for name, helptext in (("transfer", "synthesise the texture on a target mesh"),
                           ("interpolate", "animate between two noises on a target mesh")):
        r = dsub.add_parser(name, help=helptext)
        r.add_argument("--model", required=True, type=pathlib.Path, help="folder of `dgts train` (or its model/)")
        r.add_argument("--target", required=True, help="target mesh file or procedural name")
        r.add_argument("--start-level", type=int, default=0, help="first generator level to run (default 0)")
        if name == "transfer":
            r.add_argument("--samples", type=int, default=1, help="number of samples (default 1)")
        else:
            r.add_argument("--frames", type=int, default=8, help="frames including both ends (default 8)")
        r.add_argument("--seed", type=int, default=0)
        r.add_argument("--out", required=True, type=pathlib.Path, help="output folder")
        r.set_defaults(func=_cached(_transfer if name == "transfer" else _interpolate))
    p.set_defaults(func=lambda args: (p.print_help(), 1)[1])


def load_mesh_arg(spec: str):
    """A mesh from a file path or a procedural name (see the module docstring)."""
    from .. import data
    from ..data import bumpy_sphere

    parts = spec.split(":")
    try:
        nums = [int(x) for x in parts[1:]]
    except ValueError as err:
        raise InputError(f"bad procedural mesh {spec!r}: numbers expected after ':'") from err
    named = {
        "icosahedron": lambda: data.icosahedron(),
        "icosphere": lambda: data.icosphere(*(nums or [1])),
        "torus": lambda: data.torus(*(nums or [24, 12])),
        "bumpy-sphere": lambda: bumpy_sphere(subdivisions=(nums or [4])[0]),
        "grid": lambda: data.grid(*(nums or [8])),
    }
    if parts[0] in named and not pathlib.Path(spec).exists():
        return named[parts[0]]()
    from ..geometry import prepare_mesh
    from ..io import load_mesh

    path = pathlib.Path(spec)
    if not path.exists():
        raise InputError(f"{spec!r} is neither a mesh file nor one of the procedural names {sorted(named)}")
    mesh, _ = prepare_mesh(load_mesh(path))
    return mesh.vertices, mesh.faces


def _bar(disable: bool):
    from tqdm.auto import tqdm

    state = {}

    def progress(stage, done, total):
        bar = state.get(stage)
        if bar is None:
            bar = state[stage] = tqdm(total=total, desc=f"prepare {stage}", unit="step", disable=disable)
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return progress


def _prepare(args) -> int:
    from ..dgts import PrepareConfig, save_training_meshes, training_meshes
    from ..io import atomic_write, save_mesh
    from ..render import render_grid, render_mesh

    changes = {"num_levels": args.levels}
    if args.iterations is not None:
        changes["iterations"] = args.iterations
    if args.samples is not None:
        changes["samples_per_level"] = args.samples
    config = PrepareConfig(**changes)
    ref = load_mesh_arg(args.reference)
    tmpl = load_mesh_arg(args.template)
    tm = training_meshes(ref, tmpl, config=config, progress=_bar(args.no_progress))
    out = args.out
    save_training_meshes(out / "training.npz", tm)
    atomic_write(out / "prepare.json", json.dumps(config.to_dict(), indent=2).encode())
    save_mesh(ref, out / "reference.obj")
    images = [render_mesh(*ref, size=(300, 300))]
    for level, (v, f) in enumerate(zip(tm.vertices, tm.faces, strict=True)):
        save_mesh((v, f), out / f"level_{level:02d}.obj")
        images.append(render_mesh(v, f, size=(300, 300)))
    render_grid(images, out / "levels.png", titles=["reference"] + [f"level {i}" for i in range(tm.num_levels)])
    print(f"wrote {out / 'training.npz'} ({tm.num_levels} levels, {[len(f) for f in tm.faces]} faces)")
    return 0


def _train(args) -> int:
    import jax
    import numpy as np

    from ..dgts import TrainConfig, generate, hierarchy_geometry, load_training_meshes, train
    from ..io import save_mesh
    from ..render import render_mesh

    tm = load_training_meshes(args.dir / "training.npz")
    changes = {"seed": args.seed, "shared_levels": args.shared_levels}
    if args.iterations is not None:
        changes["iterations"] = args.iterations
    if args.layers is not None:
        changes["num_layers"] = args.layers
    if args.features is not None:
        changes.update(zip(("start_features", "min_features", "max_features"), args.features, strict=True))
    config = TrainConfig(**changes)
    out = args.dir / "model"
    model, reports = train(tm, config, out_dir=out, num_levels=args.levels, progress=not args.no_progress)
    for r in reports:
        print(f"level {r.level}: {r.faces} faces, {r.iterations} it, compile {r.compile_seconds:.1f} s, "
              f"{1000 * r.seconds_per_iteration:.1f} ms/it")
    geos, faces = hierarchy_geometry(tm.faces[0], len(tm.template), model.num_levels)
    sizes = [len(v) for v in tm.vertices[: model.num_levels]]
    keys = jax.random.split(jax.random.key(args.seed), len(sizes))
    zs = [config.noise_amplitude * jax.random.normal(k, (s, 3)).astype("float32") for k, s in zip(keys, sizes, strict=True)]
    v = np.asarray(generate(model.generators, jax.numpy.asarray(tm.template, "float32"), geos, zs,
                            scale=config.scale_factor, negative_slope=config.negative_slope, eps=config.eps))
    save_mesh((v.astype(float), faces[-1]), out / "sample.obj")
    render_mesh(v, faces[-1], out / "sample.png", size=(400, 400), title="sample from the template")
    print(f"wrote {out} ({model.num_levels} levels)")
    return 0


def _model_dir(path: pathlib.Path) -> pathlib.Path:
    return path / "model" if (path / "model" / "state.json").exists() else path


def _write_results(res, out: pathlib.Path, stem: str, title: str) -> None:
    import numpy as np

    from ..io import save_mesh
    from ..render import render_grid, render_mesh

    lim = float(np.abs(res.heights).max()) or 1.0
    out.mkdir(parents=True, exist_ok=True)
    images = []
    for i, (v, h) in enumerate(zip(res.vertices, res.heights, strict=True)):
        save_mesh((v, res.faces), out / f"{stem}_{i:02d}.obj")
        images.append(render_mesh(v, res.faces, scalars=h, cmap="coolwarm", clim=(-lim, lim), size=(300, 300)))
    render_grid(images, out / f"{title}.png", titles=[f"{stem} {i}" for i in range(len(images))])
    print(f"wrote {len(images)} meshes and {out / (title + '.png')}")


def _transfer(args) -> int:
    import jax

    from ..dgts import load_model, transfer

    model = load_model(_model_dir(args.model))
    v, f = load_mesh_arg(args.target)
    res = transfer(model, v, f, start_level=args.start_level, num_samples=args.samples, key=jax.random.key(args.seed))
    _write_results(res, args.out, "sample", "transfer")
    return 0


def _interpolate(args) -> int:
    import jax

    from ..dgts import interpolate, load_model

    model = load_model(_model_dir(args.model))
    v, f = load_mesh_arg(args.target)
    res = interpolate(model, v, f, start_level=args.start_level, num_frames=args.frames, key=jax.random.key(args.seed))
    _write_results(res, args.out, "frame", "interpolate")
    return 0

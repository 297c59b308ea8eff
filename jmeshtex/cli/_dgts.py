"""``jmeshtex dgts prepare|train|transfer|interpolate``: a thin layer over :mod:`jmeshtex.dgts`.

- ``prepare --reference R --template T --levels L --out DIR``: multi-scale training meshes
  (``DIR/training.npz``, ``DIR/level_XX.obj``, ``DIR/reference.obj``, ``DIR/levels.png``); run it
  again after a stop to resume after the last finished level (``DIR/training.levels/``).
- ``train DIR``: trains the hierarchy with checkpoints in ``DIR/checkpoints`` (run it again to
  resume), saves the model into ``DIR/model`` and writes a sample generated from the template
  (``DIR/sample.obj`` / ``.png``).
- ``transfer --model DIR --target M [--start-level l | --max-faces N] [--stop-level s] --samples n
  --out OUT``: ``OUT/sample_XX.obj`` and ``OUT/transfer.png`` (coloured by displacement along the
  normal). Without ``--start-level`` the level whose training mesh has the target's face count (at
  least 1) is chosen (jmeshtex's own default; the official code starts at ``--gen-levels``' 1),
  raised until the output fits ``--max-faces`` (default 500000), and printed; ``--stop-level``
  stops early (the official ``--gen-levels`` stop); noise goes on the first two levels run (the
  official practice), ``--zero-noise-from k`` zeroes it from level k.
- ``interpolate --model DIR --target M --frames n --out OUT``: ``OUT/frame_XX.obj`` and
  ``OUT/interpolate.png``.

Every mesh argument is a file or a procedural name (``jmeshtex.cli._common.load_mesh_spec``:
``icosahedron``, ``icosphere:N``, ``torus``, ``torus:NMAJOR:NMINOR``, ``bumpy-sphere``, ``grid:N``,
...). ``--seed`` makes the ``key`` of the library calls, ``--quiet`` turns the progress bars off.
Compiled programs are kept in JAX's persistent compilation cache (``$JMESHTEX_JAX_CACHE``), so a
second ``train`` or ``transfer`` with the same sizes skips most compilation.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import shutil

from .._config import is_int
from .._errors import InputError
from ._common import (
    MAX_SPEC_VERTICES,
    add_common,
    add_method,
    cached,
    check_checkpoints,
    for_render,
    int_in,
    load_mesh_spec,
)
from ._output import claim_args, claim_output


def register(sub: argparse._SubParsersAction) -> None:
    dsub = add_method(
        sub,
        "dgts",
        help="DGTS: learn a geometric texture from one mesh, transfer it to any mesh",
        description="Deep Geometric Texture Synthesis (Hertz et al. 2020) on the CPU.",
    )

    _add_prepare(dsub)
    _add_train(dsub)
    _add_transfer_and_interpolate(dsub)


def _add_prepare(dsub) -> None:
    """``jmeshtex dgts prepare``: fit the template to the reference at every level."""
    q = dsub.add_parser(
        "prepare", help="fit a template to the reference at every level (training meshes)"
    )
    q.add_argument("--reference", required=True, help="reference mesh file or procedural name")
    q.add_argument(
        "--template", default="icosphere:1", help="template mesh file or name (default icosphere:1)"
    )
    q.add_argument(
        "--levels",
        type=int_in(1, 10),
        default=5,
        help="number of levels, 1 to 10 (default 5, the paper's depth)",
    )
    q.add_argument(
        "--steps",
        type=int_in(1, 1_000_000),
        default=None,
        help="Adam steps per level (default: PrepareConfig's)",
    )
    q.add_argument(
        "--samples",
        type=int_in(1, MAX_SAMPLES),
        default=None,
        help=f"surface samples at level 0 (at most {MAX_SAMPLES:,})",
    )
    q.add_argument(
        "--remeshes",
        type=int_in(1, 16),
        default=1,
        help="fit the reference R times, R - 1 of them from randomly turned templates "
        "(training_remesh<i>.npz), so the texture lies elsewhere on the template's triangles; "
        "`dgts train` then trains on all R (beyond the paper; default 1)",
    )
    add_common(q)
    q.set_defaults(func=cached(_prepare))


def _add_train(dsub) -> None:
    """``jmeshtex dgts train``: train the generator hierarchy from a prepared folder."""
    t = dsub.add_parser("train", help="train the generator hierarchy (WGAN-GP), resumable")
    t.add_argument("dir", type=pathlib.Path, metavar="DIR", help="folder written by `dgts prepare`")
    t.add_argument(
        "--steps",
        type=int_in(1, 10_000_000),
        default=None,
        help="training steps per level (default 2000)",
    )
    t.add_argument(
        "--layers", type=int_in(1, 64), default=None, help="layers per network (default 7)"
    )
    t.add_argument(
        "--features",
        type=int_in(1, 4096),
        nargs=3,
        default=None,
        metavar=("START", "MIN", "MAX"),
        help="width schedule (default 32 32 128)",
    )
    t.add_argument(
        "--levels", type=int_in(1, 10), default=None, help="train only the first N levels"
    )
    t.add_argument(
        "--shared-levels",
        type=int_in(0, 10),
        default=0,
        metavar="N",
        help="pad levels 0..N-1 to one size so equal-width levels share one compiled step (default 0)",
    )
    t.add_argument(
        "--checkpoint-every",
        type=int_in(1),
        default=None,
        metavar="N",
        help="also checkpoint every N steps within a level (default: after each level only)",
    )
    t.add_argument(
        "--snapshot-every",
        type=int_in(1),
        default=None,
        metavar="N",
        help="record the current sample and reconstruction every N steps (DIR/snapshots.npz)",
    )
    add_common(t, out=None)
    t.add_argument(
        "--overwrite",
        action="store_true",
        help="train in a DIR that holds another command's output or foreign files (files jmeshtex "
        "did not write are never replaced)",
    )
    t.set_defaults(func=cached(_train))


def _add_transfer_and_interpolate(dsub) -> None:
    """``jmeshtex dgts transfer`` and ``interpolate``: run a trained model on a target mesh."""
    for name, helptext in (
        ("transfer", "synthesise the texture on a target mesh"),
        ("interpolate", "animate between two noises on a target mesh"),
    ):
        r = dsub.add_parser(name, help=helptext)
        r.add_argument(
            "--model",
            required=True,
            type=pathlib.Path,
            help="folder of `dgts train` (or its model/)",
        )
        r.add_argument("--target", required=True, help="target mesh file or procedural name")
        r.add_argument(
            "--start-level",
            type=int,
            default=None,
            help="first generator level to run (default: the level whose training mesh has the "
            "target's face count, at least 1, raised until the output fits --max-faces)",
        )
        r.add_argument(
            "--stop-level",
            type=int,
            default=None,
            help="last generator level to run (default: the last; the official --gen-levels "
            "default is --start-level 1 --stop-level 4)",
        )
        r.add_argument(
            "--max-faces",
            type=int,
            default=500_000,
            help="face budget of the output (default 500000)",
        )
        if name == "transfer":
            r.add_argument(
                "--samples", type=int_in(1, 1000), default=1, help="number of samples (default 1)"
            )
            r.add_argument(
                "--zero-noise-from",
                type=int,
                default=None,
                metavar="K",
                help="zero noise at levels >= K (default: start level + 2, noise on the first two "
                "levels run; K <= start level: deterministic)",
            )
        else:
            r.add_argument(
                "--frames", type=int, default=8, help="frames including both ends (default 8)"
            )
        add_common(r, quiet=False)
        r.set_defaults(func=cached(_transfer if name == "transfer" else _interpolate))


def _prepare(args) -> int:
    import jax

    from ..dgts import PrepareConfig, save_training_meshes, training_meshes
    from ..io import atomic_write, save_mesh
    from ..render import render_grid, render_mesh

    changes = {"levels": args.levels}
    if args.steps is not None:
        changes["steps"] = args.steps
    if args.samples is not None:
        changes["samples_per_level"] = args.samples
    config = PrepareConfig(**changes)
    claim_args(args, "dgts prepare", args.reference, args.template, accept=("dgts train",))
    ref = load_mesh_spec(args.reference)
    tmpl = load_mesh_spec(args.template)
    finest = tmpl.num_faces * 4 ** (config.levels - 1)  # each level subdivides the one before
    if finest > 2 * MAX_SPEC_VERTICES:
        raise InputError(
            f"--levels {config.levels} on a {tmpl.num_faces}-face template makes ~{finest:.3g} "
            f"faces at the finest level, more than {2 * MAX_SPEC_VERTICES:,}: ask for fewer "
            "levels or a coarser --template"
        )
    key = jax.random.key(args.seed)
    out = args.out
    for i in range(args.remeshes):  # a stopped fit resumes after its last finished level
        name = "training" if i == 0 else f"training_remesh{i}"
        fit = training_meshes(
            ref,
            tmpl,
            config=config,
            key=key,
            progress=not args.quiet,
            rotation=_random_rotation(jax.random.fold_in(key, i)) if i else None,
            checkpoint_dir=out / f"{name}.levels",
        )
        save_training_meshes(fit, out / f"{name}.npz")
        if i == 0:
            tm = fit  # the plain fit: the levels written below
    for done in out.glob("training*.levels"):  # kept until every fit is done
        shutil.rmtree(done)
    atomic_write(
        out / "prepare.json",
        json.dumps(
            {**config.to_dict(), "seed": args.seed, "remeshes": args.remeshes}, indent=2
        ).encode(),
    )
    save_mesh(ref, out / "reference.obj")
    images = [render_mesh(for_render(ref), size=(300, 300))]
    for level in range(tm.num_levels):
        save_mesh(tm.mesh(level), out / f"level_{level:02d}.obj")
        images.append(render_mesh(tm.mesh(level), size=(300, 300)))
    render_grid(
        images,
        out / "levels.png",
        titles=["reference"] + [f"level {i}" for i in range(tm.num_levels)],
    )
    print(
        f"wrote {out / 'training.npz'} ({tm.num_levels} levels, {[len(f) for f in tm.faces]} faces)"
    )
    return 0


def _train(args) -> int:
    import jax

    from .. import Mesh
    from ..dgts import Config, load_training_meshes, save, train, transfer
    from ..io import save_mesh
    from ..render import render_mesh

    if args.dir.is_dir():  # one process per folder: a second run would race on the checkpoints
        claim_output(
            args.dir, command="dgts train", overwrite=args.overwrite, accept=("dgts prepare",)
        )
        check_checkpoints(args.dir / "checkpoints")
    remeshes = _prepared_remeshes(args.dir / "prepare.json")
    tm = load_training_meshes(args.dir / "training.npz")
    references = [tm] + [
        load_training_meshes(args.dir / f"training_remesh{i}.npz") for i in range(1, remeshes)
    ]
    changes = {"shared_levels": args.shared_levels, "checkpoint_every": args.checkpoint_every}
    if args.steps is not None:
        changes["steps"] = args.steps
    if args.layers is not None:
        changes["num_layers"] = args.layers
    if args.features is not None:
        changes.update(
            zip(("start_features", "min_features", "max_features"), args.features, strict=True)
        )
    config = Config(**changes)
    key = jax.random.key(args.seed)
    result = train(
        references,
        config,
        key=key,
        levels=args.levels,
        progress=not args.quiet,
        checkpoint_dir=args.dir / "checkpoints",
        snapshot_every=args.snapshot_every,
    )
    if args.snapshot_every is not None:
        from ..io import atomic_save_npz

        snaps = result.extra["snapshots"]
        atomic_save_npz(
            args.dir / "snapshots.npz",
            {
                **{f"sample_{i:03d}": s["sample"] for i, s in enumerate(snaps)},
                **{f"reconstruction_{i:03d}": s["reconstruction"] for i, s in enumerate(snaps)},
                "level": [s["level"] for s in snaps],
                "step": [s["step"] for s in snaps],
            },
        )
        print(f"wrote {len(snaps)} snapshots to {args.dir / 'snapshots.npz'}")
    if result.resumed_from is not None:
        print(f"resumed from checkpoint step {result.resumed_from}")
    for r in result.extra["levels"]:
        print(
            f"level {r.level}: {r.faces} faces, {r.steps} steps, compile {r.compile_seconds:.1f} s, "
            f"{1000 * r.seconds_per_step:.1f} ms/step"
        )
    out = save(result.model, args.dir / "model")
    # through every level (the default start skips level 0): a generation from the template
    sample = transfer(result.model, Mesh(tm.template, tm.faces[0]), start_level=0, key=key).mesh(0)
    save_mesh(sample, args.dir / "sample.obj")
    render_mesh(sample, args.dir / "sample.png", size=(400, 400), title="sample from the template")
    print(f"wrote {out} ({result.model.num_levels} levels) and {args.dir / 'sample.png'}")
    return 0


#: the most surface samples `dgts prepare --samples` may ask for (each level fits a Chamfer
#: distance against them; 1e9 would need hundreds of GB)
MAX_SAMPLES = 2_000_000


def _prepared_remeshes(path: pathlib.Path) -> int:
    """``remeshes`` from ``dgts prepare``'s record (1 without one), or one typed error naming it."""
    if not path.exists():
        return 1
    from ..io import check_input_file

    check_input_file(path, "dgts prepare record", max_bytes=1 << 20)
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError) as err:
        raise InputError(
            f"{path} is not the JSON record `dgts prepare` writes ({err}). Fix: run `jmeshtex dgts "
            "prepare` again into this folder"
        ) from err
    if not isinstance(record, dict):
        raise InputError(
            f"{path} holds a JSON {type(record).__name__}, not the object `dgts prepare` writes. "
            "Fix: run `jmeshtex dgts prepare` again into this folder"
        )
    remeshes = record.get("remeshes", 1)
    if not is_int(remeshes, 1) or remeshes > 16:
        raise InputError(
            f"{path}: 'remeshes' must be a whole number from 1 to 16, not {remeshes!r}. Fix: "
            "run `jmeshtex dgts prepare` again into this folder"
        )
    return remeshes


def _random_rotation(key):
    """A Haar-random proper rotation ``[3, 3]`` (float64 NumPy) drawn from ``key``."""
    import jax
    import numpy as np

    q = np.asarray(jax.random.orthogonal(key, 3), np.float64)
    return q if np.linalg.det(q) > 0 else q * np.array([-1.0, 1.0, 1.0])


def _model_dir(path: pathlib.Path) -> pathlib.Path:
    return path / "model" if (path / "model").is_dir() else path


def _write_results(res, out: pathlib.Path, stem: str, title: str) -> None:
    import numpy as np

    from ..io import save_mesh
    from ..render import render_grid, render_mesh

    lim = float(np.abs(res.heights).max()) or 1.0
    out.mkdir(parents=True, exist_ok=True)
    images = []
    for i, h in enumerate(res.heights):
        save_mesh(res.mesh(i), out / f"{stem}_{i:02d}.obj")
        images.append(
            render_mesh(res.mesh(i), scalars=h, cmap="coolwarm", clim=(-lim, lim), size=(300, 300))
        )
    render_grid(images, out / f"{title}.png", titles=[f"{stem} {i}" for i in range(len(images))])
    print(f"wrote {len(images)} meshes and {out / (title + '.png')}")


def _say_start(res, target, args) -> None:
    how = (
        "given"
        if args.start_level is not None
        else f"matched to the target's faces, within --max-faces {args.max_faces}"
    )
    print(
        f"start level {res.start_level} ({how}): {target.num_faces} target faces -> {len(res.faces)} output faces"
    )


def _model_and_target(args, command: str):
    """Claim ``--out`` for ``command``, then load ``--model`` and ``--target``."""
    from ..dgts import load

    claim_args(args, command, args.model, args.target)
    return load(_model_dir(args.model)), load_mesh_spec(args.target)


def _levels(args) -> dict:
    """The level keywords ``transfer`` and ``interpolate`` share."""
    return {
        "start_level": args.start_level,
        "stop_level": args.stop_level,
        "max_faces": args.max_faces,
    }


def _transfer(args) -> int:
    import jax

    from ..dgts import transfer

    model, target = _model_and_target(args, "dgts transfer")
    res = transfer(
        model,
        target,
        num_samples=args.samples,
        zero_noise_from=args.zero_noise_from,
        key=jax.random.key(args.seed),
        **_levels(args),
    )
    _say_start(res, target, args)
    _write_results(res, args.out, "sample", "transfer")
    return 0


def _interpolate(args) -> int:
    import jax

    from ..dgts import interpolate

    model, target = _model_and_target(args, "dgts interpolate")
    res = interpolate(
        model, target, num_frames=args.frames, key=jax.random.key(args.seed), **_levels(args)
    )
    _say_start(res, target, args)
    _write_results(res, args.out, "frame", "interpolate")
    return 0

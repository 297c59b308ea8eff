"""``jmeshtex fldm train|sample|inpaint``: a thin layer over the Field Latent Diffusion API.

- ``train --mesh M [--texture T] [--labels L.npy] --out DIR``: re-triangulated copies (cached in
  ``DIR/data``), FL-VAE latents, denoiser training (resumable checkpoints in ``DIR``), model files
  ``DIR/model.npz`` + ``model.json`` and ``DIR/fldm.json`` (what to decode with).
- ``sample --model DIR [--mesh N] [--vertices n] [--steps 50] [--ddpm] --n 4 --out OUT``: ``OUT/latents.npz``
  and a PNG per sample (``OUT/sample_XX_0.png``); with ``--mesh`` on another mesh (transfer); with
  ``--vertices`` on a re-triangulation with that many vertices (textural scale follows resolution).
- ``inpaint --model DIR --mask MASK.npy [--mesh N] ... --out OUT``: keeps the latents of the mesh's
  own colours where the ``[V]`` boolean mask is True.

Latent codec: ``--codec fl-vae`` (default) uses ``--vae PATH`` (an ``fl_vae.npz``) or the shipped
pre-trained FL-VAE; ``--codec stripes`` is the analytic codec of the demo (vertex colours on a
blue/yellow ramp, :mod:`jmeshtex.cli._stages.fldm`). Meshes are files or the procedural names of
``jmeshtex dgts`` plus ``striped-sphere``.
"""

from __future__ import annotations

import argparse
import json
import pathlib

import numpy as np

from .._errors import InputError, MeshIOError

PRESETS = ("tiny", "cpu", "paper")
PREDICTIONS = ("epsilon", "v")  # jmeshtex.fl.PREDICTIONS, spelled out so that --help needs no JAX


def register(sub: argparse._SubParsersAction) -> None:
    from ._dgts import _cached

    p = sub.add_parser("fldm", help="Field Latent Diffusion: generate / inpaint / transfer textures on a mesh",
                       description="Field Latent Diffusion (Mitchel et al. 2024) trained on one textured mesh.")
    fsub = p.add_subparsers(dest="fldm_command", metavar="STEP")

    t = fsub.add_parser("train", help="train a diffusion model on re-triangulated copies of one mesh (resumable)")
    t.add_argument("--mesh", required=True, help="textured mesh file or procedural name")
    t.add_argument("--texture", default=None, help="texture image replacing the mesh's (needs UVs)")
    t.add_argument("--labels", default=None, type=pathlib.Path, help="[V] int labels (.npy) for label guidance")
    t.add_argument("--out", required=True, type=pathlib.Path, help="model folder (checkpoints, data cache)")
    t.add_argument("--preset", choices=PRESETS, default="cpu", help="denoiser/data preset (default cpu)")
    t.add_argument("--copies", type=int, default=None, help="re-triangulated copies")
    t.add_argument("--vertices", type=int, default=None, help="vertices per copy")
    t.add_argument("--steps", type=int, default=None, help="training steps")
    t.add_argument("--prediction", choices=PREDICTIONS, default=None,
                   help="what the denoiser predicts (default: the preset's; cpu: v, paper: epsilon)")
    t.add_argument("--codec", choices=("fl-vae", "stripes"), default="fl-vae", help="latent encoder/decoder")
    t.add_argument("--vae", default=None, help="FL-VAE file (default: the shipped pre-trained one)")
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--no-progress", action="store_true", help="no progress bars")
    t.set_defaults(func=_cached(_train))

    for name, helptext in (("sample", "sample textures (optionally on another mesh)"),
                           ("inpaint", "fill in the unmasked part of a mesh's texture")):
        s = fsub.add_parser(name, help=helptext)
        s.add_argument("--model", required=True, type=pathlib.Path, help="folder of `fldm train`")
        s.add_argument("--mesh", default=None, help="mesh to sample on (default: the training mesh)")
        s.add_argument("--vertices", type=int, default=None, help="re-triangulate the mesh to this many vertices first")
        s.add_argument("--steps", type=int, default=50, help="DDIM steps (default 50)")
        s.add_argument("--ddim", action="store_true", help="DDIM sampling (the default)")
        s.add_argument("--ddpm", action="store_true", help="ancestral DDPM with all T steps")
        s.add_argument("--eta", type=float, default=0.0, help="DDIM eta (default 0)")
        s.add_argument("--n", type=int, default=4, help="number of samples (default 4)")
        s.add_argument("--labels", default=None, type=pathlib.Path, help="[V] int label map (.npy) on the mesh")
        s.add_argument("--size", type=int, default=512, help="texture atlas size when the mesh has UVs")
        s.add_argument("--seed", type=int, default=0)
        s.add_argument("--out", required=True, type=pathlib.Path, help="output folder")
        s.add_argument("--no-progress", action="store_true", help="no progress bars")
        if name == "inpaint":
            s.add_argument("--mask", required=True, type=pathlib.Path, help="[V] bool mask (.npy): True = keep")
        s.set_defaults(func=_cached(_sample if name == "sample" else _inpaint))
    p.set_defaults(func=lambda args: (p.print_help(), 1)[1])


def _load_mesh(spec: str):
    from .._mesh import Mesh
    from ._stages.fldm import striped_sphere

    if spec == "striped-sphere":
        return striped_sphere(subdivisions=3)
    if pathlib.Path(spec).suffix:
        from ..io import load_mesh

        return load_mesh(spec)
    from ._dgts import load_mesh_arg

    v, f = load_mesh_arg(spec)
    return Mesh(v, f)


def _codec(kind: str, vae: str | None, original, *, seed: int):
    """``(encode, decode)``: encode ``Mesh -> [V, d]``, decode ``(Mesh, [n, V, d]) -> list of dicts``."""
    import jax

    if kind == "stripes":
        from ._stages.fldm import intensity_to_rgb, stripe_decoder, stripe_encoder

        def decode(mesh, latents, size):
            return [{"vertex_colors": intensity_to_rgb(stripe_decoder(z))} for z in latents]

        return stripe_encoder, decode, 2
    from ..fl import load_fl_vae, load_pretrained
    from ..fldm import decode_samples, fl_vae_encoder

    params, cfg = load_pretrained() if vae is None else load_fl_vae(vae)
    encode = fl_vae_encoder(params, cfg, original, key=jax.random.key(seed))

    def decode(mesh, latents, size):
        return decode_samples(params, cfg, mesh, latents, size=size)

    return encode, decode, cfg.latent_dim


def _train(args) -> int:
    from ..fldm import FLDMConfig, build_dataset, train_fldm

    mesh = _load_mesh(args.mesh)
    if args.texture:
        if mesh.uv is None:
            raise InputError(f"--texture needs a mesh with UVs; {args.mesh} has none")
        from ..io import load_texture

        mesh = mesh.replace(texture=load_texture(args.texture))
    labels = None if args.labels is None else np.load(args.labels)
    encode, _, d = _codec(args.codec, args.vae, mesh, seed=args.seed)
    changes = {"latent_channels": d, "seed": args.seed}
    if labels is not None:
        changes["num_labels"] = int(np.max(labels)) + 1
    for field, value in (("n_copies", args.copies), ("copy_vertices", args.vertices), ("train_steps", args.steps),
                         ("prediction", args.prediction)):
        if value is not None:
            changes[field] = value
    config = getattr(FLDMConfig, args.preset)(**changes)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    data = build_dataset(mesh, config, encode=encode, labels=labels, cache_dir=out / "data",
                         progress=not args.no_progress)
    res = train_fldm(data, config, out_dir=out, progress=not args.no_progress)
    meta = {"mesh": args.mesh, "texture": args.texture, "codec": args.codec, "vae": args.vae, "seed": args.seed,
            "labels": None if args.labels is None else str(args.labels)}
    (out / "fldm.json").write_text(json.dumps(meta, indent=2))
    print(f"trained {res.steps_done} steps in {res.seconds:.1f} s; loss {np.mean(res.losses[-20:]):.4f}; model in {out}")
    return 0


def _target(args, meta):
    from ..geometry import remesh

    original = _load_mesh(meta["mesh"])
    mesh = original if args.mesh is None else _load_mesh(args.mesh)
    if args.vertices is not None:
        mesh = remesh(mesh, n_vertices=args.vertices, seed=args.seed)
    return original, mesh


def _run_sampling(args, *, inpaint: bool) -> int:
    import jax

    from ..fldm import load_fldm, render_samples, sample_fldm

    model = load_fldm(args.model)
    meta_path = args.model / "fldm.json"
    if not meta_path.is_file():
        raise MeshIOError(f"{meta_path} is missing; was {args.model} written by `jmeshtex fldm train`?")
    meta = json.loads(meta_path.read_text())
    original, mesh = _target(args, meta)
    encode, decode, _ = _codec(meta["codec"], meta["vae"], original, seed=args.seed)
    if args.ddim and args.ddpm:
        raise InputError("choose one of --ddim and --ddpm")
    labels = None if args.labels is None else np.load(args.labels)
    kwargs = dict(key=jax.random.key(args.seed), n=args.n, method="ddpm" if args.ddpm else "ddim", steps=args.steps,
                  eta=args.eta, labels=labels, progress=not args.no_progress)
    if inpaint:
        mask = np.load(args.mask).astype(bool)
        if mask.shape != (mesh.num_vertices,):
            raise InputError(f"--mask must be a [V] = ({mesh.num_vertices},) boolean array, got {mask.shape}")
        kwargs.update(known=encode(mesh), mask=mask)
    latents = sample_fldm(model, mesh, **kwargs)
    args.out.mkdir(parents=True, exist_ok=True)
    np.savez(args.out / "latents.npz", latents=latents, vertices=mesh.vertices, faces=mesh.faces)
    paths = render_samples(mesh, decode(mesh, latents, args.size), args.out, prefix="inpaint" if inpaint else "sample")
    print(f"{len(latents)} samples on {mesh.num_vertices} vertices → {args.out} ({len(paths)} PNGs)")
    return 0


def _sample(args) -> int:
    return _run_sampling(args, inpaint=False)


def _inpaint(args) -> int:
    return _run_sampling(args, inpaint=True)

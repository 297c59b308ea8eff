"""``jmeshtex fldm train|sample|inpaint``: a thin layer over the Field Latent Diffusion API.

- ``train --mesh M [--texture T] [--labels L.npy] [--mask-conditioning] --out DIR``: re-triangulated copies (cached in
  ``DIR/data``), FL-VAE latents, denoiser training (resumable checkpoints in ``DIR/checkpoints``),
  the model file ``DIR/model.npz`` (:func:`jmeshtex.fldm.save`) and ``DIR/fldm.json``
  (what to decode with).
- ``sample --model DIR [--mesh N] [--vertices n] [--steps 50] [--ddpm] --num-samples 4 --out OUT``: ``OUT/latents.npz``
  and a PNG per sample (``OUT/sample_XX_0.png``); with ``--mesh`` on another mesh (transfer); with
  ``--vertices`` on a re-triangulation with that many vertices (textural scale follows resolution).
- ``inpaint --model DIR --mask MASK.npy [--mesh N] ... --out OUT``: keeps the latents of the mesh's
  own colours where the ``[V]`` boolean mask is True.

Latent codec: ``--codec fl-vae`` (default) uses ``--vae PATH`` (a folder written by :func:`jmeshtex.fl.save`, or a model file) or the shipped
pre-trained FL-VAE; ``--codec stripes`` is the analytic codec of the demo (vertex colours on a
blue/yellow ramp, ``jmeshtex/cli/_stages/fldm.py``). Meshes are files or procedural names
(``icosphere:N``, ``striped-sphere[:N]``, ...; ``cli._common.load_mesh_spec``). ``--seed``
makes the ``jax.random.key`` of every random choice; ``--quiet`` turns off the progress bars.
"""

from __future__ import annotations

import argparse
import json
import pathlib

import numpy as np

from .._errors import InputError, MeshIOError
from ._common import (
    MAX_SPEC_VERTICES,
    MAX_TEXTURE_SIZE,
    add_common,
    add_method,
    cached,
    check_checkpoints,
    float_in,
    int_in,
    load_array,
    load_labels,
    load_mesh_spec,
    spec_for_record,
)
from ._output import claim_args

PRESETS = ("tiny", "cpu", "paper")
PREDICTIONS = ("epsilon", "v")  # jmeshtex.fldm.PREDICTIONS, spelled out so that --help needs no JAX


def register(sub: argparse._SubParsersAction) -> None:
    fsub = add_method(
        sub,
        "fldm",
        help="Field Latent Diffusion: generate / inpaint / transfer textures on a mesh",
        description="Field Latent Diffusion (Mitchel et al. 2024) trained on one textured mesh.",
    )
    _add_train(fsub)
    _add_sampling(fsub, "sample", "sample textures (optionally on another mesh)")
    _add_sampling(fsub, "inpaint", "fill in the unmasked part of a mesh's texture")


def _add_train(fsub: argparse._SubParsersAction) -> None:
    """``fldm train``."""
    t = fsub.add_parser(
        "train", help="train a diffusion model on re-triangulated copies of one mesh (resumable)"
    )
    t.add_argument("--mesh", required=True, help="textured mesh file or procedural name")
    t.add_argument("--texture", default=None, help="texture image replacing the mesh's (needs UVs)")
    t.add_argument(
        "--labels", default=None, type=pathlib.Path, help="[V] int labels (.npy) for label guidance"
    )
    add_common(t, out="model folder (model, checkpoints, data cache)")
    t.add_argument(
        "--preset", choices=PRESETS, default="cpu", help="denoiser/data preset (default cpu)"
    )
    t.add_argument("--copies", type=int_in(1, 10_000), default=None, help="re-triangulated copies")
    t.add_argument(
        "--vertices", type=int_in(4, MAX_SPEC_VERTICES), default=None, help="vertices per copy"
    )
    t.add_argument("--steps", type=int_in(1, 10_000_000), default=None, help="training steps")
    t.add_argument(
        "--prediction",
        choices=PREDICTIONS,
        default=None,
        help="what the denoiser predicts (default: the preset's; cpu: v, paper: epsilon)",
    )
    t.add_argument(
        "--mask-conditioning",
        action="store_true",
        help="train on random masks and condition the denoiser on the inpainting mask (§6.4)",
    )
    t.add_argument(
        "--codec", choices=("fl-vae", "stripes"), default="fl-vae", help="latent encoder/decoder"
    )
    t.add_argument(
        "--vae",
        default=None,
        help="FL-VAE folder of `fl train` (default: the shipped pre-trained one)",
    )
    t.set_defaults(func=cached(_train))


def _add_sampling(fsub: argparse._SubParsersAction, name: str, helptext: str) -> None:
    """``fldm sample`` or ``fldm inpaint`` (``name``): the same options, inpaint adds ``--mask``."""
    s = fsub.add_parser(name, help=helptext)
    s.add_argument("--model", required=True, type=pathlib.Path, help="folder of `fldm train`")
    s.add_argument("--mesh", default=None, help="mesh to sample on (default: the training mesh)")
    s.add_argument(
        "--vertices",
        type=int_in(4, MAX_SPEC_VERTICES),
        default=None,
        help="re-triangulate the mesh to this many vertices first",
    )
    s.add_argument("--steps", type=int_in(1, 100_000), default=50, help="DDIM steps (default 50)")
    s.add_argument("--ddim", action="store_true", help="DDIM sampling (the default)")
    s.add_argument("--ddpm", action="store_true", help="ancestral DDPM with all T steps")
    s.add_argument("--eta", type=float_in(0.0), default=0.0, help="DDIM eta (default 0)")
    s.add_argument(
        "--num-samples",
        "--n",
        dest="num_samples",
        type=int_in(1, 4096),
        default=4,
        help="number of samples (default 4)",
    )
    s.add_argument(
        "--labels", default=None, type=pathlib.Path, help="[V] int label map (.npy) on the mesh"
    )
    s.add_argument(
        "--size",
        type=int_in(8, MAX_TEXTURE_SIZE),
        default=512,
        help="texture atlas size when the mesh has UVs",
    )
    add_common(s, out="output folder (latents.npz, PNGs)")
    if name == "inpaint":
        s.add_argument(
            "--mask", required=True, type=pathlib.Path, help="[V] bool mask (.npy): True = keep"
        )
    s.set_defaults(func=cached(_sample if name == "sample" else _inpaint))


def _load_mesh(spec: str, texture: str | None = None):
    """The mesh of a mesh argument, with ``--texture`` replacing its texture (it needs UVs)."""
    mesh = load_mesh_spec(spec)
    if texture:
        if mesh.uv is None:
            raise InputError(f"--texture needs a mesh with UVs; {spec} has none")
        from ..io import load_texture

        mesh = mesh.replace(texture=load_texture(texture))
    return mesh


def _codec(kind: str, vae: str | None, original, *, key):
    """``(encode, decode, d)``: encode ``Mesh -> [V, d]``, decode ``(Mesh, [n, V, d]) -> list of dicts``."""
    if kind == "stripes":
        from ..data import intensity_to_rgb, stripe_decoder, stripe_encoder

        def decode(mesh, latents, size):
            return [{"vertex_colors": intensity_to_rgb(stripe_decoder(z))} for z in latents]

        return stripe_encoder, decode, 2
    from .. import fl
    from ..fldm import decode_samples, fl_vae_encoder

    model = fl.load_pretrained() if vae is None else fl.load(vae)
    encode = fl_vae_encoder(model, original, key=key)

    def decode(mesh, latents, size):
        return decode_samples(model, mesh, latents, size=size)

    return encode, decode, model.config.latent_dim


def _train(args) -> int:
    import jax

    from ..fldm import Config, build_dataset, save, train
    from ..io import atomic_write

    claim_args(args, "fldm train", args.mesh, args.texture, args.labels, args.vae)
    check_checkpoints(args.out / "checkpoints")
    mesh = _load_mesh(args.mesh, args.texture)
    labels = None if args.labels is None else load_labels(args.labels)
    k_codec, k_data, k_train = jax.random.split(jax.random.key(args.seed), 3)
    encode, _, d = _codec(args.codec, args.vae, mesh, key=k_codec)
    changes = {"latent_channels": d}
    if labels is not None:
        changes["num_labels"] = int(np.max(labels)) + 1
    if args.mask_conditioning:
        changes["mask_conditioning"] = True
    for field, value in (
        ("n_copies", args.copies),
        ("copy_vertices", args.vertices),
        ("steps", args.steps),
        ("prediction", args.prediction),
    ):
        if value is not None:
            changes[field] = value
    config = getattr(Config, args.preset)(**changes)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    data = build_dataset(
        mesh,
        config,
        encode=encode,
        key=k_data,
        labels=labels,
        cache_dir=out / "data",
        progress=not args.quiet,
    )
    res = train(
        data, config, key=k_train, checkpoint_dir=out / "checkpoints", progress=not args.quiet
    )
    from ..fldm.core import model_card

    save(res.model, out, card=model_card(res))
    meta = {  # files as absolute paths: the record is read from other folders too
        "mesh": spec_for_record(args.mesh),
        "texture": spec_for_record(args.texture),
        "codec": args.codec,
        "vae": spec_for_record(args.vae),
        "seed": args.seed,
        "labels": spec_for_record(args.labels),
    }
    atomic_write(out / "fldm.json", json.dumps(meta, indent=2))
    done = res.steps - (res.resumed_from or 0)
    print(
        f"trained {done} steps in {res.seconds:.1f} s ({res.steps} in all); loss "
        f"{np.mean(res.losses['loss'][-20:]):.4f}; model in {out}"
    )
    return 0


def _target(args, meta):
    import jax

    from ..geometry import remesh

    original = _load_mesh(meta["mesh"], meta.get("texture"))
    mesh = original if args.mesh is None else _load_mesh(args.mesh)
    if args.vertices is not None:
        mesh = remesh(mesh, n_vertices=args.vertices, key=jax.random.key(args.seed))
    return original, mesh


def _run_sampling(args, *, inpaint: bool) -> int:
    import jax

    from ..fldm import load, render_samples, sample
    from ..io import atomic_save_npz

    claim_args(
        args,
        f"fldm {'inpaint' if inpaint else 'sample'}",
        args.model,
        args.mesh,
        args.labels,
        getattr(args, "mask", None),
    )
    model = load(args.model)
    meta_path = args.model / "fldm.json"
    if not meta_path.is_file():
        raise MeshIOError(
            f"{meta_path} is missing; was {args.model} written by `jmeshtex fldm train`?"
        )
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
        if not isinstance(meta, dict) or not {"codec", "vae", "mesh"} <= set(meta):
            raise ValueError("not a record with the keys codec, vae and mesh")
    except (OSError, ValueError, UnicodeDecodeError) as err:
        raise MeshIOError(
            f"{meta_path} is corrupt ({type(err).__name__}: {err}); rerun `jmeshtex fldm train`"
        ) from err
    original, mesh = _target(args, meta)
    k_codec, k_sample = jax.random.split(jax.random.key(args.seed))
    encode, decode, _ = _codec(meta["codec"], meta["vae"], original, key=k_codec)
    if args.ddim and args.ddpm:
        raise InputError("choose one of --ddim and --ddpm")
    labels = None if args.labels is None else load_labels(args.labels)
    kwargs = dict(
        key=k_sample,
        num_samples=args.num_samples,
        method="ddpm" if args.ddpm else "ddim",
        steps=args.steps,
        eta=args.eta,
        labels=labels,
        progress=not args.quiet,
    )
    if inpaint:
        mask = load_array(args.mask, "--mask")
        if mask.dtype.kind not in "biu":
            raise InputError(f"--mask must be a boolean (or 0/1) array, got dtype {mask.dtype}")
        mask = mask.astype(bool)
        if mask.shape != (mesh.num_vertices,):
            raise InputError(
                f"--mask must be a [V] = ({mesh.num_vertices},) boolean array, got {mask.shape}"
            )
        kwargs.update(known=encode(mesh), mask=mask)
    latents = sample(model, mesh, **kwargs).latents
    if not np.isfinite(np.asarray(latents)).all():  # nothing non-finite is written (exit 0)
        raise InputError(
            "sampling produced non-finite latents: the model or the target mesh is out of range "
            "(check the mesh's scale, or retrain the model); nothing was written"
        )
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_save_npz(
        args.out / "latents.npz",
        {"latents": np.asarray(latents), "vertices": mesh.vertices, "faces": mesh.faces},
    )
    paths = render_samples(
        mesh, decode(mesh, latents, args.size), args.out, prefix="inpaint" if inpaint else "sample"
    )
    print(
        f"{len(latents)} samples on {mesh.num_vertices} vertices → {args.out} ({len(paths)} PNGs)"
    )
    return 0


def _sample(args) -> int:
    return _run_sampling(args, inpaint=False)


def _inpaint(args) -> int:
    return _run_sampling(args, inpaint=True)

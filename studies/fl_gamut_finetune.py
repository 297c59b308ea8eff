"""Study (issue 55, item 2): the FL-VAE's colour bias at the gamut boundary, and a decoder-only fine-tune.

Finding (the shipped ``fl_vae.npz``, a flat colour on a 12 × 12 grid sheet, decoded at 48²): greys
come back within 0.01 up to 0.9, but colours on the RGB cube's faces do not: white decodes to
(.941, .958, .971), (1, 0, 0) to (.902, .088, .064), (0, 0, 1) to (.075, .027, .930). The latents
of those colours are not out of range (|μ| 1.41 for red, 1.61 for black, which decodes exactly).
The training colours rarely lie on the cube's faces: the procedural palettes draw saturation from
[0.55, 1] and value from [0.35, 1] uniformly (``fl/_textures.py``), so a colour with s = v = 1 has
probability zero, and photographs seldom clip all three channels.

The fix tried here changes the training data at that source: half of each step's textures are
cells of colours on the cube's faces (one channel at 0 or 1, often two), the other half the
shipped model's own stream (:func:`jmeshtex.fl.core.training_meshes`). Only the decoder is trained
(the encoder, and so every latent an FLDM was trained on, stays bit for bit), from the shipped
weights, with Adam at a constant rate after a warm-up, resumable through :func:`jmeshtex.fit`.

It reports, before and after: the flat-colour probe (largest channel error over 14 colours on and
inside the cube), the held-out photographs on planar meshes at 26 pixels per vertex (PSNR, the
shipped model's table) and Spot's own texture on its mesh as stored (atlas PSNR, when
``../shared/data`` is there).

Usage::

    python studies/fl_gamut_finetune.py --steps 1000 --work runs/fl_gamut   # resumable
    python studies/fl_gamut_finetune.py --steps 1000 --work runs/fl_gamut --eval-only

Writes ``studies/results/fl_gamut_finetune.md`` and ``runs/fl_gamut/model/`` (the fine-tuned
model; copying it over the shipped file is a separate, deliberate step).
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
import optax

from jmeshtex import Mesh, fl
from jmeshtex._training import CheckpointPolicy, fit  # the training driver (private)
from jmeshtex.data import grid
from jmeshtex.fl.core import batch_loss, density_mesh, mesh_batch, planar_mesh, training_meshes

#: the probe's colours: greys, colours inside the cube and on its faces, its corners
PROBE = (
    (1.0, 1.0, 1.0), (0.9, 0.9, 0.9), (0.5, 0.5, 0.5), (0.0, 0.0, 0.0),
    (1.0, 0.5, 0.5), (0.8, 0.5, 0.5), (0.5, 1.0, 0.5), (0.5, 0.5, 1.0),
    (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 1.0, 0.0),
    (0.0, 1.0, 1.0), (1.0, 0.0, 1.0),
)  # fmt: skip


def gamut_colors(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` colours on the RGB cube's faces: a uniform colour with its largest channel set to 1
    (probability ½) and its smallest to 0 (probability ½; at least one of the two)."""
    c = rng.random((n, 3))
    top = rng.random(n) < 0.5
    bottom = ~top | (rng.random(n) < 0.5)
    rows = np.arange(n)
    c[rows[top], c[top].argmax(1)] = 1.0
    c[rows[bottom], c[bottom].argmin(1)] = 0.0
    return c


def gamut_texture(rng: np.random.Generator, size: int) -> np.ndarray:
    """Voronoi cells of :func:`gamut_colors`, 3–12 cells, on a ``size``² texture."""
    k = int(rng.integers(3, 13))
    centres = rng.random((k, 2)) * size
    yy, xx = np.mgrid[0:size, 0:size] + 0.5
    d = (yy[..., None] - centres[:, 0]) ** 2 + (xx[..., None] - centres[:, 1]) ** 2
    return gamut_colors(rng, k)[d.argmin(-1)]


def batches_for(config: fl.Config, seed: int):
    """Step ``t``'s batch: ``batch_size`` meshes, alternately gamut cells and the shipped stream."""
    images = fl.training_images()
    size = int(config.texture_size)
    # the densest stream mesh (round(size² / ppv) vertices at the densest draw), for every mesh
    densest = round(size * size / (float(config.pixels_per_vertex) / float(config.density_spread)))
    num_vertices = config.batch_size * (densest + 1)

    def batch(t: int):
        rng = np.random.default_rng([seed, t])
        stream = training_meshes(jax.random.fold_in(jax.random.key(seed), t), config, images=images)
        meshes = [
            density_mesh(gamut_texture(rng, size), float(config.pixels_per_vertex), rng=rng),
            *stream[: config.batch_size - 1],
        ]
        arrays = mesh_batch(meshes, config, rng, num_vertices=num_vertices)
        return {k: jnp.asarray(v) for k, v in arrays.items()}, jax.random.fold_in(
            jax.random.key(seed + 1), t
        )

    return batch


def decoder_step(config: fl.Config, learning_rate: float, warmup: int):
    """``(state, (batch, key)) -> (state, losses)``: an Adam step on the decoder alone."""
    opt = optax.chain(
        optax.clip_by_global_norm(config.grad_clip),
        optax.adam(optax.linear_schedule(0.0, learning_rate, warmup)),
    )

    def loss_fn(decoder, encoder, batch, key):
        return batch_loss(fl.core.Params(encoder, decoder), config, batch, key=key)

    @jax.jit
    def step(state, inputs):
        batch, key = inputs
        (loss, aux), g = jax.value_and_grad(loss_fn, has_aux=True)(
            state["decoder"], state["encoder"], batch, key
        )
        updates, opt_state = opt.update(g, state["opt"], state["decoder"])
        decoder = optax.apply_updates(state["decoder"], updates)
        return {**state, "decoder": decoder, "opt": opt_state}, {"loss": loss, "l1": aux["l1"]}

    return step, opt


def probe(model: fl.Model) -> list[tuple[tuple, np.ndarray]]:
    """Each :data:`PROBE` colour as a flat texture, encoded and decoded: the mean decoded colour."""
    v, f = grid(12)
    out = []
    for c in PROBE:
        tex = np.empty((48, 48, 3), np.float32)
        tex[:] = c
        mesh = Mesh(v, f, uv=v[f][..., :2], texture=tex)
        lat = fl.encode(model, mesh, key=jax.random.key(0))
        t, valid = fl.decode_texture(model, mesh, lat, size=48)
        out.append((c, np.asarray(t)[np.asarray(valid)].mean(0)))
    return out


def held_out_psnr(model: fl.Model) -> list[float]:
    """Atlas PSNR of the three held-out photographs on planar meshes at 26 pixels per vertex (192²)."""
    out = []
    for i, image in enumerate(fl.held_out_images(max_size=192)):
        h, w = image.shape[:2]
        mesh = planar_mesh(image, max(4, round(h * w / 26)), rng=np.random.default_rng(i))
        out.append(fl.reconstruct(model, mesh, key=jax.random.key(i), lpips=False).metrics["psnr"])
    return out


def spot_psnr(model: fl.Model) -> float | None:
    """Spot's own texture on its mesh as stored (latents at its vertices), 512² atlas; None without
    ``../shared/data``."""
    root = pathlib.Path(os.environ.get("JMESHTEX_SHARED_DATA", "../shared/data"))
    path = root / "spot" / "spot_triangulated.obj"
    if not path.is_file():
        return None
    from jmeshtex.io import load_mesh

    spot = load_mesh(path, texture=path.parent / "spot_texture.png")
    return float(
        fl.reconstruct(model, spot, key=jax.random.key(0), size=512, lpips=False).metrics["psnr"]
    )


def evaluate(label: str, model: fl.Model) -> dict:
    t0 = time.perf_counter()
    colours = probe(model)
    errors = [float(np.abs(np.asarray(c) - m).max()) for c, m in colours]
    result = {
        "label": label,
        "probe": colours,
        "worst": max(errors),
        "worst_inside": max(
            e for (c, _), e in zip(colours, errors, strict=True) if max(c) < 1 and min(c) > 0
        ),
        "held_out": held_out_psnr(model),
        "spot": spot_psnr(model),
    }
    print(f"[{label}] evaluated in {time.perf_counter() - t0:.0f} s", flush=True)
    return result


def write_report(path: pathlib.Path, rows: list[dict], run: dict) -> None:
    lines = [
        "# FL-VAE decoder fine-tune on gamut colours (studies/fl_gamut_finetune.py)",
        "",
        f"run: {run}",
        "",
        "| model | worst channel error (14 flat colours) | worst inside the cube | held-out PSNR "
        "chelsea / coffee / rocket (26 px per vertex) | Spot as stored, 512² |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        spot = "—" if r["spot"] is None else f"{r['spot']:.2f}"
        held = " / ".join(f"{p:.2f}" for p in r["held_out"])
        lines.append(
            f"| {r['label']} | {r['worst']:.3f} | {r['worst_inside']:.3f} | {held} | {spot} |"
        )
    lines += ["", "Flat colours decoded (mean over the sheet):", ""]
    lines.append("| colour | " + " | ".join(r["label"] for r in rows) + " |")
    lines.append("|---" * (len(rows) + 1) + "|")
    for i, (c, _) in enumerate(rows[0]["probe"]):
        cells = ["(" + ", ".join(f"{x:.3f}" for x in r["probe"][i][1]) + ")" for r in rows]
        lines.append(f"| {c} | " + " | ".join(cells) + " |")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text("\n".join(lines) + "\n")
    tmp.replace(path)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--steps", type=int, default=1000)
    p.add_argument("--stop-after", type=int, default=None)
    p.add_argument("--learning-rate", type=float, default=2e-4)
    p.add_argument("--warmup", type=int, default=100)
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--work", type=pathlib.Path, default=pathlib.Path("runs/fl_gamut"))
    p.add_argument("--eval-only", action="store_true")
    p.add_argument(
        "--report", type=pathlib.Path, default=pathlib.Path("studies/results/fl_gamut_finetune.md")
    )
    args = p.parse_args(argv)

    shipped = fl.load_pretrained()
    config = shipped.config
    out = args.work / "model"  # fl.save writes a folder
    if not args.eval_only:
        step, opt = decoder_step(config, args.learning_rate, args.warmup)
        state = {
            "decoder": shipped.params.decoder,
            "encoder": shipped.params.encoder,
            "opt": opt.init(shipped.params.decoder),
        }
        c0 = resource.getrusage(resource.RUSAGE_SELF).ru_utime
        result = fit(
            step,
            state,
            batches_for(config, args.seed),
            steps=args.steps,
            stop_after=args.stop_after,
            checkpoints=CheckpointPolicy(
                args.work / "checkpoints",
                every=50,
                fingerprint={"lr": args.learning_rate, "warmup": args.warmup, "seed": args.seed},
            ),
            progress=True,
        )
        print(
            f"trained to step {result.steps} "
            f"({resource.getrusage(resource.RUSAGE_SELF).ru_utime - c0:.0f} CPU-s this call)"
        )
        if result.steps < args.steps:
            return 0
        tuned = fl.Model(fl.core.Params(shipped.params.encoder, result.model["decoder"]), config)
        args.work.mkdir(parents=True, exist_ok=True)
        fl.save(tuned, out, extra={"finetune": "decoder on gamut colours", "steps": args.steps})
    tuned = fl.load(out)
    rows = [evaluate("shipped", shipped), evaluate(f"decoder fine-tuned {args.steps}", tuned)]
    write_report(
        args.report, rows, {"steps": args.steps, "lr": args.learning_rate, "seed": args.seed}
    )
    print(args.report.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

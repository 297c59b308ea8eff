"""Benchmark: FLDM's results on Spot on the paper's protocol (training density, baselines, decoder-free statistics).

Run::

    python benchmarks/fldm.py --train-only     # train (resumes; ~2 h of CPU at 10K vertices)
    python benchmarks/fldm.py --eval-only      # evaluate the newest model snapshot
    python benchmarks/fldm.py --eval-only --checkpoint-step 3000
    python benchmarks/fldm.py                  # train on, then evaluate
    python benchmarks/fldm.py --quick          # a smoke run (tiny model, ~2 min)

Writes ``benchmarks/results/fldm_spot.{json,md}`` and ``fldm_spot.png`` (``--out`` to change the
folder, ``--name`` the file name; ``--set FIELD=JSON`` changes a field of the preset's config, e.g.
``--set phase_sync=flat --set invariants=false`` for coherent latents, beyond the paper;
``--decoder barycentric --set phase_sync=all`` for the synchronised barycentric codec). The
work folder (``runs/fldm_spot[_quick]/``, git-ignored; ``--work``) holds the training
copies (``data/``), the resumable checkpoints (``train/``: re-running the same command resumes after
the newest) and a model snapshot with its card after every ``checkpoint_every`` steps
(``models/step_NNNNN/model.npz`` + ``card.json``), which ``--eval-only --checkpoint-step N``
evaluates while training goes on. The same command runs on a GPU when JAX sees one; there a
step costs about the same for batches of 2 to 8 copies (``--set batch_size=8``: 26.5 steps/s on an
H200; ``results/fldm_spot_gpu.md`` is such a run, trained there and evaluated here with
``--eval-only``). The report's training row names the device the steps ran on.

Protocol (Mitchel et al. 2024, §6.1, §6.6):

1. ``n_copies`` re-triangulations of Spot (``../shared/data/spot`` or ``$JMESHTEX_SHARED_DATA``) at
   ``--vertices`` vertices (default 10,000: the FL-VAE's training density, not Spot's own 2,930),
   each encoded ``encodings_per_copy`` times with the shipped FL-VAE (fresh one-ring samplings);
2. ``fldm.train`` with ``fldm.Config.cpu`` (the decoder-free statistics logged at every checkpoint);
3. samples on Spot midpoint-subdivided to about the training density (``sampling_subdivisions``:
   once at 10,000 vertices, not at all at 3,000; with Spot's UV atlas):
   DDIM-50 and DDPM-1000, decoded to the atlas (``fldm.decode_samples``), rendered at fixed views.

Rows (table ``quality``; sources vs the exemplar's renders from the same views):

- ``exemplar``: the metric's zero; ``reconstruction``: encode the sampling mesh → decode (the
  codec's ceiling); ``masked flat colour``: the best constant colour over the *used* texels only;
  ``shuffled latents``: the reconstruction's latents permuted over vertices (right marginal, no
  spatial structure); ``random channel phases``: each latent turned by its own random phase (right
  magnitudes, no cross-channel phase structure); the trained samples (DDIM-50, DDPM-1000).
- ``fidelity_gram``: mean VGG Gram distance (relu1_1…relu4_1) to the exemplar's render;
  ``diversity_lpips``: mean LPIPS-VGG between two samples' renders (all pairs);
- decoder-free statistics of the latents (``jmeshtex.fldm`` ``latent_statistics`` on the sampling
  mesh's neighbourhoods): ``concentration`` (cross-channel relative-phase concentration R),
  ``energy_corr`` (neighbour correlation of |z|²), ``phase_coh`` (transported phase coherence);
- ``nearest_copy_corr``: the largest correlation of a field's total energy ``Σ|z|²`` with that of a
  training copy carried to the sampling mesh (nearest vertex): a sample that copies the training
  field scores like the reconstruction does.

Table ``statistics`` is the training curve of the decoder-free statistics (one row per checkpoint),
table ``denoising`` one denoiser call on a noised training copy at several noise levels (what the
network restores, apart from the sampler), table ``trajectory`` a DDIM path traced (where the
samples' structure is made and lost), table ``training`` the step rate (wall and process CPU
seconds per step).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import resource
import sys
import time
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from _harness import RESULTS, Report

from jmeshtex import Mesh

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
SHARED = ROOT / ".." / "shared" / "data"
VIEWS = ((15.0, 35.0), (15.0, 125.0), (15.0, 215.0), (15.0, 305.0))


def _load() -> float:
    return os.getloadavg()[0]


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def spot_path() -> pathlib.Path:
    """Spot's folder, or exit with a message that says where it was looked for."""
    base = pathlib.Path(os.environ.get("JMESHTEX_SHARED_DATA", SHARED))
    spot = base / "spot"
    for name in ("spot_triangulated.obj", "spot_texture.png"):
        if not (spot / name).is_file():
            sys.exit(
                f"fldm_spot: {spot / name} not found. This benchmark needs Spot (../shared/data/spot "
                "with spot_triangulated.obj and spot_texture.png); point JMESHTEX_SHARED_DATA at the "
                "folder that holds spot/."
            )
    return spot


def _field_change(item: str) -> tuple[str, object]:
    """``"name=value"`` of ``--set`` as ``(name, value)``, the value read as JSON (else a string)."""
    name, sep, value = item.partition("=")
    if not sep:
        raise SystemExit(f"fldm_spot: --set needs FIELD=VALUE, got {item!r}")
    try:
        return name.strip(), json.loads(value)
    except json.JSONDecodeError:
        return name.strip(), value


def presets(quick: bool, latent_dim: int, vertices: int, spot_vertices: int):
    """``(fldm.Config, run settings)`` of the full benchmark or the ``--quick`` smoke run."""
    from jmeshtex import fldm

    if quick:
        cfg = fldm.Config.cpu(
            latent_channels=latent_dim,
            widths=(8, 16),
            hdim=2,
            n_copies=2,
            copy_vertices=400,
            encodings_per_copy=2,
            steps=4,
            checkpoint_every=2,
            diffusion_steps=100,
            stats_samples=1,
            stats_ddim_steps=2,
            bucket=64,
        )
        run = dict(samples=2, ddpm=1, views=VIEWS[:2], size=96, atlas=128, ddim=3, subdivide=0)
    else:
        cfg = fldm.Config.cpu(latent_channels=latent_dim, copy_vertices=vertices)
        run = dict(
            samples=6,
            ddpm=2,
            views=VIEWS,
            size=256,
            atlas=512,
            ddim=50,
            subdivide=sampling_subdivisions(vertices, spot_vertices),
        )
    return cfg, run


def sampling_subdivisions(vertices: int, spot_vertices: int) -> int:
    """The midpoint subdivisions of Spot (``spot_vertices`` vertices; each subdivision multiplies
    them by about 4) whose vertex count is nearest (in ratio) the training copies' ``vertices``:
    the samples are drawn at the density the denoiser was trained at (its
    k-NN neighbourhoods span a fixed number of vertices, so a denser mesh shrinks them on the
    surface). 10,000 → 1 (11,714 vertices), 3,000 → 0 (Spot itself)."""
    return max(0, round(float(np.log(vertices / spot_vertices) / np.log(4.0))))


def subdivided(spot: Mesh, times: int) -> Mesh:
    """Spot midpoint-subdivided ``times`` times, with its UV atlas and texture (the sampling mesh)."""
    from jmeshtex.geometry import subdivide_midpoint, subdivide_uv

    v, f, uv = np.asarray(spot.vertices, np.float64), spot.faces, spot.uv
    for _ in range(times):
        s = subdivide_midpoint(v, f)
        v, f, uv = s.vertices, s.faces, subdivide_uv(uv)
    return Mesh(v, f, uv=uv, texture=spot.texture)


def render_mesh_of(spot, subdivide: int):
    """``(vertices z-up, faces, uv)`` of Spot for rendering, midpoint-subdivided ``subdivide`` times."""
    m = subdivided(spot, subdivide)
    v = np.asarray(m.vertices)
    v = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)  # Spot is y-up, the renderer z-up
    return v, m.faces, m.uv


def render_views(geom, texture: np.ndarray, views, size: int) -> np.ndarray:
    """``[len(views), size, size, 3]`` float32 renders in [0, 1] of Spot with ``texture``."""
    from jmeshtex.render import render_mesh

    v, f, uv = geom
    return (
        np.stack(
            [
                render_mesh(Mesh(v, f, uv=uv, texture=texture), view=view, size=(size, size))
                for view in views
            ]
        ).astype(np.float32)
        / 255.0
    )


class Context:
    """What both stages need: Spot, the FL-VAE, the config, the keys, the data and the folders."""

    def __init__(self, args):
        from jmeshtex import fl, fldm
        from jmeshtex.io import load_mesh

        spot_dir = spot_path()
        self.args = args
        self.work = args.work or ROOT / "runs" / ("fldm_spot" + ("_quick" if args.quick else ""))
        self.spot = load_mesh(
            spot_dir / "spot_triangulated.obj", texture=spot_dir / "spot_texture.png"
        )
        self.vae = fl.load_pretrained(decoder=args.decoder)
        self.cfg, self.run = presets(
            args.quick, self.vae.config.latent_dim, args.vertices, len(self.spot.vertices)
        )
        if args.steps is not None:
            self.cfg = self.cfg.replace(steps=args.steps)
        if args.set:
            self.cfg = self.cfg.replace(**dict(_field_change(item) for item in args.set))
        keys = jax.random.split(jax.random.key(args.seed), 4)
        self.k_codec, self.k_data, self.k_train, self.k_sample = keys
        t0, c0 = time.perf_counter(), _cpu()
        encode = fldm.fl_vae_encoder(self.vae, self.spot, key=self.k_codec)
        self.data = fldm.build_dataset(
            self.spot,
            self.cfg,
            encode=encode,
            key=self.k_data,
            cache_dir=self.work / "data",
            progress=False,
        )
        self._keep_recorded_scale()
        self.dataset_seconds = (time.perf_counter() - t0, _cpu() - c0)
        print(
            f"[dataset] {self.data.num_copies} copies × {self.cfg.experimental.encodings_per_copy} encodings, "
            f"V0={self.data.latents.shape[1]}: {self.dataset_seconds[0]:.1f} s wall, "
            f"{self.dataset_seconds[1]:.1f} CPU-s",
            flush=True,
        )

    def _keep_recorded_scale(self) -> None:
        """Resume with the latent scale the run recorded.

        The copies' cache is keyed by the encoder's identity (the FL-VAE's weights and config
        repr): a change of ``fl.Config``'s fields re-encodes the copies, and a change in the
        encoder's arithmetic moves the scale by round-off (1e-4 measured), which the checkpoint's
        fingerprint would refuse. Within 1 % the run's recorded scale is kept.
        """
        from jmeshtex.io import Checkpoints

        folder = self.work / "train"
        with Checkpoints(folder) as ckpt:
            step = ckpt.latest_step()
            if step is None:
                return
            recorded = ckpt.read_meta(step).get("fingerprint", {}).get("data", {})
        scale = np.asarray(recorded.get("scale", []), np.float64)
        if list(recorded.get("shape", [])) != list(self.data.latents.shape):
            return
        if scale.shape == self.data.scale.shape and not np.array_equal(scale, self.data.scale):
            if np.allclose(scale, self.data.scale, rtol=1e-2):
                change = float(np.max(np.abs(scale / self.data.scale - 1)))
                print(
                    f"[dataset] keeping the run's recorded latent scale (re-encoded: {change:.1e})"
                )
                self.data = self.data._replace(scale=scale)


def train_stage(ctx: Context) -> None:
    """Train on from the newest checkpoint in chunks of ``checkpoint_every`` steps; after each, a
    model snapshot with its card and a log line (wall and CPU seconds per step, statistics)."""
    from jmeshtex import fldm
    from jmeshtex.fldm.core import model_card

    cfg, work = ctx.cfg, ctx.work
    rates = work / "rates.jsonl"
    while True:
        t0, c0 = time.perf_counter(), _cpu()
        result = fldm.train(
            ctx.data,
            cfg,
            key=ctx.k_train,
            checkpoint_dir=work / "train",
            stop_after=2 * cfg.checkpoint_every,  # a snapshot every other checkpoint
            progress=False,
        )
        ran = result.steps - (result.resumed_from or 0)
        wall, cpu = time.perf_counter() - t0, _cpu() - c0
        card = model_card(result)
        fldm.save(result.model, work / "models" / f"step_{result.steps:05d}", card=card)
        stats = card["statistics"][-1] if card["statistics"] else {}
        line = {
            "step": result.steps,
            "ran": ran,
            "wall_s": wall,
            "cpu_s": cpu,
            "compile_s": result.compile_seconds,
            "steps_per_s": result.extra.get("steps_per_second"),
            "stats_s": stats.get("seconds"),
            "load": _load(),
            "device": jax.devices()[0].device_kind,
            "loss": float(np.mean(result.losses["loss"][-ran:])) if ran else None,
        }
        if ran:
            with open(rates, "a") as fh:
                fh.write(json.dumps(line) + "\n")
        print(
            f"[train] step {result.steps}/{cfg.steps}: {ran} steps in {wall:.0f} s wall "
            f"({wall / max(ran, 1):.3f} s/step, {cpu / max(ran, 1):.3f} CPU-s/step, compile "
            f"{result.compile_seconds:.0f} s, load {line['load']:.2f}), loss {line['loss']}, "
            f"R {stats.get('concentration', float('nan')):.3f}, |z|² corr "
            f"{stats.get('energy_correlation', float('nan')):.3f}",
            flush=True,
        )
        if result.steps >= cfg.steps:
            return


def _snapshot(ctx: Context, step: int | None):
    """``(model, card, step)``: the model snapshot of ``step`` (default: the newest step that has a
    snapshot or a checkpoint), else the EMA weights restored from the training checkpoint."""
    from jmeshtex import fldm
    from jmeshtex.io import Checkpoints

    folder = ctx.work / "models"
    found = sorted(int(p.name[5:]) for p in folder.glob("step_*") if (p / "model.npz").is_file())
    with Checkpoints(ctx.work / "train") as ckpt:
        kept = ckpt.steps()
    if step is None and (found or kept):
        step = max(found + kept)
    if step in found:
        path = folder / f"step_{step:05d}"
        card = (
            json.loads((path / "card.json").read_text()) if (path / "card.json").is_file() else {}
        )
        return fldm.load(path), card, step
    if step not in kept:
        sys.exit(
            f"fldm_spot: no snapshot of step {step} in {folder} (there are {found}) and no "
            f"checkpoint of it in {ctx.work / 'train'} (there are {kept}); train first (--train-only)"
        )
    from jmeshtex.fldm.core import init_denoiser, optimizer

    cfg = ctx.cfg
    k_init = jax.random.split(ctx.k_train, 3)[0]  # fldm.train's (init, batch, noise) split
    params = init_denoiser(k_init, cfg, dtype=jnp.complex64)
    like = {"params": params, "opt_state": optimizer(cfg).init(params)}
    if cfg.ema_decay > 0:
        like["ema"] = params
    with Checkpoints(ctx.work / "train") as ckpt:
        tree, meta = ckpt.restore(like, step=step)
    weights = tree["ema" if cfg.ema_decay > 0 else "params"]
    model = fldm.Model(jax.tree.map(np.asarray, weights), cfg, np.asarray(ctx.data.scale))
    return model, {"steps": step, "statistics": meta.get("statistics", [])}, step


def _nearest(src_vertices: np.ndarray, dst_vertices: np.ndarray) -> np.ndarray:
    """Index of the nearest ``src`` vertex of every ``dst`` vertex."""
    from scipy.spatial import cKDTree

    return cKDTree(src_vertices).query(dst_vertices)[1]


class _Copy0(NamedTuple):
    """What the probes of training copy 0 share: the model's config and schedule, the copy's
    geometry and vertex mask, and the statistics of a latent in the model's scale."""

    cfg: object
    sched: object
    geo: object
    scale: np.ndarray
    vm: np.ndarray

    @classmethod
    def of(cls, ctx: Context, model) -> _Copy0:

        cfg = model.config
        geo = jax.tree.map(lambda a: jnp.asarray(a[0]), ctx.data.geometry)
        return cls(
            cfg,
            cfg.noise_schedule(),
            geo,
            np.asarray(model.scale, np.float32),
            np.asarray(geo.fine.vertex_mask),
        )

    def noise(self, rng: np.random.Generator) -> jax.Array:
        shape = (self.vm.size, self.cfg.latent_channels)
        z = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2)
        return jnp.asarray(z * self.vm[:, None], jnp.complex64)

    def row(self, z_in, x0) -> dict:
        """The x̂₀ statistics with its input's beside them."""
        from jmeshtex.fldm import core as st

        s_in, s_out = (
            st.latent_statistics(jnp.asarray(np.asarray(a) / self.scale), self.geo.fine)
            for a in (z_in, x0)
        )
        return dict(
            concentration=s_out["concentration"],
            energy_corr=s_out["energy_correlation"],
            phase_coh=s_out["phase_coherence"],
            rms=s_out["rms"],
            input_energy_corr=s_in["energy_correlation"],
            input_concentration=s_in["concentration"],
        )


def denoising_probe(ctx: Context, model, report: Report, fractions=(0.025, 0.1, 0.25, 0.5, 0.75)):
    """Table ``denoising``: one denoiser call on training copy 0 noised to ``t = f·T``.

    Does the network restore what the samples lack? For each ``t``, the statistics of the one-step
    estimate ``x̂₀`` against those of its input ``z_t`` and of the data (the ``statistics`` table's
    last row): an ``x̂₀`` whose neighbour correlation of |z|² stays near its input's means the
    denoiser does not use the neighbourhood at that noise level; one near the data's while the
    samples stay low points at the sampler's path instead.
    """
    from jmeshtex.fldm import core as st

    c = _Copy0.of(ctx, model)
    z0 = jnp.asarray(ctx.data.latents[0] * c.scale * c.vm[:, None], jnp.complex64)
    denoise = jax.jit(lambda p, z, t, g: st.denoise(p, c.cfg, z, t, g))
    rng = np.random.default_rng(ctx.args.seed + 202)
    for f in fractions:
        t = int(round(f * (c.cfg.diffusion_steps - 1)))
        tt = jnp.asarray(t, jnp.int32)
        zt = st.q_sample(c.sched, z0, tt, c.noise(rng))
        out = denoise(model.params, zt, tt, c.geo)
        eps = st.epsilon_from_output(c.sched, c.cfg.prediction, zt, tt, out)
        ab = float(c.sched.alpha_bars[t])
        x0 = np.asarray((zt - np.sqrt(1 - ab) * eps) / np.sqrt(ab))
        err = float(np.sum(np.abs(x0 - np.asarray(z0)) ** 2) / np.sum(np.abs(np.asarray(z0)) ** 2))
        report.add(
            table="denoising",
            source=f"t = {t} (ᾱ = {ab:.3f})",
            **c.row(zt, x0),
            x0_error=err,
            what="one-step x̂₀ on training copy 0 (input: z_t; x0_error: relative squared error)",
        )


def trajectory_trace(ctx: Context, model, report: Report, steps: int = 50, every: int = 5):
    """Table ``trajectory``: one DDIM trajectory (η = 0) on training copy 0, traced.

    At every ``every``-th step, the statistics of the state ``z_t`` and of the step's estimate
    ``x̂₀``: where along the path the samples' spatial structure (|z|² neighbour correlation) is
    made, and whether later steps keep it.
    """
    from jmeshtex.fldm import core as st

    c = _Copy0.of(ctx, model)
    denoise = jax.jit(lambda p, z, t: st.denoise(p, c.cfg, z, t, c.geo))
    z = c.noise(np.random.default_rng(ctx.args.seed + 303))
    ts = st.timestep_sequence(c.cfg.diffusion_steps, min(steps, c.cfg.diffusion_steps))
    for i, t in enumerate(ts):
        tt = jnp.asarray(int(t), jnp.int32)
        eps = st.epsilon_from_output(c.sched, c.cfg.prediction, z, tt, denoise(model.params, z, tt))
        ab = float(c.sched.alpha_bars[t])
        if i % every == 0 or i == len(ts) - 1:
            report.add(
                table="trajectory",
                source=f"step {i} of {len(ts)}, t = {int(t)} (ᾱ = {ab:.3f})",
                **c.row(z, (z - np.sqrt(1 - ab) * eps) / np.sqrt(ab)),
                what="DDIM (η = 0) on training copy 0: the step's x̂₀ (input: the state z_t)",
            )
        t_prev = jnp.asarray(int(ts[i + 1]) if i + 1 < len(ts) else -1, jnp.int32)
        z = st.ddim_step(c.sched, z, tt, t_prev, eps, jnp.zeros_like(z))


class _Fields(NamedTuple):
    """The sources scored on the sampling mesh: latent fields and what decoding them needs."""

    target: Mesh  # Spot at about the training density, with its atlas
    nb: object  # the denoiser's fine neighbourhoods of ``target`` (the statistics' pairs)
    recon: np.ndarray  # the codec's latents of ``target`` (as the model was trained on them)
    fields: dict[str, np.ndarray]  # source -> [n, V, C] latents


def _sample_fields(ctx: Context, model, stage) -> _Fields:
    """Samples (DDIM, DDPM) and the baseline fields (reconstruction, shuffled latents, random
    channel phases) on Spot midpoint-subdivided to about the training density."""
    from jmeshtex import fldm
    from jmeshtex.fldm import core as st
    from jmeshtex.fldm.core import denoiser_geometry, sampling_geometry

    args, cfg, run, spot = ctx.args, ctx.cfg, ctx.run, ctx.spot
    n = run["samples"] if args.samples is None else args.samples
    target = subdivided(spot, run["subdivide"])
    denoiser = denoiser_geometry(target, knn=cfg.knn, pool_ratio=cfg.pool_ratio)
    nb = denoiser.fine
    t0, c0 = time.perf_counter(), _cpu()
    geo = sampling_geometry(target, model)
    z = {"DDIM": fldm.sample(model, geo, key=ctx.k_sample, num_samples=n, steps=run["ddim"])}
    stage("sample DDIM", t0, c0)
    t0, c0 = time.perf_counter(), _cpu()
    n_ddpm = run["ddpm"] if args.ddpm_samples is None else args.ddpm_samples
    if n_ddpm:
        k = jax.random.fold_in(ctx.k_sample, 1)
        z["DDPM"] = fldm.sample(model, geo, key=k, num_samples=n_ddpm, method="ddpm")
    stage("sample DDPM", t0, c0)
    z = {k: np.asarray(v.latents) for k, v in z.items()}
    # the codec's latents as the model was trained on them (phase_sync)
    recon = fldm.encode(ctx.vae, target, cfg, key=ctx.k_codec, geometry=denoiser)
    kb = jax.random.key(args.seed + 101)
    fields = {
        "reconstruction": recon[None],
        "shuffled latents": np.asarray(st.shuffle_latents(jnp.asarray(recon), key=kb))[None],
        "random channel phases": np.asarray(st.random_channel_phases(jnp.asarray(recon), key=kb))[
            None
        ],
        f"samples DDIM-{run['ddim']}": z["DDIM"],
    }
    if "DDPM" in z:
        fields["samples DDPM-1000"] = z["DDPM"]
    return _Fields(target, nb, recon, fields)


def _latent_stats(ctx: Context, f: _Fields) -> dict[str, dict]:
    """Decoder-free statistics of every source's latents, and the nearest-training-copy check on
    ``|z|²`` (the largest correlation with a training copy carried to the sampling mesh)."""
    from jmeshtex.fldm import core as st

    copies = []
    for i, m in enumerate(ctx.data.meshes):
        idx = _nearest(np.asarray(m.vertices), np.asarray(f.target.vertices))
        copies.append(ctx.data.latents[i, : m.num_vertices][idx])

    def stats(zs):
        per = [st.latent_statistics(jnp.asarray(zi), f.nb) for zi in zs]
        near = [
            max(float(st.energy_field_correlation(jnp.asarray(zi), jnp.asarray(c))) for c in copies)
            for zi in zs
        ]
        out = {k: float(np.mean([p[k] for p in per])) for k in per[0] if k != "power"}
        out["nearest_copy_corr"] = float(np.mean(near))
        out["nearest_copy_corr_max"] = float(np.max(near))
        return out

    return {src: stats(zs) for src, zs in f.fields.items()}


def _decode(ctx: Context, f: _Fields) -> tuple[dict[str, list], np.ndarray, np.ndarray]:
    """Every source decoded to the atlas (unused texels filled), plus the masked best constant:
    the mean colour over the texels the atlas uses. Returns ``(textures, valid, truth)``, the
    truth being Spot's texture at the atlas' resolution."""
    from jmeshtex import fldm
    from jmeshtex.geometry import fill_unused_texels
    from jmeshtex.metrics import flat_baseline

    size = ctx.run["atlas"]

    def atlases(latents):
        decoded = fldm.decode_samples(ctx.vae, f.target, latents, size=size)
        return [fill_unused_texels(d["texture"], d["valid"]) for d in decoded]

    tex = {src: atlases(zs) for src, zs in f.fields.items()}
    valid = np.asarray(fldm.decode_samples(ctx.vae, f.target, f.recon[None], size=size)[0]["valid"])
    full = np.asarray(ctx.spot.texture[..., :3])
    rows = np.arange(valid.shape[0]) * full.shape[0] // valid.shape[0]
    cols = np.arange(valid.shape[1]) * full.shape[1] // valid.shape[1]
    truth = full[rows][:, cols]
    flat = flat_baseline(truth, mask=valid)[valid][0]
    tex["masked flat colour"] = [np.broadcast_to(flat, (8, 8, 3)).astype(full.dtype)]
    return tex, valid, truth


#: the baselines' rows, in order, and what each is
BASELINES = {
    "masked flat colour": "best constant over the used texels",
    "reconstruction": "encode the sampling mesh → decode: the codec's ceiling",
    "shuffled latents": "reconstruction permuted over vertices: no spatial structure",
    "random channel phases": "reconstruction, each latent turned by a random phase",
}


def _quality_rows(ctx, report, tex, renders, ref, valid, truth, latent_stats, order, step):
    """Table ``quality``: render Gram fidelity and diversity, the surface-patch measure and the
    palette, and the latent statistics per source; the exemplar's floor row last."""
    from jmeshtex.metrics import (
        gram_distance,
        load_vgg16,
        lpips,
        palette_distance,
        patch_gram_distance,
        patch_spectrum_distance,
        surface_patches,
    )

    spot = ctx.spot
    weights = load_vgg16()
    ref_j = jnp.asarray(ref)

    def gram(imgs):
        return float(np.mean(np.asarray(gram_distance(jnp.asarray(imgs), ref_j, weights=weights))))

    # the surface-patch measure (the surface CNN's, DESIGN.md "one measure per question"): geodesic
    # patches of 32² atlas texels at 32 places on Spot; every source read at one set of places, the
    # exemplar (Spot's texture at the atlas' resolution) at another; the floor is the exemplar at
    # the first set against the second. Palette: total variation between RGB histograms (8³ cells)
    # over the used texels, which sees speckle and colour casts that patch statistics average away.
    corners = (spot.vertices[spot.faces[:, k]] - spot.vertices[spot.faces[:, 0]] for k in (1, 2))
    area = 0.5 * np.linalg.norm(np.cross(*corners), axis=1).sum()
    texel = float(np.sqrt(area / valid.sum()))
    k_a, k_b = jax.random.split(jax.random.key(ctx.args.seed + 202))
    at_a = surface_patches(spot, num=32, step=texel, key=k_a, size=32)
    ex_b = surface_patches(spot, num=32, step=texel, key=k_b, size=32).sample(truth)

    def surface(img):
        full_img = img if img.shape == truth.shape else np.broadcast_to(img[0, 0], truth.shape)
        p = at_a.sample(full_img)
        return (
            patch_gram_distance(p, ex_b, weights=weights),
            patch_spectrum_distance(p, ex_b),
            palette_distance(
                img, truth, mask_a=valid if img.shape[:2] == valid.shape else None, mask_b=valid
            ),
        )

    def diversity(rs):
        return [
            float(np.mean(np.asarray(lpips(jnp.asarray(a), jnp.asarray(b), weights=weights))))
            for i, a in enumerate(rs)
            for b in rs[i + 1 :]
        ]

    for src in order:
        g = [gram(r) for r in renders[src]]
        d = diversity(renders[src]) if len(renders[src]) > 1 else []
        ls = latent_stats.get(src, {})
        sp = np.array([surface(t) for t in tex[src]])
        report.add(
            table="quality",
            source=src,
            n=len(g),
            fidelity_gram=float(np.mean(g)),
            fidelity_gram_std=float(np.std(g)),
            patch_gram=float(sp[:, 0].mean()),
            patch_spectrum=float(sp[:, 1].mean()),
            palette_tv=float(sp[:, 2].mean()),
            diversity_lpips=float(np.mean(d)) if d else "",
            concentration=ls.get("concentration", ""),
            energy_corr=ls.get("energy_correlation", ""),
            phase_coh=ls.get("phase_coherence", ""),
            rms=ls.get("rms", ""),
            nearest_copy_corr=ls.get("nearest_copy_corr", ""),
            what=BASELINES.get(src, f"step {step}"),
        )
    report.add(
        table="quality",
        source="exemplar (floor)",
        n=1,
        patch_gram=patch_gram_distance(at_a.sample(truth), ex_b, weights=weights),
        patch_spectrum=patch_spectrum_distance(at_a.sample(truth), ex_b),
        palette_tv=0.0,
        what="the exemplar's patches at the first places against the second: the measure's floor",
    )


def _curve_rows(ctx: Context, report: Report, card: dict) -> None:
    """Table ``statistics``: the decoder-free statistics at every checkpoint (the model card's)."""
    cfg = ctx.cfg
    for rec in card.get("statistics", []):
        report.add(
            table="statistics",
            source=f"step {rec['step']}",
            concentration=rec.get("concentration"),
            energy_corr=rec.get("energy_correlation"),
            phase_coh=rec.get("phase_coherence"),
            rms=rec.get("rms"),
            what=f"{cfg.experimental.stats_samples} DDIM-{cfg.experimental.stats_ddim_steps} samples on training copy 0",
        )
    data_ref = next((r["data"] for r in card.get("statistics", []) if "data" in r), None)
    if data_ref:
        report.add(
            table="statistics",
            source="training copy 0 (data)",
            concentration=data_ref["concentration"],
            energy_corr=data_ref["energy_correlation"],
            phase_coh=data_ref["phase_coherence"],
            rms=data_ref["rms"],
            what="the target of the curve",
        )


def _rate_row(ctx: Context, report: Report) -> None:
    """Table ``training``: the step rate over every training session in the work folder."""
    cfg = ctx.cfg
    rates_path = ctx.work / "rates.jsonl"
    if not rates_path.is_file():
        return
    lines = [json.loads(x) for x in rates_path.read_text().splitlines() if x.strip()]
    ran = sum(x["ran"] for x in lines)
    wall = sum(x["wall_s"] - (x.get("compile_s") or 0) - (x.get("stats_s") or 0) for x in lines)
    cpu = sum(x["cpu_s"] for x in lines)
    devices = sorted({x.get("device", "cpu") for x in lines})  # the machine(s) it trained on
    report.add(
        table="training",
        source=f"{cfg.copy_vertices} vertices, batch {cfg.batch_size}, on {' + '.join(devices)}",
        n=ran,
        s_per_step=wall / max(ran, 1),
        cpu_s_per_step=cpu / max(ran, 1),
        load=float(np.mean([x["load"] for x in lines])),
        what="wall (compile and statistics excluded) and process CPU (all included) per step",
    )


def _figure(ctx: Context, ref, renders, order) -> None:
    """The PNG: exemplar, baselines, samples (first view; a second view of the samples)."""
    from jmeshtex.render import render_grid

    args = ctx.args
    args.out.mkdir(parents=True, exist_ok=True)
    images = [ref[0], renders["reconstruction"][0][0], renders["masked flat colour"][0][0]]
    titles = ["exemplar", "FL-VAE recon.", "masked flat"]
    images += [renders["shuffled latents"][0][0], renders["random channel phases"][0][0]]
    titles += ["shuffled", "random phases"]
    for src in order[4:]:
        for i, r in enumerate(renders[src]):
            images += [r[0], r[2 % len(r)]]
            titles += [f"{src.split()[1]} {i + 1}", f"{src.split()[1]} {i + 1} (back)"]
    render_grid(
        [(255 * np.clip(i, 0, 1)).astype(np.uint8) for i in images],
        args.out / f"{args.name}.png",
        titles=titles,
        columns=5,
    )


def _notes(ctx: Context, report: Report, order, step: int, sampling_vertices: int) -> None:
    """What the columns are, and each sampler's verdict against issue 35's and 55's targets."""
    cfg, run = ctx.cfg, ctx.run
    report.notes += [
        f"model: snapshot of step {step} of {cfg.steps} (`{ctx.work / 'models'}`), config "
        f"`fldm.Config.cpu` at {cfg.copy_vertices} vertices per copy, {cfg.n_copies} copies × "
        f"{cfg.experimental.encodings_per_copy} encodings; samples on Spot midpoint-subdivided "
        f"{run['subdivide']}× ({sampling_vertices} vertices), atlas {run['atlas']}², "
        f"{len(run['views'])} views at {run['size']}².",
        "",
        "concentration: cross-channel relative-phase concentration R; energy_corr: neighbour "
        "correlation of |z|² (k-NN pairs of the sampling mesh); phase_coh: transported phase "
        "coherence; nearest_copy_corr: largest correlation of Σ|z|² with a training copy's "
        "(nearest vertex). Targets (issue 35): R ≥ 0.6, |z|² corr ≥ 0.4, Gram below the masked "
        "flat colour and the shuffled latents, diversity LPIPS ≥ 0.1, no sample a training copy.",
        "",
        "patch_gram, patch_spectrum: the surface-patch measure (`jmeshtex.metrics` "
        "`patch_gram_distance`, `patch_spectrum_distance`): 32 geodesic patches of 32² atlas "
        "texels on Spot, each source at one set of places against the exemplar at another; row "
        "`exemplar (floor)` is the exemplar against itself at the two sets. palette_tv: "
        "`palette_distance`, total variation between the used texels' RGB histograms (8³ cells), "
        "0 for the exemplar's palette (speckle and colour casts raise it). Targets (issue 55): "
        "patch Gram and spectrum ≥ 2× closer than the masked flat colour and the shuffled latents.",
        "",
    ]
    q = {r["source"]: r for r in report.rows if r["table"] == "quality"}
    flat, shuffled = q["masked flat colour"], q["shuffled latents"]
    for src in order[4:]:
        r = q[src]
        checks = {
            "R ≥ 0.6": r["concentration"] >= 0.6,
            "|z|² corr ≥ 0.4": r["energy_corr"] >= 0.4,
            "Gram < masked flat": r["fidelity_gram"] < flat["fidelity_gram"],
            "Gram < shuffled": r["fidelity_gram"] < shuffled["fidelity_gram"],
            "patch Gram ≥ 2× closer than flat and shuffled": 2 * r["patch_gram"]
            <= min(flat["patch_gram"], shuffled["patch_gram"]),
            "patch spectrum ≥ 2× closer than flat and shuffled": 2 * r["patch_spectrum"]
            <= min(flat["patch_spectrum"], shuffled["patch_spectrum"]),
            "LPIPS ≥ 0.1": r["diversity_lpips"] != "" and r["diversity_lpips"] >= 0.1,
            "no copy (nearest-copy corr < half the reconstruction's)": r["nearest_copy_corr"]
            < 0.5 * q["reconstruction"]["nearest_copy_corr"],
        }
        met = ", ".join(f"{k}: {'yes' if v else 'no'}" for k, v in checks.items())
        report.notes.append(f"- {src} at step {step}: {met}.")


def eval_stage(ctx: Context, step: int | None) -> None:
    """Sample, decode, render and score a model snapshot of the work folder into ``args.name``."""
    args, cfg, run, spot = ctx.args, ctx.cfg, ctx.run, ctx.spot
    report = Report(args.name, ceilings=not args.quick)
    model, card, step = _snapshot(ctx, step)
    timings: dict[str, tuple[float, float, float]] = {}

    def stage(label: str, t0: float, c0: float) -> None:
        timings[label] = (time.perf_counter() - t0, _cpu() - c0, _load())
        print(f"[{label}] {timings[label][0]:.1f} s, {timings[label][1]:.1f} CPU-s", flush=True)

    f = _sample_fields(ctx, model, stage)
    t0, c0 = time.perf_counter(), _cpu()
    latent_stats = _latent_stats(ctx, f)
    stage("statistics", t0, c0)
    t0, c0 = time.perf_counter(), _cpu()
    tex, valid, truth = _decode(ctx, f)
    stage("decode", t0, c0)
    t0, c0 = time.perf_counter(), _cpu()
    rgeom = render_mesh_of(spot, run["subdivide"])
    ref = render_views(rgeom, spot.texture[..., :3], run["views"], run["size"])
    renders = {
        src: [render_views(rgeom, t, run["views"], run["size"]) for t in ts]
        for src, ts in tex.items()
    }
    stage("render", t0, c0)
    t0, c0 = time.perf_counter(), _cpu()
    order = [*BASELINES, *(k for k in f.fields if k.startswith("samples"))]
    _quality_rows(ctx, report, tex, renders, ref, valid, truth, latent_stats, order, step)
    stage("metrics", t0, c0)
    _curve_rows(ctx, report, card)
    denoising_probe(ctx, model, report)
    trajectory_trace(ctx, model, report)
    _rate_row(ctx, report)
    for label, (seconds, cpu, load) in timings.items():
        report.add(table="timing", source=label, seconds=seconds, cpu_s=cpu, load=round(load, 2))
    _figure(ctx, ref, renders, order)
    report.config = {
        "fldm": cfg.to_dict(),
        "step": step,
        "sampling_vertices": f.target.num_vertices,
        "vae": ctx.vae.config.to_dict(),
    }
    _notes(ctx, report, order, step, f.target.num_vertices)
    report.write(args.out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="tiny smoke settings")
    ap.add_argument("--out", type=pathlib.Path, default=RESULTS, help="folder of the results")
    ap.add_argument(
        "--name", default="fldm_spot", help="results' file name (NAME.md, .json, .png) in --out"
    )
    ap.add_argument("--work", type=pathlib.Path, default=None, help="copies, checkpoints, models")
    ap.add_argument("--steps", type=int, default=None, help="training steps (default: preset's)")
    ap.add_argument("--vertices", type=int, default=10000, help="vertices per training copy")
    ap.add_argument("--samples", type=int, default=None, help="DDIM samples (default: preset's)")
    ap.add_argument("--ddpm-samples", type=int, default=None, help="DDPM-1000 samples")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="FIELD=JSON",
        help="change a field of the preset's fldm.Config, e.g. --set invariants=true (repeatable)",
    )
    ap.add_argument(
        "--decoder",
        choices=("log", "barycentric"),
        default="log",
        help="which shipped FL-VAE encodes and decodes (barycentric: pair with --set phase_sync=all)",
    )
    ap.add_argument("--train-only", action="store_true", help="train (resume), no evaluation")
    ap.add_argument("--eval-only", action="store_true", help="evaluate a snapshot, no training")
    ap.add_argument("--checkpoint-step", type=int, default=None, help="snapshot to evaluate")
    ap.add_argument(
        "--probe-only",
        action="store_true",
        help="print the denoising and trajectory tables of a snapshot (a minute), write nothing",
    )
    args = ap.parse_args(argv)
    spot_path()  # fail before the heavy imports
    ctx = Context(args)
    if args.probe_only:
        model, _, step = _snapshot(ctx, args.checkpoint_step)
        report = Report(args.name, ceilings=False)
        denoising_probe(ctx, model, report)
        trajectory_trace(ctx, model, report)
        for row in report.rows:
            print(
                f"step {step} {row['source']}: x̂₀ R {row['concentration']:.3f}, |z|² corr "
                f"{row['energy_corr']:.3f}; input R {row['input_concentration']:.3f}, |z|² corr "
                f"{row['input_energy_corr']:.3f}; error {row.get('x0_error', float('nan')):.3f}"
            )
        return 0
    if not args.eval_only:
        train_stage(ctx)
    if not args.train_only:
        eval_stage(ctx, args.checkpoint_step)
    return 0


if __name__ == "__main__":
    sys.exit(main())

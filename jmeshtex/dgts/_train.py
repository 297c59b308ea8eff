"""Hierarchical WGAN-GP training of DGTS (Hertz et al. 2020, §3.4), resumable per level.

Levels are trained one after another. At level ``L`` the input template runs through the frozen
generators ``0 … L−1`` (subdividing and rescaling in between) and the trainable generator ``L``; a
patch discriminator scores every face of the result against the level-``L`` training mesh:

.. math:: \\mathcal L_D = \\overline{D(G(z))} - \\overline{D(x_L)} + \\lambda\\,
   \\overline{\\big(\\lVert \\nabla_{\\hat\\phi_f} \\textstyle\\sum_g D(\\hat\\phi)_g \\rVert - 1\\big)^2},
   \\quad \\hat\\phi = \\alpha \\phi(x_L) + (1 - \\alpha) \\phi(G(z))

.. math:: \\mathcal L_G = -\\overline{D(G(z))} + \\gamma\\, \\mathrm{MSE}\\big(G(z^*, 0, …, 0), x_L\\big)

(gradient penalty on interpolated face features, one ``α ~ U(0, 1)`` per critic step, per-face
gradient norms; reconstruction with the fixed noise ``z*`` at the coarsest level and zero noise
above). Adam with step decay; ``discriminator_steps`` critic updates then ``generator_steps``
generator updates per iteration.

How it runs (compilation dominated the first version: each level compiled a step that unrolled
every frozen generator three times, 265 s of 872 s in the small benchmark):

- the frozen levels ``0 … L−1`` only make inputs for level ``L``; :func:`level_batch` runs them
  forward, level by level, on all noise draws of ``CHUNK`` iterations at once (one compiled
  function per frozen level, reused by every later level since the batch size does not change);
- :func:`train_chunk` holds level ``L``'s generator and critic only, and runs ``CHUNK`` iterations
  per call (``fori_loop``), so every level compiles one program of the same size;
- ``TrainConfig.shared_levels`` pads the small levels (masked faces and vertices, the
  padded-neighbourhood contract: no loss or update changes, tested) to one size so equal-width
  levels reuse one compiled step (tests, demo);
- compilation is ahead of time (``lower().compile()``), timed apart from the iterations
  (:class:`LevelReport`), and cached per shapes in the process; the CLI also enables JAX's
  persistent compilation cache (``jmeshtex dgts --help``).

Checkpoints (``out_dir``): after each level ``level_XX.npz`` (generator and discriminator
parameters) and then ``state.json`` (config, completed levels, timings) are written atomically, with
``z_star.npz`` before the first level; :func:`train` with the same ``out_dir`` resumes after the
last complete level.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import pathlib
import time
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._errors import ConfigError, InputError, MeshIOError
from .._neighborhoods import FaceNeighborhood
from .._types import Array, Float
from ..geometry import pad_to
from ..io import atomic_save_npz, atomic_write, load_npz
from ..ops import FaceConvStackParams, face_features, masked_mean
from ._config import TrainConfig
from ._model import (
    discriminator,
    discriminator_features,
    generator_level,
    hierarchy_geometry,
    init_level,
    upsample,
)
from ._multiscale import TrainingMeshes

STATE_FILE = "state.json"


class DGTSModel(NamedTuple):
    """A trained (or partly trained) DGTS hierarchy.

    Attributes:
      config: the :class:`TrainConfig` it was trained with.
      generators: one parameter set per trained level, coarsest first.
      discriminators: the matching discriminators (kept to warm-start and resume).
      z_star: ``[V_0, 3]`` the fixed reconstruction noise of the coarsest level.
    """

    config: TrainConfig
    generators: tuple[FaceConvStackParams, ...]
    discriminators: tuple[FaceConvStackParams, ...]
    z_star: np.ndarray

    @property
    def num_levels(self) -> int:
        return len(self.generators)


@dataclasses.dataclass
class LevelReport:
    """What training one level measured (seconds and final losses).

    Attributes:
      compile_seconds: compilation of the level's step and of its newest frozen level (the first
        chunk's frozen-level pass is counted here too), 0 where the process had compiled them.
      seconds: wall time of the whole level, compilation included.
      seconds_per_iteration: ``(seconds − compile_seconds) / iterations``.
      losses: the last iteration's losses (:data:`LOSS_NAMES`).
    """

    level: int
    iterations: int
    faces: int
    compile_seconds: float
    seconds: float
    seconds_per_iteration: float
    losses: dict[str, float]


class _Opt(NamedTuple):
    g: Any
    d: Any


def _optimizer(config: TrainConfig, steps_per_iteration: int) -> optax.GradientTransformation:
    schedule = optax.exponential_decay(
        config.lr,
        transition_steps=config.lr_decay_every * max(steps_per_iteration, 1),
        decay_rate=config.lr_decay,
        staircase=True,
    )
    return optax.adam(schedule, b1=config.beta1, b2=config.beta2)


def gradient_penalty(
    d_params: FaceConvStackParams, real_features, fake_features, nbhd, alpha, *, negative_slope: float, eps: float
):
    """WGAN-GP term on features interpolated between a real and a fake mesh (same connectivity).

    .. math:: \\overline{(\\lVert \\nabla_{\\hat\\phi_f} \\textstyle\\sum_g D(\\hat\\phi)_g\\rVert_2 - 1)^2}

    The norm is taken per face over its ``3 × 4`` features (the reference code's ``norm(dim=1)``);
    the mean runs over real faces only (``nbhd.face_mask``), so padded faces change nothing.
    """
    x = alpha * real_features + (1 - alpha) * fake_features

    def total(x):
        return jnp.sum(discriminator_features(d_params, x, nbhd, negative_slope=negative_slope, eps=eps))

    g = jax.grad(total)(x)
    sq = jnp.sum(g * g, axis=(1, 2))
    norm = jnp.sqrt(sq + jnp.asarray(1e-12, sq.dtype))
    return masked_mean((norm - 1) ** 2, nbhd.face_mask)


#: training iterations run by one compiled call (a ``fori_loop`` inside): fewer dispatches, and the
#: frozen levels run once per chunk, batched over all its noise draws.
CHUNK = 10


class LevelBatch(NamedTuple):
    """Inputs of ``CHUNK`` training iterations of level ``L`` (``S = D + G`` fake meshes each).

    Attributes:
      fake_base: ``[K, S, V_L, 3]`` outputs of the frozen levels ``0 … L−1`` (subdivided and scaled
        into level ``L``'s frame) for fresh noise; the template itself at level 0.
      fake_noise: ``[K, S, V_L, 3]`` the level-``L`` noise of those fakes.
      rec_base, rec_noise: ``[K, G, V_L, 3]`` the same for the reconstruction (``z*`` at level 0
        and zero above from ``reconstruction_start`` on, fresh noise below it).
      alpha: ``[K, D]`` gradient-penalty interpolation weights.
    """

    fake_base: Float[Array, "K S V 3"]
    fake_noise: Float[Array, "K S V 3"]
    rec_base: Float[Array, "K G V 3"]
    rec_noise: Float[Array, "K G V 3"]
    alpha: Float[Array, "K D"]


@functools.partial(jax.jit, static_argnames=("config",))
def _advance(params, vertices, noise, geometry, *, config: TrainConfig):
    """One frozen level on a batch: ``s·U(v + G(v, z))`` for every row (forward only)."""
    kw = {"negative_slope": config.negative_slope, "eps": config.eps}
    out = jax.vmap(lambda v, z: v + generator_level(params, v, geometry.nbhd, z, **kw))(vertices, noise)
    return jax.vmap(lambda v: upsample(v, geometry.edge_vertices, scale=config.scale_factor))(out)


@functools.partial(jax.jit, static_argnames=("shape", "amplitude"))
def _noise(key, fixed, *, shape: tuple[int, ...], amplitude: float):
    """``[n + m, V, 3]``: ``n`` fresh Gaussian draws, then the ``m`` fixed rows ``fixed [m, V, 3]``."""
    fresh = amplitude * jax.random.normal(key, shape, fixed.dtype)
    return jnp.concatenate([fresh, fixed], axis=0)


def level_batch(model_levels, geos, template, z_star, key, *, config: TrainConfig, chunk: int) -> LevelBatch:
    """Draw the noise of ``chunk`` iterations of level ``L = len(model_levels)`` and run the frozen
    levels ``0 … L−1`` on it (forward only).

    All draws of the chunk (``chunk·(D + G)`` fakes, and the reconstruction) go through each frozen
    level as one batch, level by level: the compiled level step depends only on that level's sizes
    and on the batch size, so it is compiled once and reused by every later level and chunk.

    Returns:
      :class:`LevelBatch`; with ``L ≥ reconstruction_start`` the reconstruction is the one fixed
      row (``z*`` at level 0, zero noise above), broadcast.
    """
    c = config
    L = len(model_levels)
    D, G = c.discriminator_steps, c.generator_steps
    dtype = template.dtype
    sizes = [int(g.nbhd.vertex_mask.shape[0]) for g in geos[: L + 1]]
    fixed_rec = L >= c.reconstruction_start
    n_fresh = chunk * (D + G) + (0 if fixed_rec else chunk * G)
    keys = jax.random.split(key, L + 2)
    v = jnp.broadcast_to(template, (n_fresh + int(fixed_rec), *template.shape))
    zs = []
    for level in range(L + 1):
        fixed = jnp.zeros((int(fixed_rec), sizes[level], 3), dtype)
        if level == 0 and fixed_rec:
            fixed = z_star.astype(dtype)[None]
        z = _noise(keys[level], fixed, shape=(n_fresh, sizes[level], 3), amplitude=float(c.noise_amplitude))
        if level < L:
            v = _advance(model_levels[level], v, z, geos[level], config=c)
        zs.append(z)
    z = zs[L]
    n_fake = chunk * (D + G)
    fake_base = v[:n_fake].reshape(chunk, D + G, sizes[L], 3)
    fake_noise = z[:n_fake].reshape(chunk, D + G, sizes[L], 3)
    if fixed_rec:
        rec_base = jnp.broadcast_to(v[n_fake], (chunk, G, sizes[L], 3))
        rec_noise = jnp.broadcast_to(z[n_fake], (chunk, G, sizes[L], 3))
    else:
        rec_base = v[n_fake:].reshape(chunk, G, sizes[L], 3)
        rec_noise = z[n_fake:].reshape(chunk, G, sizes[L], 3)
    alpha = jax.random.uniform(keys[L + 1], (chunk, D), dtype)
    return LevelBatch(fake_base, fake_noise, rec_base, rec_noise, alpha)


@functools.partial(jax.jit, static_argnames=("config",))
def train_chunk(g, d, opt, nbhd, real, batch: LevelBatch, n, *, config: TrainConfig):
    """``n ≤ K`` WGAN-GP iterations of one level on the inputs ``batch`` (one compiled call).

    Each iteration: ``discriminator_steps`` critic updates, then ``generator_steps`` generator
    updates (module docstring losses). Only level ``L``'s networks are in here: the frozen levels
    are inputs (:func:`level_batch`), so every level compiles the same small program, and the
    level-``L`` mesh may be padded (``nbhd.face_mask`` / ``vertex_mask``) without changing a loss.

    Returns:
      ``(g, d, opt, losses)`` with the losses of the last iteration.
    """
    c = config
    kw = {"negative_slope": c.negative_slope, "eps": c.eps}
    opt_d = _optimizer(c, c.discriminator_steps)
    opt_g = _optimizer(c, c.generator_steps)
    vmask = nbhd.vertex_mask

    def produce(g, base, z):
        return base + generator_level(g, base, nbhd, z, **kw)

    def d_loss(d, fake, alpha):
        real_f, fake_f = face_features(real, nbhd), face_features(fake, nbhd)
        s_real = masked_mean(discriminator_features(d, real_f, nbhd, **kw), nbhd.face_mask)
        s_fake = masked_mean(discriminator_features(d, fake_f, nbhd, **kw), nbhd.face_mask)
        gp = gradient_penalty(d, real_f, fake_f, nbhd, alpha, **kw)
        return s_fake - s_real + c.penalty_weight * gp, jnp.stack([s_real, s_fake, gp])

    def g_loss(g, d, base, z, rec_base, rec_z):
        # two calls, not a vmap over both: the vmapped gathers cost ~25 % more compile and run (CPU)
        fake, rec = produce(g, base, z), produce(g, rec_base, rec_z)
        adv = -masked_mean(discriminator(d, fake, nbhd, **kw), nbhd.face_mask)
        mse = masked_mean(jnp.mean((rec - real) ** 2, axis=1), vmask)
        return adv + c.reconstruction_weight * mse, jnp.stack([adv, mse])

    def update(opt, grads, state, params):
        with jax.numpy_dtype_promotion("standard"):  # optax mixes int counters and floats
            updates, state = opt.update(grads, state, params)
        return optax.apply_updates(params, updates), state

    def iteration(i, carry):
        g, d, opt, _ = carry
        b = jax.tree.map(lambda x: x[i], batch)
        D = c.discriminator_steps

        def d_step(carry, inputs):
            d, state = carry
            base, z, alpha = inputs
            fake = jax.lax.stop_gradient(produce(g, base, z))
            (_, aux), grads = jax.value_and_grad(d_loss, has_aux=True)(d, fake, alpha)
            return update(opt_d, grads, state, d), aux

        def g_step(carry, inputs):
            g, state = carry
            base, z, rbase, rz = inputs
            (_, aux), grads = jax.value_and_grad(g_loss, has_aux=True)(g, d, base, z, rbase, rz)
            return update(opt_g, grads, state, g), aux

        (d, sd), d_aux = jax.lax.scan(d_step, (d, opt.d), (b.fake_base[:D], b.fake_noise[:D], b.alpha))
        (g, sg), g_aux = jax.lax.scan(g_step, (g, opt.g), (b.fake_base[D:], b.fake_noise[D:], b.rec_base, b.rec_noise))
        last_d = d_aux[-1] if D else jnp.zeros(3, real.dtype)
        return g, d, _Opt(sg, sd), jnp.concatenate([last_d, g_aux[-1]])

    g, d, opt, losses = jax.lax.fori_loop(0, n, iteration, (g, d, opt, jnp.zeros(5, real.dtype)))
    return g, d, opt, dict(zip(LOSS_NAMES, losses, strict=True))


#: the losses :func:`train_chunk` reports (critic on real / fake, penalty, generator adversarial / MSE)
LOSS_NAMES = ("d_real", "d_fake", "penalty", "g_adv", "g_rec")


# ----------------------------------------------------------------------------------------------
# checkpoints
# ----------------------------------------------------------------------------------------------


def _save_params(path: pathlib.Path, g: FaceConvStackParams, d: FaceConvStackParams) -> None:
    arrays = {}
    for prefix, tree in (("g", g), ("d", d)):
        for i, leaf in enumerate(jax.tree.leaves(tree)):
            arrays[f"{prefix}_{i:03d}"] = np.asarray(leaf)
    atomic_save_npz(path, arrays)


def _load_params(path: pathlib.Path, config: TrainConfig, level: int):
    data = load_npz(path, "DGTS checkpoint")
    out = []
    for prefix, generator in (("g", True), ("d", False)):
        like = init_level(jax.random.key(0), config, level, generator=generator)
        leaves, treedef = jax.tree.flatten(like)
        try:
            loaded = [jnp.asarray(data[f"{prefix}_{i:03d}"]) for i in range(len(leaves))]
        except KeyError as err:
            raise MeshIOError(f"{path}: incomplete DGTS checkpoint (missing {err})") from err
        if any(a.shape != b.shape for a, b in zip(loaded, leaves, strict=True)):
            raise MeshIOError(f"{path}: parameter shapes do not match the config's widths at level {level}")
        out.append(jax.tree.unflatten(treedef, loaded))
    return out[0], out[1]


def _read_state(out_dir: pathlib.Path) -> dict | None:
    path = out_dir / STATE_FILE
    if not path.is_file():
        return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as err:
        raise MeshIOError(f"cannot read training state {path}: {err}") from err


def load_model(out_dir: str | os.PathLike) -> DGTSModel:
    """Load the levels completed so far from a training folder (see the module docstring).

    Raises:
      MeshIOError: no ``state.json`` there, or damaged files.
    """
    out_dir = pathlib.Path(out_dir)
    state = _read_state(out_dir)
    if state is None:
        raise MeshIOError(f"{out_dir} holds no DGTS model ({STATE_FILE} is missing): run `jmeshtex dgts train` first")
    config = TrainConfig.from_dict(state["config"])
    gs, ds = [], []
    for level in range(int(state["completed_levels"])):
        g, d = _load_params(out_dir / f"level_{level:02d}.npz", config, level)
        gs.append(g)
        ds.append(d)
    z_star = load_npz(out_dir / "z_star.npz", "reconstruction noise")["z_star"]
    return DGTSModel(config, tuple(gs), tuple(ds), z_star)


def _write_state(out_dir: pathlib.Path, config: TrainConfig, completed: int, reports: list[LevelReport], total: int) -> None:
    state = {
        "config": config.to_dict(),
        "completed_levels": completed,
        "total_levels": total,
        "levels": [dataclasses.asdict(r) for r in reports],
    }
    atomic_write(out_dir / STATE_FILE, json.dumps(state, indent=2).encode())


# ----------------------------------------------------------------------------------------------
# the training loop
# ----------------------------------------------------------------------------------------------


def train(
    meshes: TrainingMeshes,
    config: TrainConfig | None = None,
    *,
    out_dir: str | os.PathLike | None = None,
    num_levels: int | None = None,
    progress: bool = True,
) -> tuple[DGTSModel, list[LevelReport]]:
    """Train the DGTS hierarchy on multi-scale training meshes, level by level (§3.4).

    Args:
      meshes: from :func:`~jmeshtex.dgts.training_meshes`.
      config: :class:`TrainConfig` (default: its defaults, the paper's).
      out_dir: checkpoint folder; when it already holds a run, training resumes after its last
        complete level (its config must equal ``config``).
      num_levels: train only the first ``num_levels`` levels (default: all of ``meshes``).
      progress: show a tqdm progress bar with ETA per level.

    Returns:
      ``(model, reports)``: the model and one :class:`LevelReport` per level trained in this call.

    Raises:
      ConfigError: resuming with a different config, or more levels than ``meshes`` has.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.dgts import PrepareConfig, training_meshes
      >>> tm = training_meshes(icosahedron(), icosahedron(), config=PrepareConfig(num_levels=2, iterations=0))
      >>> cfg = TrainConfig(num_layers=3, start_features=4, min_features=4, max_features=4, iterations=2, seed=3,
      ...     shared_levels=2)
      >>> model, reports = train(tm, cfg, progress=False)
      >>> model.num_levels, [r.faces for r in reports]
      (2, [20, 80])
    """
    config = TrainConfig() if config is None else config
    total = meshes.num_levels if num_levels is None else int(num_levels)
    if not 1 <= total <= meshes.num_levels:
        raise ConfigError(f"num_levels must be in [1, {meshes.num_levels}] (the training meshes' levels), got {num_levels}")
    V = [len(v) for v in meshes.vertices]
    # the padded sizes come from the training meshes, not from num_levels: resuming stays exact
    n_geo = max(total, min(config.shared_levels, meshes.num_levels))
    geos_all, faces = hierarchy_geometry(meshes.faces[0], V[0], n_geo)
    for level in range(n_geo):
        if not np.array_equal(faces[level], meshes.faces[level]):
            raise InputError(f"training mesh level {level} is not the midpoint subdivision of level {level - 1}")
    key = jax.random.key(config.seed)
    k_init, k_z, k_train = jax.random.split(key, 3)
    gs: list = []
    ds: list = []
    reports: list[LevelReport] = []
    previous: list[LevelReport] = []
    z_star = np.asarray(config.noise_amplitude * jax.random.normal(k_z, (V[0], 3), jnp.float32))
    out = pathlib.Path(out_dir) if out_dir is not None else None
    if out is not None:
        state = _read_state(out)
        if state is not None:
            saved = TrainConfig.from_dict(state["config"])
            if saved != config:
                diff = {k: (v, getattr(config, k)) for k, v in saved.to_dict().items() if config.to_dict()[k] != v}
                raise ConfigError(f"{out} holds a run with a different config (saved, given): {diff}; use a new folder")
            model = load_model(out)
            gs, ds, z_star = list(model.generators), list(model.discriminators), model.z_star
            previous = [LevelReport(**r) for r in state.get("levels", [])]
        else:
            atomic_save_npz(out / "z_star.npz", {"z_star": z_star})
    template = jnp.asarray(meshes.template, jnp.float32)
    z_star_j = jnp.asarray(z_star, jnp.float32)
    padded = _padded_sizes(geos_all, config.shared_levels)
    for level in range(len(gs), total):
        g, d = _initial_params(config, level, k_init, gs, ds)
        opt = _Opt(_optimizer(config, config.generator_steps).init(g), _optimizer(config, config.discriminator_steps).init(d))
        geos = geos_all[: level + 1]
        nbhd = geos[-1].nbhd
        real = jnp.asarray(meshes.vertices[level], jnp.float32)
        frozen = tuple(gs)
        k_level = jax.random.fold_in(k_train, level)
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=config.iterations, desc=f"DGTS level {level + 1}/{total}", unit="it", leave=True)
        n_chunks = -(-config.iterations // CHUNK)
        t_compile = 0.0
        t0 = time.perf_counter()
        losses: dict = {}
        for chunk in range(n_chunks):
            n = min(CHUNK, config.iterations - chunk * CHUNK)
            t_b = time.perf_counter()
            batch = level_batch(frozen, geos, template, z_star_j, jax.random.fold_in(k_level, chunk), config=config,
                                chunk=CHUNK)
            if chunk == 0:  # the first chunk compiles the frozen levels (new shapes only)
                jax.block_until_ready(batch)
                t_b = time.perf_counter() - t_b
            else:
                t_b = 0.0
            args = (g, d, opt, nbhd, real, batch, jnp.int32(n))
            if level < len(padded):
                args = _pad_level(args, padded[level])
            step_fn, t_s = _compiled(train_chunk, args, {"config": config})
            g, d, opt, losses = step_fn(*args)
            t_compile += t_b + t_s
            if bar is not None:
                bar.update(n)
                bar.set_postfix(rec=f"{float(losses['g_rec']):.3g}", adv=f"{float(losses['g_adv']):.3g}")
        jax.block_until_ready(g)
        seconds = time.perf_counter() - t0
        if bar is not None:
            bar.close()
        report = LevelReport(
            level=level,
            iterations=config.iterations,
            faces=int(len(meshes.faces[level])),
            compile_seconds=t_compile,
            seconds=seconds,
            seconds_per_iteration=(seconds - t_compile) / max(config.iterations, 1),
            losses={k: float(v) for k, v in losses.items()},
        )
        gs.append(g)
        ds.append(d)
        reports.append(report)
        if out is not None:
            _save_params(out / f"level_{level:02d}.npz", g, d)
            _write_state(out, config, level + 1, previous + reports, total)
    return DGTSModel(config, tuple(gs), tuple(ds), np.asarray(z_star)), reports


def _padded_sizes(geos, shared_levels: int) -> list[dict[str, int]]:
    """Target sizes (``F``, ``V``, ``M``) of the levels padded to share one step (``shared_levels``)."""
    shared = geos[: min(int(shared_levels), len(geos))]
    if len(shared) < 2:
        return []
    last = shared[-1].nbhd
    size = {"F": int(last.faces.shape[0]), "V": int(last.vertex_mask.shape[0]),
            "M": max(int(g.nbhd.vertex_faces.shape[1]) for g in shared)}
    return [size] * len(shared)


def pad_level(nbhd: FaceNeighborhood, real, batch: LevelBatch, size: dict[str, int]):
    """Pad one level's training inputs to ``size`` (``F``, ``V``, ``M``): masked faces and vertices.

    Padded vertices sit at the origin with zero noise and belong to no real face, padded faces are
    masked out of every feature, norm and mean (:func:`train_chunk`), so training on the padded level
    gives the same parameters as on the level itself (tested).
    """
    extra = size["V"] - int(real.shape[0])

    def rows(x):
        return jnp.pad(x, [(0, 0)] * (x.ndim - 2) + [(0, extra), (0, 0)])

    batch = batch._replace(**{k: rows(getattr(batch, k)) for k in ("fake_base", "fake_noise", "rec_base", "rec_noise")})
    return pad_to(nbhd, size), rows(real), batch


def _pad_level(args, size):
    g, d, opt, nbhd, real, batch, n = args
    return (g, d, opt, *pad_level(nbhd, real, batch, size), n)


def _initial_params(config: TrainConfig, level: int, key, gs: list, ds: list):
    """Fresh parameters of ``level``, or the previous level's where the widths match (warm start)."""
    out = []
    for generator, previous, k in zip((True, False), (gs, ds), jax.random.split(jax.random.fold_in(key, level)),
                                      strict=True):
        same = level > 0 and config.level_features(level, generator=generator) == config.level_features(
            level - 1, generator=generator)
        out.append(previous[-1] if same else init_level(k, config, level, generator=generator))
    return out[0], out[1]


#: ahead-of-time compiled functions, keyed by function, static arguments and argument shapes
_COMPILED: dict = {}


def _compiled(fn, args: tuple, static: dict):
    """``(compiled fn, compile seconds)``: ``fn`` lowered and compiled once per static arguments and
    argument shapes/dtypes (so compile time is measured apart from run time)."""
    leaves, treedef = jax.tree.flatten(args)
    signature = (fn, tuple(sorted(static.items())), treedef,
                 tuple((np.shape(x), jnp.result_type(x).name if hasattr(x, "dtype") else type(x)) for x in leaves))
    hit = _COMPILED.get(signature)
    if hit is not None:
        return hit, 0.0
    t = time.perf_counter()
    compiled = fn.lower(*args, **static).compile()
    if len(_COMPILED) >= 64:
        _COMPILED.clear()
    _COMPILED[signature] = compiled
    return compiled, time.perf_counter() - t

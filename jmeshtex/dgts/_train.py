"""Hierarchical WGAN-GP training of DGTS (Hertz et al. 2020, §3.4), resumable per level.

Levels are trained one after another. At level ``L`` the input template runs through the frozen
generators ``0 … L−1`` (subdividing and rescaling in between) and the trainable generator ``L``; a
patch discriminator scores every face of the result against the level-``L`` training mesh:

.. math:: \\mathcal L_D = \\overline{D(G(z))} - \\overline{D(x_L)} + \\lambda\\,
   \\overline{\\big(\\lVert \\nabla_{\\hat\\phi_f} \\textstyle\\sum_g D(\\hat\\phi)_g \\rVert - 1\\big)^2},
   \\quad \\hat\\phi = \\alpha \\phi(x_L) + (1 - \\alpha) \\phi(G(z))

.. math:: \\mathcal L_G = -\\overline{D(G(z))} + \\gamma\\, \\mathrm{MSE}\\big(G(z^*, 0, …, 0), x_L\\big)

(gradient penalty on interpolated face features, one ``α ~ U(0, 1)`` per step, per-face gradient
norms; reconstruction with the fixed noise ``z*`` at the coarsest level and zero noise above).
Adam with step decay; ``discriminator_steps`` critic updates then ``generator_steps`` generator
updates per iteration, all inside one jit-compiled function.

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
from ..ops import FaceConvStackParams, face_features
from ._config import TrainConfig
from ._model import (
    discriminator,
    discriminator_features,
    generate,
    hierarchy_geometry,
    init_level,
)
from ._multiscale import TrainingMeshes, atomic_save_npz, atomic_write_bytes, load_npz

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
    """What training one level measured (seconds and final losses)."""

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


def _num_vertices(meshes: TrainingMeshes) -> list[int]:
    return [len(v) for v in meshes.vertices]


def gradient_penalty(
    d_params: FaceConvStackParams, real_features, fake_features, nbhd, alpha, *, negative_slope: float, eps: float
):
    """WGAN-GP term on features interpolated between a real and a fake mesh (same connectivity).

    .. math:: \\overline{(\\lVert \\nabla_{\\hat\\phi_f} \\textstyle\\sum_g D(\\hat\\phi)_g\\rVert_2 - 1)^2}

    The norm is taken per face over its ``3 × 4`` features (the reference code's ``norm(dim=1)``).
    """
    x = alpha * real_features + (1 - alpha) * fake_features

    def total(x):
        return jnp.sum(discriminator_features(d_params, x, nbhd, negative_slope=negative_slope, eps=eps))

    g = jax.grad(total)(x)
    sq = jnp.sum(g * g, axis=(1, 2))
    norm = jnp.sqrt(sq + jnp.asarray(1e-12, sq.dtype))
    return jnp.mean((norm - 1) ** 2)


@functools.lru_cache(maxsize=32)
def make_iteration(config: TrainConfig, level: int, num_vertices: tuple[int, ...]):
    """The jit-compiled training iteration of ``level`` (cached: the same config and sizes reuse
    the compiled function, e.g. when training resumes in the same process).

    Returns ``step(g, d, opt, frozen, geos, template, real, z_star, key) -> (g, d, opt, losses)``.
    """
    c = config
    L = level
    opt_d = _optimizer(c, c.discriminator_steps)
    opt_g = _optimizer(c, c.generator_steps)
    kw = {"negative_slope": c.negative_slope, "eps": c.eps}

    def noises(key, dtype):
        keys = jax.random.split(key, L + 1)
        return [c.noise_amplitude * jax.random.normal(keys[i], (num_vertices[i], 3), dtype) for i in range(L + 1)]

    def run(g, frozen, geos, template, zs):
        frozen = jax.lax.stop_gradient(frozen)
        return generate((*frozen, g), template, geos, zs, scale=c.scale_factor, **kw)

    def d_loss(d, fake, real, nbhd, alpha):
        real_f, fake_f = face_features(real, nbhd), face_features(fake, nbhd)
        s_real = jnp.mean(discriminator_features(d, real_f, nbhd, **kw))
        s_fake = jnp.mean(discriminator_features(d, fake_f, nbhd, **kw))
        gp = gradient_penalty(d, real_f, fake_f, nbhd, alpha, **kw)
        return s_fake - s_real + c.penalty_weight * gp, (s_real, s_fake, gp)

    def g_loss(g, d, frozen, geos, template, real, z_star, key):
        k_fake, k_rec = jax.random.split(key)
        dtype = template.dtype
        fake = run(g, frozen, geos, template, noises(k_fake, dtype))
        if L >= c.reconstruction_start:
            zs = [z_star.astype(dtype)] + [0.0] * L
        else:
            zs = noises(k_rec, dtype)
        rec = run(g, frozen, geos, template, zs)
        adv = -jnp.mean(discriminator(d, fake, geos[-1].nbhd, **kw))
        mse = jnp.mean((rec - real) ** 2)
        return adv + c.reconstruction_weight * mse, (adv, mse)

    @jax.jit
    def step(g, d, opt, frozen, geos, template, real, z_star, key):
        dtype = template.dtype
        zero = jnp.zeros((), dtype)

        def d_step(i, carry):
            d, state, _ = carry
            k_noise, k_alpha = jax.random.split(jax.random.fold_in(key, i))
            fake = jax.lax.stop_gradient(run(g, frozen, geos, template, noises(k_noise, dtype)))
            alpha = jax.random.uniform(k_alpha, (), dtype)
            (_, aux), grads = jax.value_and_grad(d_loss, has_aux=True)(d, fake, real, geos[-1].nbhd, alpha)
            with jax.numpy_dtype_promotion("standard"):  # optax mixes int counters and floats
                updates, state = opt_d.update(grads, state, d)
            return optax.apply_updates(d, updates), state, aux

        d, opt_d_state, (s_real, s_fake, gp) = jax.lax.fori_loop(
            0, c.discriminator_steps, d_step, (d, opt.d, (zero, zero, zero))
        )

        def g_step(i, carry):
            g, state, _ = carry
            k = jax.random.fold_in(key, c.discriminator_steps + i)
            (_, aux), grads = jax.value_and_grad(g_loss, has_aux=True)(
                g, d, frozen, geos, template, real, z_star, k
            )
            with jax.numpy_dtype_promotion("standard"):  # optax mixes int counters and floats
                updates, state = opt_g.update(grads, state, g)
            return optax.apply_updates(g, updates), state, aux

        g, opt_g_state, (adv, mse) = jax.lax.fori_loop(0, c.generator_steps, g_step, (g, opt.g, (zero, zero)))
        losses = {"d_real": s_real, "d_fake": s_fake, "penalty": gp, "g_adv": adv, "g_rec": mse}
        return g, d, _Opt(opt_g_state, opt_d_state), losses

    return step, opt_g, opt_d


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
    atomic_write_bytes(out_dir / STATE_FILE, json.dumps(state, indent=2).encode())


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
      >>> cfg = TrainConfig(num_layers=3, start_features=4, min_features=4, max_features=4, iterations=2, seed=3)
      >>> model, reports = train(tm, cfg, progress=False)
      >>> model.num_levels, [r.faces for r in reports]
      (2, [20, 80])
    """
    config = TrainConfig() if config is None else config
    total = meshes.num_levels if num_levels is None else int(num_levels)
    if not 1 <= total <= meshes.num_levels:
        raise ConfigError(f"num_levels must be in [1, {meshes.num_levels}] (the training meshes' levels), got {num_levels}")
    V = _num_vertices(meshes)
    geos_all, faces = hierarchy_geometry(meshes.faces[0], V[0], total)
    for level in range(total):
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
    for level in range(len(gs), total):
        kg, kd = jax.random.split(jax.random.fold_in(k_init, level))
        g = init_level(kg, config, level, generator=True)
        d = init_level(kd, config, level, generator=False)
        if level > 0 and config.level_features(level, generator=True) == config.level_features(level - 1, generator=True):
            g = gs[-1]
        if level > 0 and config.level_features(level, generator=False) == config.level_features(level - 1, generator=False):
            d = ds[-1]
        step, opt_g, opt_d = make_iteration(config, level, tuple(V))
        opt = _Opt(opt_g.init(g), opt_d.init(d))
        geos = geos_all[: level + 1]
        real = jnp.asarray(meshes.vertices[level], jnp.float32)
        frozen = tuple(gs)
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=config.iterations, desc=f"DGTS level {level + 1}/{total}", unit="it", leave=True)
        t_compile = 0.0
        t0 = time.perf_counter()
        losses: dict = {}
        for it in range(config.iterations):
            t_it = time.perf_counter()
            g, d, opt, losses = step(g, d, opt, frozen, geos, template, real, z_star_j, jax.random.fold_in(jax.random.fold_in(k_train, level), it))
            if it == 0:
                jax.block_until_ready(g)
                t_compile = time.perf_counter() - t_it
                t0 = time.perf_counter()
            if bar is not None:
                bar.update(1)
                if it % 20 == 0:
                    bar.set_postfix(rec=f"{float(losses['g_rec']):.3g}", adv=f"{float(losses['g_adv']):.3g}")
        jax.block_until_ready(g)
        seconds = time.perf_counter() - t0
        if bar is not None:
            bar.close()
        n_timed = max(config.iterations - 1, 1)
        report = LevelReport(
            level=level,
            iterations=config.iterations,
            faces=int(len(meshes.faces[level])),
            compile_seconds=t_compile,
            seconds=seconds + t_compile,
            seconds_per_iteration=seconds / n_timed if config.iterations > 1 else t_compile,
            losses={k: float(v) for k, v in losses.items()},
        )
        gs.append(g)
        ds.append(d)
        reports.append(report)
        if out is not None:
            _save_params(out / f"level_{level:02d}.npz", g, d)
            _write_state(out, config, level + 1, previous + reports, total)
    return DGTSModel(config, tuple(gs), tuple(ds), np.asarray(z_star)), reports

"""Pre-training the FL-VAE on planar meshes laid over images (paper supplement §9.1).

Each step draws ``batch_meshes`` planar meshes from a pool (random resolutions), samples every
one-ring afresh on the host, and takes one jitted Adam step on :func:`~jmeshtex.fl.vae_loss`
(cosine-decayed learning rate with warm-up, global-norm clipping, complex gradients conjugated
before the update — DESIGN.md). All randomness of step ``t`` derives from ``(seed, t)``, so a run
resumed from a checkpoint continues exactly as an uninterrupted one would.

Output folder: ``checkpoint.npz`` (parameters, optimiser state, step; written atomically every
``checkpoint_every`` steps), ``log.json`` (loss history) and, at the end, ``fl_vae.npz``
(:func:`~jmeshtex.fl.save_fl_vae`). :func:`pretrain` with the same folder resumes.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._errors import ConfigError, InputError, MeshIOError
from .._mesh import Mesh
from ..io import atomic_write
from ..ops import conjugate_complex_grads
from ._colors import surface_colors
from ._config import FLVAEConfig
from ._encoder import one_ring_samples
from ._planar import builtin_images, folder_images, planar_pool
from ._vae import FLVAEParams, init_fl_vae, save_fl_vae, vae_loss

CHECKPOINT = "checkpoint.npz"
LOG = "log.json"
FINAL = "fl_vae.npz"


@dataclasses.dataclass(frozen=True)
class PretrainResult:
    """What :func:`pretrain` returns.

    Attributes:
      params: trained :class:`~jmeshtex.fl.FLVAEParams`.
      config: the :class:`~jmeshtex.fl.FLVAEConfig` used.
      losses: ``[steps]`` total loss per step (all steps, also those of earlier resumed runs).
      l1: ``[steps]`` reconstruction term per step.
      seconds: wall time of this call's training steps (excluding compilation of the first step).
      steps_per_second: measured training throughput of this call.
    """

    params: FLVAEParams
    config: FLVAEConfig
    losses: np.ndarray
    l1: np.ndarray
    seconds: float
    steps_per_second: float


def optimizer(config: FLVAEConfig) -> optax.GradientTransformation:
    """Adam with linear warm-up and cosine decay to ``lr · final_lr_fraction``, after norm clipping."""
    schedule = optax.warmup_cosine_decay_schedule(
        init_value=0.0, peak_value=config.lr, warmup_steps=config.warmup_steps,
        decay_steps=max(config.steps, config.warmup_steps + 1), end_value=config.lr * config.final_lr_fraction,
    )
    return optax.chain(optax.clip_by_global_norm(config.grad_clip), optax.adam(schedule))


@functools.lru_cache(maxsize=8)
def make_step(config: FLVAEConfig):
    """The jitted training step ``(params, opt_state, batch, key) -> (params, opt_state, loss, l1)``.

    Cached per config, so repeated or resumed runs in one process compile once.
    """
    opt = optimizer(config)

    def loss_fn(params, batch, key):
        return vae_loss(params, config, batch["log"], batch["rgb"], batch["mask"], key=key,
                        corners=batch["corners"], bary=batch["bary"], vertex_mask=batch["vertex_mask"])

    @jax.jit
    def step(params, opt_state, batch, key):
        (loss, aux), grads = jax.value_and_grad(loss_fn, has_aux=True)(params, batch, key)
        grads = conjugate_complex_grads(grads)
        with jax.numpy_dtype_promotion("standard"):
            updates, opt_state = opt.update(grads, opt_state, params)
            params = optax.apply_updates(params, updates)
        return params, opt_state, loss, aux["l1"]

    return step


def mesh_batch(meshes: list[Mesh], config: FLVAEConfig, rng: np.random.Generator, *, num_vertices: int, dtype=np.float32) -> dict:
    """One training batch: one-ring samples of several meshes, concatenated and padded to ``num_vertices``.

    Returns a dict of arrays ``log [N, S]``, ``rgb [N, S, 3]``, ``mask [N, S]``, ``corners [N, S, 3]``
    (global vertex ids of each sample's face), ``bary [N, S, 3]``, ``vertex_mask [N]``.
    """
    S = config.num_samples
    logs, rgbs, masks, corners, barys = [], [], [], [], []
    offset = 0
    for mesh in meshes:
        s = one_ring_samples(mesh.vertices, mesh.faces, S, rng=rng)
        logs.append(s.log)
        rgbs.append(surface_colors(mesh).at_barycentric(s.face, s.bary))
        masks.append(s.mask)
        corners.append(np.asarray(mesh.faces)[s.face] + offset)
        barys.append(s.bary)
        offset += mesh.num_vertices
    if offset > num_vertices:
        raise InputError(f"batch has {offset} vertices, more than the padded size {num_vertices}")
    pad = num_vertices - offset

    def cat(parts, fill=0):
        a = np.concatenate(parts)
        return np.concatenate([a, np.full((pad, *a.shape[1:]), fill, a.dtype)]) if pad else a

    cdt = np.complex64 if dtype == np.float32 else np.complex128
    return {
        "log": cat(logs).astype(cdt), "rgb": cat(rgbs).astype(dtype), "mask": cat(masks, False),
        "corners": cat(corners).astype(np.int32), "bary": cat(barys).astype(dtype),
        "vertex_mask": np.arange(num_vertices) < offset,
    }


def _load_images(images, max_size: int) -> list[np.ndarray]:
    if isinstance(images, str) and images == "builtin":
        return builtin_images(max_size=max_size)
    if isinstance(images, (str, os.PathLike)):
        return folder_images(images, max_size=max_size)
    if isinstance(images, (list, tuple)) and images:
        from ._planar import _to_rgb01, downscale

        return [downscale(_to_rgb01(im), max_size) for im in images]
    raise InputError(f"images must be 'builtin', a folder path or a non-empty list of arrays, got {type(images).__name__}")


def _save_checkpoint(out: pathlib.Path, params, opt_state, step: int, losses, l1s, config: FLVAEConfig) -> None:
    import io

    leaves = jax.tree.leaves((params, opt_state))
    arrays = {f"leaf_{i:04d}": np.asarray(x) for i, x in enumerate(leaves)}
    arrays["step"] = np.asarray(step)
    arrays["losses"] = np.asarray(losses, np.float64)
    arrays["l1"] = np.asarray(l1s, np.float64)
    arrays["config"] = np.frombuffer(json.dumps(config.to_dict()).encode(), np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write(out / CHECKPOINT, buf.getvalue())


def _load_checkpoint(out: pathlib.Path, like, config: FLVAEConfig):
    path = out / CHECKPOINT
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError) as err:
        raise MeshIOError(f"cannot read checkpoint {path}: {err}") from err
    stored = FLVAEConfig.from_dict(json.loads(arrays["config"].tobytes().decode()))
    if stored.replace(steps=config.steps, checkpoint_every=config.checkpoint_every) != config.replace(
        steps=config.steps, checkpoint_every=config.checkpoint_every
    ):
        raise ConfigError(
            f"{path} was written with a different FLVAEConfig; use another --out folder or the same config"
        )
    flat, treedef = jax.tree.flatten(like)
    leaves = [jnp.asarray(arrays[f"leaf_{i:04d}"]) for i in range(len(flat))]
    params, opt_state = jax.tree.unflatten(treedef, leaves)
    return params, opt_state, int(arrays["step"]), list(arrays["losses"]), list(arrays["l1"])


def pretrain(
    out_dir: str | os.PathLike | None,
    config: FLVAEConfig | None = None,
    *,
    images="builtin",
    progress: bool = True,
    dtype=jnp.float32,
    stop_after: int | None = None,
) -> PretrainResult:
    """Train an FL-VAE on planar meshes over images; resumable, with atomic checkpoints.

    Args:
      out_dir: folder for ``checkpoint.npz``, ``log.json`` and the final ``fl_vae.npz`` (None: keep
        nothing on disk). An existing checkpoint there is resumed (the config must match, except
        ``steps`` and ``checkpoint_every``).
      config: :class:`~jmeshtex.fl.FLVAEConfig` (model, data and optimiser settings); None = defaults.
      images: ``"builtin"`` (scikit-image's bundled images), a folder of images, or a list of
        ``[H, W, C]`` arrays.
      progress: show a tqdm bar with ETA and the running loss.
      dtype: real dtype of the parameters.
      stop_after: run at most this many steps in this call (a time-boxed run; call again with the
        same folder to continue). The schedule always follows ``config.steps``.

    Returns:
      :class:`PretrainResult`; the final ``fl_vae.npz`` is written only once ``config.steps`` are done.

    Example:
      >>> import numpy as np
      >>> img = np.indices((16, 16)).sum(0)[..., None].repeat(3, -1) % 2 * 1.0
      >>> c = FLVAEConfig(features=8, num_heads=2, num_blocks=1, num_samples=8, decoder_features=16,
      ...                 min_vertices=10, max_vertices=12, meshes_per_image=1, batch_meshes=1, steps=2)
      >>> r = pretrain(None, c, images=[img], progress=False)
      >>> r.losses.shape, bool(np.isfinite(r.losses).all())
      ((2,), True)
    """
    config = FLVAEConfig() if config is None else config
    if not isinstance(config, FLVAEConfig):
        raise ConfigError(f"config must be an FLVAEConfig, got {type(config).__name__}")
    out = None if out_dir is None else pathlib.Path(out_dir)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    np_dtype = np.float64 if jnp.dtype(dtype) == jnp.float64 else np.float32
    pool_rng = np.random.default_rng([config.seed, 2**31 - 1])
    pool = planar_pool(_load_images(images, config.max_image_size), per_image=config.meshes_per_image,
                       min_vertices=config.min_vertices, max_vertices=config.max_vertices, rng=pool_rng)
    opt = optimizer(config)
    params = init_fl_vae(jax.random.key(config.seed), config, dtype=dtype)
    opt_state = opt.init(params)
    start, losses, l1s = 0, [], []
    if out is not None and (out / CHECKPOINT).is_file():
        params, opt_state, start, losses, l1s = _load_checkpoint(out, (params, opt_state), config)
        losses, l1s = losses[:start], l1s[:start]
    step_fn = make_step(config)
    num_vertices = config.batch_meshes * config.max_vertices
    base_key = jax.random.key(config.seed + 1)
    bar = None
    if progress and start < config.steps:
        from tqdm.auto import tqdm

        bar = tqdm(total=config.steps, initial=start, desc="FL-VAE pretrain", unit="step")
    t_first = None
    t0 = time.perf_counter()
    end = config.steps if stop_after is None else min(config.steps, start + int(stop_after))
    for step in range(start, end):
        rng = np.random.default_rng([config.seed, step])
        chosen = rng.choice(len(pool), size=min(config.batch_meshes, len(pool)), replace=False)
        batch = mesh_batch([pool[i] for i in chosen], config, rng, num_vertices=num_vertices, dtype=np_dtype)
        params, opt_state, loss, l1 = step_fn(params, opt_state, batch, jax.random.fold_in(base_key, step))
        loss, l1 = float(loss), float(l1)
        if not np.isfinite(loss):
            raise FloatingPointError(f"FL-VAE pretraining diverged at step {step} (loss {loss}); lower lr")
        losses.append(loss)
        l1s.append(l1)
        if t_first is None:
            t_first = time.perf_counter()
        if bar is not None:
            bar.update(1)
            bar.set_postfix(loss=f"{loss:.4f}", l1=f"{l1:.4f}")
        if out is not None and ((step + 1) % config.checkpoint_every == 0 or step + 1 == end):
            _save_checkpoint(out, params, opt_state, step + 1, losses, l1s, config)
            atomic_write(out / LOG, json.dumps({"step": step + 1, "loss": losses, "l1": l1s}).encode())
    if bar is not None:
        bar.close()
    done = end - start
    seconds = time.perf_counter() - (t_first if t_first is not None else t0)
    rate = (done - 1) / seconds if done > 1 and seconds > 0 else float("nan")
    if out is not None and end == config.steps:
        save_fl_vae(out / FINAL, params, config, extra={"steps": config.steps,
                                                         "final_loss": float(np.mean(losses[-50:])) if losses else None,
                                                         "final_l1": float(np.mean(l1s[-50:])) if l1s else None})
    return PretrainResult(params, config, np.asarray(losses), np.asarray(l1s), seconds, rate)




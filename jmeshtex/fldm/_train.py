"""Training the FLDM denoiser (ε- or v-loss) on a batch of mesh copies, data-parallel and resumable.

One step (eq. 10): draw a batch of training copies, a timestep ``t ~ U{0..T−1}`` and tangent noise
``ε`` per copy, form ``z_t = √ᾱ_t s·μ + √(1−ᾱ_t) ε`` (eq. 8, ``s`` the per-channel scale of eq. 38–39)
and descend ``‖ε − ε̂_θ(z_t, t)‖²`` over real vertices (Adam; complex gradients conjugated first,
DESIGN.md), or ``‖v − v̂_θ‖²`` with ``config.prediction = "v"``
(:func:`~jmeshtex.fl.prediction_target`). The step is one ``jax.jit`` over ``vmap``-ed copies; the
batch axis is sharded over every available device with :mod:`jax.sharding` (parameters
replicated), so the same code runs on one CPU or on several accelerators (the batch is rounded up
to a multiple of the device count).

Checkpoints: every ``checkpoint_every`` steps ``checkpoint.npz`` (parameters, optimiser state, step,
losses) and ``state.json`` are written atomically (temporary file + rename); calling
:func:`train_fldm` again with the same folder resumes after the last checkpoint with the same batch
and noise sequence (both derive from ``(seed, step)``). The finished model is ``model.npz`` +
``model.json`` (:func:`save_fldm` / :func:`load_fldm`).
"""

from __future__ import annotations

import functools
import json
import os
import pathlib
import time
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._errors import ConfigError, MeshIOError
from ..ops import conjugate_complex_grads, tangent_noise
from ._config import FLDMConfig
from ._data import FLDMData, batch_geometry
from ._denoiser import denoise, init_denoiser
from ._diffusion import epsilon_loss, make_schedule, prediction_target, q_sample

CHECKPOINT_FILE = "checkpoint.npz"
STATE_FILE = "state.json"
MODEL_FILE = "model.npz"
MODEL_JSON = "model.json"


class FLDMModel(NamedTuple):
    """A trained (or freshly initialised) FLDM.

    Attributes:
      params: denoiser parameters (flax ``params`` dict).
      config: the :class:`FLDMConfig`.
      scale: ``[d]`` latent scale ``s`` (train on ``s·μ``, decode ``z/s``).
    """

    params: dict
    config: FLDMConfig
    scale: np.ndarray


class TrainResult(NamedTuple):
    """What :func:`train_fldm` returns: the model, the loss per step and timings."""

    model: FLDMModel
    losses: np.ndarray
    steps_done: int
    seconds: float


def optimizer(config: FLDMConfig) -> optax.GradientTransformation:
    """Adam with global-norm clipping at 1."""
    return optax.chain(optax.clip_by_global_norm(1.0), optax.adam(config.learning_rate))


def _data_sharding(batch: int):
    devices = np.array(jax.devices())
    mesh = jax.sharding.Mesh(devices, ("data",))
    P = jax.sharding.PartitionSpec
    return (jax.sharding.NamedSharding(mesh, P("data")), jax.sharding.NamedSharding(mesh, P()), len(devices))


@functools.lru_cache(maxsize=16)
def make_train_step(config: FLDMConfig):
    """The jitted step ``(params, opt_state, z0 [B,V,d], geo [B,…], labels [B,V]|None, key) ->
    (params, opt_state, loss)``; one per configuration (cached, so a resumed or repeated run in the
    same process does not compile again)."""
    schedule = make_schedule(config.schedule, num_steps=config.num_train_steps)
    opt = optimizer(config)

    def loss_fn(params, z0, geo, labels, t, eps):
        zt = q_sample(schedule, z0, t, eps)
        if labels is None:
            pred = jax.vmap(lambda z, tt, g: denoise(params, config, z, tt, g))(zt, t, geo)
        else:
            pred = jax.vmap(lambda z, tt, g, lab: denoise(params, config, z, tt, g, labels=lab))(zt, t, geo, labels)
        return epsilon_loss(pred, prediction_target(schedule, config.prediction, z0, t, eps), geo.fine.vertex_mask)

    @jax.jit
    def step(params, opt_state, z0, geo, labels, key):
        kt, ke = jax.random.split(key)
        t = jax.random.randint(kt, (z0.shape[0],), 0, config.num_train_steps)
        eps = tangent_noise(ke, z0.shape, dtype=z0.dtype)
        loss, grads = jax.value_and_grad(loss_fn)(params, z0, geo, labels, t, eps)
        grads = conjugate_complex_grads(grads)
        with jax.numpy_dtype_promotion("standard"):
            updates, opt_state = opt.update(grads, opt_state, params)
            params = optax.apply_updates(params, updates)
        return params, opt_state, loss

    return step


def _batch(data: FLDMData, config: FLDMConfig, step: int, size: int, cdtype):
    rng = np.random.default_rng([config.seed, step])
    idx = rng.choice(data.num_copies, size=size, replace=data.num_copies < size)
    z0 = (data.latents[idx] * data.scale).astype(cdtype)
    geo = batch_geometry(data, idx)
    labels = None if data.labels is None else data.labels[idx]
    return z0, geo, labels


def _flatten(tree) -> list[np.ndarray]:
    return [np.asarray(x) for x in jax.tree.leaves(tree)]


def _unflatten(like, arrays: list[np.ndarray]):
    leaves, treedef = jax.tree.flatten(like)
    if len(leaves) != len(arrays):
        raise MeshIOError(f"checkpoint holds {len(arrays)} arrays, the model needs {len(leaves)}")
    return jax.tree.unflatten(treedef, [jnp.asarray(a, dtype=x.dtype).reshape(x.shape) for a, x in zip(arrays, leaves, strict=True)])


def _save_checkpoint(out: pathlib.Path, params, opt_state, step: int, losses, config: FLDMConfig, scale) -> None:
    from ..io import atomic_save_npz, atomic_write

    arrays = {f"p{i}": a for i, a in enumerate(_flatten(params))}
    arrays.update({f"o{i}": a for i, a in enumerate(_flatten(opt_state))})
    arrays["step"] = np.array(step)
    arrays["losses"] = np.asarray(losses, np.float64)
    atomic_save_npz(out / CHECKPOINT_FILE, arrays)
    state = {"config": config.to_dict(), "scale": np.asarray(scale).tolist(), "step": step}
    atomic_write(out / STATE_FILE, json.dumps(state, indent=2).encode())


def _load_checkpoint(out: pathlib.Path, params, opt_state, config: FLDMConfig):
    from ..io import load_npz

    state = json.loads((out / STATE_FILE).read_text())
    saved = FLDMConfig.from_dict(state["config"])
    if saved.replace(train_steps=config.train_steps, checkpoint_every=config.checkpoint_every) != config:
        raise ConfigError(
            f"{out} holds a run with another configuration ({saved}); use a new folder or the same config"
        )
    a = load_npz(out / CHECKPOINT_FILE, "FLDM checkpoint")
    n_p = len(jax.tree.leaves(params))
    n_o = len(jax.tree.leaves(opt_state))
    params = _unflatten(params, [a[f"p{i}"] for i in range(n_p)])
    opt_state = _unflatten(opt_state, [a[f"o{i}"] for i in range(n_o)])
    return params, opt_state, int(a["step"]), list(a["losses"])


def save_fldm(path: str | os.PathLike, model: FLDMModel) -> pathlib.Path:
    """Write ``model.npz`` + ``model.json`` into the folder ``path`` (atomically)."""
    from ..io import atomic_save_npz, atomic_write

    out = pathlib.Path(path)
    arrays = {"/".join(str(getattr(k, "key", k)) for k in kp): np.asarray(v)
              for kp, v in jax.tree_util.tree_flatten_with_path(model.params)[0]}
    atomic_save_npz(out / MODEL_FILE, arrays)
    meta = {"config": model.config.to_dict(), "scale": np.asarray(model.scale).tolist()}
    atomic_write(out / MODEL_JSON, json.dumps(meta, indent=2).encode())
    return out


def load_fldm(path: str | os.PathLike) -> FLDMModel:
    """Read a model written by :func:`save_fldm` / :func:`train_fldm`.

    Raises:
      MeshIOError: missing or unreadable files.
    """
    from ..io import load_npz

    out = pathlib.Path(path)
    if not (out / MODEL_JSON).is_file():
        raise MeshIOError(f"no FLDM model in {out} (expected {MODEL_JSON} and {MODEL_FILE}; train one with `jmeshtex fldm train`)")
    meta = json.loads((out / MODEL_JSON).read_text())
    arrays = load_npz(out / MODEL_FILE, "FLDM model")
    params: dict = {}
    for name, value in arrays.items():
        node = params
        *parents, leaf = name.split("/")
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = jnp.asarray(value)
    return FLDMModel(params, FLDMConfig.from_dict(meta["config"]), np.asarray(meta["scale"], np.float64))


def train_fldm(
    data: FLDMData,
    config: FLDMConfig,
    *,
    out_dir: str | os.PathLike | None = None,
    progress: bool = True,
    stop_after: int | None = None,
    dtype=jnp.complex64,
) -> TrainResult:
    """Train the denoiser on the copies of ``data`` for ``config.train_steps`` steps (resumable).

    Args:
      data: :func:`~jmeshtex.fl.build_dataset` output.
      config: the :class:`FLDMConfig` the data was built with.
      out_dir: checkpoint folder (None: nothing on disk). An existing checkpoint is resumed.
      progress: tqdm bar with ETA and the running loss.
      stop_after: run at most this many steps in this call (continue later from the checkpoint).
      dtype: complex dtype of parameters and latents.

    Returns:
      :class:`TrainResult`; ``model.npz`` is written once all steps are done.

    Example:
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.fldm._data import build_dataset
      >>> cfg = FLDMConfig.tiny(n_copies=2, copy_vertices=60, latent_channels=1, train_steps=2, bucket=32)
      >>> data = build_dataset(Mesh(*icosphere(1)), cfg, encode=lambda m: m.vertices[:, :1] + 0j, progress=False)
      >>> r = train_fldm(data, cfg, progress=False)
      >>> r.losses.shape, bool(np.isfinite(r.losses).all())
      ((2,), True)
    """
    from tqdm.auto import tqdm

    if data.latents.shape[-1] != config.latent_channels:
        raise ConfigError(f"data has {data.latents.shape[-1]} latent channels, config.latent_channels={config.latent_channels}")
    if (data.labels is None) != (config.num_labels == 0):
        raise ConfigError("labels in the data and config.num_labels must agree (both set or both absent)")
    batch_sharding, replicated, n_dev = _data_sharding(config.batch_size)
    batch = int(np.ceil(config.batch_size / n_dev) * n_dev)
    opt = optimizer(config)
    geo0 = jax.tree.map(lambda a: a[0], data.geometry)
    params = init_denoiser(jax.random.key(config.seed), config, geo0, dtype=dtype)
    opt_state = opt.init(params)
    start, losses = 0, []
    out = None if out_dir is None else pathlib.Path(out_dir)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        if (out / CHECKPOINT_FILE).is_file() and (out / STATE_FILE).is_file():
            params, opt_state, start, losses = _load_checkpoint(out, params, opt_state, config)
    params = jax.device_put(params, replicated)
    opt_state = jax.device_put(opt_state, replicated)
    step_fn = make_train_step(config)
    end = config.train_steps if stop_after is None else min(config.train_steps, start + int(stop_after))
    base_key = jax.random.key(config.seed + 1)
    t0 = time.perf_counter()
    bar = tqdm(range(start, end), initial=start, total=config.train_steps, desc="FLDM train", unit="step",
               disable=not progress)
    for step in bar:
        z0, geo, labels = _batch(data, config, step, batch, dtype)
        z0, geo, labels = jax.device_put((z0, geo, labels), batch_sharding)
        params, opt_state, loss = step_fn(params, opt_state, z0, geo, labels, jax.random.fold_in(base_key, step))
        losses.append(float(loss))
        if progress:
            bar.set_postfix(loss=f"{np.mean(losses[-20:]):.4f}")
        if out is not None and ((step + 1) % config.checkpoint_every == 0 or step + 1 == end):
            _save_checkpoint(out, params, opt_state, step + 1, losses, config, data.scale)
    seconds = time.perf_counter() - t0
    model = FLDMModel(jax.device_get(params), config, np.asarray(data.scale))
    if out is not None and end == config.train_steps:
        save_fldm(out, model)
    return TrainResult(model, np.asarray(losses), end - start, seconds)

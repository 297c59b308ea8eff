"""Training the FL-VAE on planar meshes laid over images (paper supplement §9.1).

Each step draws ``batch_size`` planar meshes — from a fixed pool over whole images (random
resolutions; ``config.pixels_per_vertex == 0``, the shipped model's recipe) or, in the stream mode
(``pixels_per_vertex > 0``, the presets), freshly made textures (augmented crops of
:func:`~jmeshtex.fl.training_images`, never the held-out ones, and procedural textures) meshed at
that pixel density (:func:`~jmeshtex.fl.core.training_meshes`) — samples every one-ring afresh on the
host, and takes one jitted Adam step on :func:`~jmeshtex.fl.core.vae_loss` (cosine-decayed learning rate with warm-up, global-norm clipping, complex gradients conjugated
before the update — docs/concepts.md). All randomness derives from the ``key`` given to :func:`train`:
the initialisation and the pool from two of its splits, step ``t``'s meshes, samples and
reparameterisation noise from ``t`` folded into two others, so a run resumed from a checkpoint
continues exactly as an uninterrupted one would.

Data parallel (``device_mesh=`` / ``devices=``, default every device JAX sees): the batch's vertex axis
(the concatenated one-rings of the step's meshes, padded to a multiple of the device count) is split
over the mesh's ``"data"`` axis, parameters and optimiser state are replicated, and XLA all-reduces
the gradients (``jmeshtex.parallel``). Each vertex's encoder and log decoder read only its own
one-ring, so the split costs no communication but the gradient reduction; the barycentric decoder
gathers corner latents across devices. A step on ``D`` devices equals the one-device step up to
float round-off whenever ``batch_size · max_vertices`` is a multiple of ``D`` (else the padding, and
with it the noise's shape, differs). Under ``jmeshtex.parallel.initialize`` every process
builds the same global batch from the key and feeds its devices their slices.

Checkpoints (``checkpoint_dir``): :class:`jmeshtex.io.Checkpoints` steps holding the parameters,
the optimiser state and, with ``config.ema_decay > 0``, the weight average, with the loss history
in their record, every ``checkpoint_every`` steps and at the end of each call; :func:`train` with
the same folder resumes.
"""

from __future__ import annotations

import hashlib
import os
import threading
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._errors import ConfigError, InputError
from .._mesh import Mesh
from .._random import key_ints
from .._train_result import TrainResult
from .._training import CheckpointPolicy, Progress, fit, optimizer_update
from .._types import PRNGKey
from .._weight_average import averaged_params, averaged_state, averaged_step
from ..ops import conjugate_complex_grads
from ..optim import flat
from ..parallel import (
    batch_multiple,
    data_parallel,
    fetch,
    resolve_mesh,
)
from ._colors import surface_colors
from ._config import Config
from ._encoder import _numpy_rng, corner_logs, one_ring_samples, ring_geometry
from ._loss import vae_loss
from ._loss_curve import plot_losses
from ._model import Model, init
from ._planar import _to_rgb01, builtin_images, downscale, folder_images, planar_pool
from ._textures import _stream_meshes, image_levels, max_stream_vertices, training_images


def optimizer(config: Config) -> optax.GradientTransformation:
    """Adam with linear warm-up and cosine decay to ``learning_rate · final_lr_fraction``, after norm clipping.

    Args:
      config: :class:`~jmeshtex.fl.Config` (``learning_rate``, ``warmup_steps``, ``steps``,
        ``final_lr_fraction``, ``grad_clip``).

    Returns:
      An optax transformation over :class:`~jmeshtex.fl.core.Params` (complex gradients must be
      conjugated first: :func:`make_train_step` does).

    Example:
      >>> import jax
      >>> from jmeshtex.fl import init
      >>> model = init(Config(features=8, num_heads=2), key=jax.random.key(0))
      >>> state = optimizer(Config()).init(model.params)
    """
    schedule = optax.warmup_cosine_decay_schedule(
        init_value=0.0,
        peak_value=config.learning_rate,
        warmup_steps=config.warmup_steps,
        decay_steps=max(config.steps, config.warmup_steps + 1),
        end_value=config.learning_rate * config.final_lr_fraction,
    )
    return flat(optax.chain(optax.clip_by_global_norm(config.grad_clip), optax.adam(schedule)))


def batch_loss(params, config: Config, batch: dict, *, key, kl_scale=1.0):
    """:func:`~jmeshtex.fl.core.vae_loss` of one :func:`mesh_batch` dict: ``(loss, aux)``."""
    return vae_loss(
        params,
        config,
        batch["log"],
        batch["rgb"],
        batch["mask"],
        key=key,
        corners=batch["corners"],
        bary=batch["bary"],
        vertex_mask=batch["vertex_mask"],
        corner_logs=batch.get("corner_logs"),
        kl_scale=kl_scale,
    )


def make_train_step(config: Config, device_mesh: jax.sharding.Mesh | None = None):
    """The jitted training step ``(params, opt_state, batch, key[, step]) -> (params, opt_state, loss, aux)``.

    One :func:`~jmeshtex.fl.core.vae_loss` gradient, complex gradients conjugated, one
    :func:`optimizer` update. ``step`` (the 0-based step index, default 0) sets the KL warm-up's
    factor ``min(1, (step + 1) / kl_warmup_steps)``; ``aux`` holds ``"l1"``, ``"kl"`` and
    ``"kl_channels"`` (each channel's mean KL in nats, ``[d]``; also as scalars ``"kl0"``, ...).

    Args:
      config: :class:`~jmeshtex.fl.Config` (static).
      device_mesh: None (a plain :func:`jax.jit`), or a :class:`jax.sharding.Mesh` with a ``"data"`` axis:
        the batch's vertex axis is split over it, everything else replicated
        (``jmeshtex.parallel.data_parallel``).

    Returns:
      The step function; ``batch`` is a :func:`mesh_batch` dict, ``key`` the reparameterisation key.

    Example:
      >>> import jax, numpy as np
      >>> from jmeshtex.fl import init
      >>> from jmeshtex.fl.core import planar_mesh
      >>> c = Config(features=8, num_heads=2, num_blocks=1, num_samples=8, decoder_features=16)
      >>> params = init(c, key=jax.random.key(0)).params
      >>> rng = np.random.default_rng(0)
      >>> batch = mesh_batch([planar_mesh(rng.random((8, 8, 3)), 10, rng=rng)], c, rng, num_vertices=12)
      >>> params, state, loss, aux = make_train_step(c)(params, optimizer(c).init(params), batch, jax.random.key(1))
      >>> bool(np.isfinite(loss))
      True
    """
    opt = optimizer(config)

    def loss_fn(params, batch, key, scale):
        return batch_loss(params, config, batch, key=key, kl_scale=scale)

    def step(params, opt_state, batch, key, step=0):
        if config.experimental.kl_warmup_steps > 0:
            scale = jnp.minimum(
                1.0, (jnp.asarray(step, jnp.float32) + 1) / config.experimental.kl_warmup_steps
            )
        else:
            scale = 1.0
        (loss, aux), grads = jax.value_and_grad(loss_fn, has_aux=True)(params, batch, key, scale)
        params, opt_state = optimizer_update(opt, conjugate_complex_grads(grads), opt_state, params)
        channels = aux["kl_channels"]
        aux = {**aux, **{f"kl{c}": channels[c] for c in range(config.latent_dim)}}
        return params, opt_state, loss, aux

    if device_mesh is None:
        return jax.jit(step)
    return data_parallel(step, device_mesh, batch_argnums=(2,))


def mesh_batch(
    meshes: list[Mesh],
    config: Config,
    rng: np.random.Generator,
    *,
    num_vertices: int,
    dtype=np.float32,
) -> dict:
    """One training batch: one-ring samples of several meshes, concatenated and padded to ``num_vertices``.

    Args:
      meshes: textured (or vertex-coloured) meshes, e.g. from :func:`~jmeshtex.fl.core.planar_pool`.
      config: :class:`~jmeshtex.fl.Config` (``num_samples``).
      rng: generator of the one-ring samples.
      num_vertices: padded size ``N`` (at least the meshes' total vertex count; a fixed size
        keeps the jitted step from recompiling).
      dtype: real dtype of the arrays (``float32`` or ``float64``).

    Returns:
      A dict of arrays ``log [N, S]``, ``rgb [N, S, 3]``, ``mask [N, S]``, ``corners [N, S, 3]``
      (global vertex ids of each sample's face), ``bary [N, S, 3]``, ``corner_logs [N, S, 3]``
      (each sample's log map seen from each corner of its face, normalised as ``log``),
      ``vertex_mask [N]`` (the vertices whose rings enter the loss: real ones, and with
      ``config.experimental.boundary_in_loss = False`` only interior ones). With ``config.experimental.token == "centre"``
      column 0 is each ring's centre (``S + 1`` columns).

    Example:
      >>> import numpy as np
      >>> from jmeshtex.fl.core import planar_mesh
      >>> rng = np.random.default_rng(0)
      >>> meshes = [planar_mesh(rng.random((8, 8, 3)), 10, rng=rng) for _ in range(2)]
      >>> b = mesh_batch(meshes, Config(num_samples=4), rng, num_vertices=24)
      >>> b["log"].shape, int(b["vertex_mask"].sum())  # the centre and 4 samples per ring
      ((24, 5), 20)
    """
    S = config.num_samples
    logs, rgbs, masks, corners, barys, clogs, keep = [], [], [], [], [], [], []
    offset = 0
    for mesh in meshes:
        geom = ring_geometry(mesh.vertices, mesh.faces)
        s = one_ring_samples(
            mesh.vertices,
            mesh.faces,
            S,
            rng=rng,
            geometry=geom,
            center=config.experimental.token == "centre",
        )
        logs.append(s.log)
        rgbs.append(surface_colors(mesh).at_barycentric(s.face, s.bary))
        masks.append(s.mask)
        corners.append(np.asarray(mesh.faces)[s.face] + offset)
        barys.append(s.bary)
        clogs.append(
            np.stack(
                [corner_logs(geom, s.face, np.full(s.face.shape, k), s.bary) for k in range(3)],
                axis=-1,
            )
            * s.mask[..., None]
        )
        keep.append(
            np.ones(mesh.num_vertices, bool)
            if config.experimental.boundary_in_loss
            else ~boundary_vertices(mesh.faces, mesh.num_vertices)
        )
        offset += mesh.num_vertices
    if offset > num_vertices:
        raise InputError(f"batch has {offset} vertices, more than the padded size {num_vertices}")
    pad = num_vertices - offset

    def cat(parts, fill=0):
        a = np.concatenate(parts)
        return np.concatenate([a, np.full((pad, *a.shape[1:]), fill, a.dtype)]) if pad else a

    cdt = np.complex64 if dtype == np.float32 else np.complex128
    return {
        "log": cat(logs).astype(cdt),
        "rgb": cat(rgbs).astype(dtype),
        "mask": cat(masks, False),
        "corners": cat(corners).astype(np.int32),
        "bary": cat(barys).astype(dtype),
        "corner_logs": cat(clogs).astype(cdt),
        "vertex_mask": cat(keep, False),
    }


def boundary_vertices(faces: np.ndarray, num_vertices: int) -> np.ndarray:
    """``[V]`` True at the vertices of edges that belong to one face only.

    Example:
      >>> from jmeshtex.data import grid
      >>> int(boundary_vertices(grid(2).faces, 9).sum())  # a 3×3 grid: all but the middle vertex
      8
    """
    f = np.asarray(faces, np.int64)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    out = np.zeros(num_vertices, bool)
    out[uniq[count == 1].ravel()] = True
    return out


def _prefetched(make):
    """``make`` (step index → batch) with the next index's batch built in a worker thread.

    ``get(i)`` returns ``make(i)``: the thread's result when it was building ``i`` (else computed
    here; an error in the thread is raised by computing again here), then starts ``i + 1``.
    """
    ahead: dict = {}

    def get(i: int):
        thread = ahead.pop("thread", None)
        if thread is not None:
            thread.join()
        box = ahead.pop("box", None)
        out = box["out"] if box is not None and box["index"] == i and "out" in box else make(i)
        nxt: dict = {"index": i + 1}

        def work() -> None:
            try:
                nxt["out"] = make(i + 1)
            except Exception:  # noqa: BLE001 (re-raised when that step is asked for)
                pass

        thread = threading.Thread(target=work, daemon=True, name="fl-batch-prefetch")
        thread.start()
        ahead.update(thread=thread, box=nxt)
        return out

    return get


def _load_images(
    images, max_size: int, stream: bool = False, extra: bool = False
) -> list[np.ndarray]:
    if images is None or (isinstance(images, str) and images == "builtin"):
        if stream:
            return training_images(max_size=max_size, extra=extra)
        return builtin_images(max_size=max_size)
    if isinstance(images, (str, os.PathLike)):
        return folder_images(images, max_size=max_size)
    if isinstance(images, (list, tuple)) and images:
        return [downscale(_to_rgb01(im), max_size) for im in images]
    if stream and isinstance(images, (list, tuple)) and not images:
        return []
    raise InputError(
        f"images must be None or 'builtin', a folder path or a non-empty list of arrays, "
        f"got {type(images).__name__}"
    )


def _fingerprint(config: Config, key: PRNGKey, images: list[np.ndarray], dtype) -> dict:
    """What a checkpoint must have been written for to be resumed by this call."""
    digest = hashlib.sha256()
    for im in images:
        digest.update(repr(im.shape).encode())
        digest.update(np.ascontiguousarray(im, np.float64).tobytes())
    return {
        "config": config.fingerprint(),
        "key": key_ints(key),
        "images": digest.hexdigest(),
        "dtype": jnp.dtype(dtype).name,
    }


def _mesh_source(loaded: list[np.ndarray], config: Config, k_pool: PRNGKey):
    """How a step draws its planar meshes from its NumPy generator (module docstring: fresh
    textures in the stream mode, else a fixed pool built once from ``k_pool``), and the most
    vertices one mesh may have."""
    if config.pixels_per_vertex > 0:
        levels = [image_levels(im) for im in loaded]
        if not levels and config.procedural_fraction < 1:
            raise InputError("fl.train: no images given and procedural_fraction < 1")
        return (lambda rng: _stream_meshes(rng, levels, config)), max_stream_vertices(config)
    pool = planar_pool(
        loaded,
        per_image=config.meshes_per_image,
        min_vertices=config.min_vertices,
        max_vertices=config.max_vertices,
        rng=_numpy_rng(k_pool),
    )

    def draw(rng: np.random.Generator) -> list:
        chosen = rng.choice(len(pool), size=min(config.batch_size, len(pool)), replace=False)
        return [pool[i] for i in chosen]

    return draw, config.max_vertices


def _driver_step(config: Config, device_mesh: jax.sharding.Mesh):
    """The training driver's step: one Adam step of the VAE and, with ``config.ema_decay > 0``, the
    weight average; it records the loss and its terms (the per-channel KL vector left out)."""
    vae_step = make_train_step(config, device_mesh)

    def update(params, opt_state, batch):
        params, opt_state, loss, aux = vae_step(params, opt_state, *batch)
        metrics = {"loss": loss, **{k: v for k, v in aux.items() if k != "kl_channels"}}
        return params, opt_state, metrics, batch[2]

    return averaged_step(update, decay=config.ema_decay, device_mesh=device_mesh)


def train(
    images,
    config: Config,
    *,
    key: PRNGKey,
    progress: bool = True,
    checkpoint_dir: str | os.PathLike | None = None,
    loss_curve: str | os.PathLike | None = None,
    dtype=jnp.float32,
    stop_after: int | None = None,
    device_mesh: jax.sharding.Mesh | None = None,
    devices=None,
    prefetch: bool = True,
) -> TrainResult[Model]:
    """Train an FL-VAE on planar meshes over images; resumable from checkpoints.

    Args:
      images: the training data: None or ``"builtin"`` (scikit-image's bundled images: in the
        stream data mode, ``config.pixels_per_vertex > 0``, :func:`~jmeshtex.fl.training_images` —
        the held-out images excluded; else :func:`~jmeshtex.fl.core.builtin_images`), a folder of
        images, or a list of ``[H, W, C]`` arrays (in the stream mode ``[]`` with
        ``procedural_fraction = 1`` trains on procedural textures only).
      config: :class:`~jmeshtex.fl.Config` (model, data and optimiser settings).
      key: PRNG key of the initialisation, the planar meshes, the one-ring samples and the
        reparameterisation noise (module docstring).
      progress: show a tqdm bar with ETA and the running loss.
      checkpoint_dir: folder of :class:`jmeshtex.io.Checkpoints` (None: keep nothing on disk). The
        newest checkpoint there is resumed; it must have been written with the same config
        (``steps`` and ``checkpoint_every`` may differ), key, images and dtype, else
        :class:`~jmeshtex.CheckpointMismatchError`.
      loss_curve: a ``.png`` path: :func:`~jmeshtex.fl.plot_losses` of the run so far, rewritten at
        every checkpoint (every ``checkpoint_every`` steps) and at the end of the call.
      dtype: real dtype of the parameters.
      stop_after: run at most this many steps in this call (a time-boxed run; call again with the
        same folder to continue). The schedule always follows ``config.steps``.
      device_mesh: the :class:`jax.sharding.Mesh` to train on (a ``"data"`` axis splits the batch;
        module docstring). None: ``jmeshtex.parallel.data_mesh(devices)``.
      devices: the devices of the default mesh (None: every device; ``jax.devices()[:1]`` trains
        on one). Not with ``device_mesh``.
      prefetch: build step ``t + 1``'s batch (meshes, one-ring samples) in a worker thread while
        step ``t`` runs (the same batches either way: each is a function of its step index).

    Returns:
      :class:`~jmeshtex.TrainResult` with the :class:`~jmeshtex.fl.Model` in ``.model`` (the weight
      average when ``config.ema_decay > 0``); ``losses``
      has ``"loss"`` (total), ``"l1"`` (reconstruction term), ``"kl"`` (the KL term, before any
      free-bits floor) and ``"kl0"`` ... ``"kl{d-1}"`` (each latent channel's mean KL in nats: a
      channel near 0 has collapsed) per step, resumed steps included;
      ``extra["steps_per_second"]`` is this call's throughput after the first (compiling) step.
      Save the model with :func:`~jmeshtex.fl.save`. The model's parameters are on the default
      device (whatever mesh trained them), and a checkpoint written on one mesh resumes on another.

    Raises:
      TrainingDivergedError: the loss or the parameters became non-finite (lower
        ``learning_rate``).
      ConfigError: ``config`` is not a :class:`~jmeshtex.fl.Config`; ``device_mesh`` and
        ``devices`` both given, or ``checkpoint_dir`` in a multi-process run (not supported yet).

    Example:
      >>> import jax, numpy as np
      >>> img = np.indices((16, 16)).sum(0)[..., None].repeat(3, -1) % 2 * 1.0
      >>> c = Config(features=8, num_heads=2, num_blocks=1, num_samples=8, decoder_features=16,
      ...            min_vertices=10, max_vertices=12, meshes_per_image=1, batch_size=1, steps=2)
      >>> r = train([img], c, key=jax.random.key(0), progress=False)
      >>> r.steps, r.losses["loss"].shape, bool(np.isfinite(r.losses["loss"]).all())
      (2, (2,), True)
    """
    started = time.perf_counter()
    if not isinstance(config, Config):
        raise ConfigError(f"config must be a jmeshtex.fl.Config, got {type(config).__name__}")
    np_dtype = np.float64 if jnp.dtype(dtype) == jnp.float64 else np.float32
    device_mesh = resolve_mesh(device_mesh, devices)
    k_init, k_pool, k_data, k_noise = jax.random.split(key, 4)
    loaded = _load_images(
        images, config.max_image_size, config.pixels_per_vertex > 0, config.extra_images
    )
    draw_meshes, max_vertices = _mesh_source(loaded, config, k_pool)
    per = batch_multiple(device_mesh)
    num_vertices = -(-config.batch_size * max_vertices // per) * per

    def batches(step: int):
        rng = _numpy_rng(jax.random.fold_in(k_data, step))
        meshes = draw_meshes(rng)
        batch = mesh_batch(meshes, config, rng, num_vertices=num_vertices, dtype=np_dtype)
        return batch, jax.random.fold_in(k_noise, step), np.int32(step)

    if prefetch:
        batches = _prefetched(batches)
    step = _driver_step(config, device_mesh)

    def curve(done: int, state, losses: dict) -> None:
        title = f"FL-VAE training ({done} steps)"
        plot_losses({"loss": losses["loss"], "l1": losses["l1"]}, loss_curve, title=title)

    params = init(config, key=k_init, dtype=dtype).params
    state = averaged_state(params, optimizer(config).init(params), decay=config.ema_decay)
    return fit(
        step,
        state,
        batches,
        steps=config.steps,
        stop_after=stop_after,
        checkpoints=CheckpointPolicy(
            checkpoint_dir,
            fingerprint=_fingerprint(config, key, loaded, dtype),
            every=config.checkpoint_every,
            on_save=None if loss_curve is None else curve,
        ),
        device_mesh=device_mesh,
        progress=Progress(progress, "FL-VAE train", ("loss", "l1")),
        model=lambda s: Model(jax.tree.map(jnp.asarray, fetch(averaged_params(s))), config),
        started=started,
    )

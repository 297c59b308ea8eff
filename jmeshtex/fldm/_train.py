"""Training the FLDM denoiser (ε- or v-loss) on a batch of mesh copies, data-parallel and resumable.

One step (eq. 10): draw a batch of training copies (each with one of its encodings when the data
set keeps several), a timestep ``t ~ U{0..T−1}`` and tangent noise ``ε`` per copy, form
``z_t = √ᾱ_t s·μ + √(1−ᾱ_t) ε`` (eq. 8, ``s`` the latent scale of eq. 38–39, per channel or global)
and descend ``‖ε − ε̂_θ(z_t, t)‖²`` over real vertices (``config.loss = "l1"``: ``|ε − ε̂_θ|``, as
released; Adam on a warm-up + cosine learning-rate schedule, :func:`learning_rate_schedule`;
complex gradients conjugated first, docs/concepts.md; optionally an EMA of the weights,
``config.ema_decay``, and gradient accumulation over ``config.accumulate`` micro-batches), or
``‖v − v̂_θ‖²`` with ``config.prediction = "v"`` (:func:`~jmeshtex.fldm.core.prediction_target`).
The step is one ``jax.jit`` over ``vmap``-ed copies.
With ``config.mask_conditioning`` every copy of a step also gets a random inpainting mask
(:func:`training_masks`); the denoiser sees it and the known clean latents, and the loss counts the
generated (unmasked) region only.

Data parallel (``device_mesh=`` / ``devices=``, default every device JAX sees; :mod:`jmeshtex.parallel`):
the batch axis (the ``batch_size`` copies of a step) is split over the mesh's ``"data"`` axis,
parameters, optimiser state and EMA are replicated, and XLA all-reduces the gradients. The batch is
the same on every mesh (``batch_size`` must be a multiple of the device count; nothing is resized),
so a step on four devices equals the one-device step up to the order of the floating-point sums.
Under :func:`jmeshtex.parallel.initialize` every process builds the same global batch from the
key and feeds its own devices their slices; losses and the model are read back with
:func:`jmeshtex.parallel.fetch` on every process.

On an accelerator (one process) the data set is sent to the device once and each step's batch is
gathered there by one compiled call; :func:`training_batch` gives the same batch on the host.

Randomness: :func:`train`'s ``key`` is split three ways, into the initialisation (the model
:func:`init` returns for the same key), the batch draws (which copies, a NumPy generator seeded
from the key and the step) and the step noise (``fold_in(key, step)``). Every step's batch and
noise is a function of ``(key, step)`` alone.

Checkpoints (``checkpoint_dir``): every ``checkpoint_every`` steps and after the last one, the
parameters, the optimiser state and the losses so far go to a :class:`jmeshtex.io.Checkpoints`
folder (atomic; the newest two kept), fingerprinted with the run's settings (the config apart from
``steps``, ``checkpoint_every``, ``remat`` and the statistics settings, the key, the dtype, the data's
shape, scale and a hash of its contents, :func:`data_digest`). Calling :func:`train` again with the
same folder resumes after the newest step and
gives the same parameters and losses as an uninterrupted run; a folder written by another run raises
:class:`~jmeshtex.CheckpointMismatchError`. With ``config.experimental.stats_samples`` every checkpoint also
records the decoder-free statistics (:func:`~jmeshtex.fldm.core.latent_statistics`) of a few DDIM
samples drawn on copy 0, and of copy 0's own latents once; the history is read back on resume and
returned in ``TrainResult.extra["statistics"]``. The finished model is written with :func:`save`
(``model.npz``; ``card=model_card(result)`` adds the card) and read back with :func:`load`.
"""

from __future__ import annotations

import functools
import os
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._errors import ConfigError, InputError
from .._neighborhoods import to_jax
from .._random import host_rng, key_ints
from .._train_result import TrainResult
from .._training import CheckpointPolicy, Progress, fit, optimizer_update
from .._weight_average import averaged_params, averaged_state, averaged_step
from ..ops import conjugate_complex_grads, tangent_noise
from ..optim import flat
from ..parallel import (
    batch_multiple,
    data_parallel,
    fetch,
    resolve_mesh,
)
from ._config import Config
from ._data import Dataset, batch_geometry
from ._denoiser import DenoiserGeometry, denoise, denoiser_geometry, init_denoiser
from ._diffusion import epsilon_loss, prediction_target, q_sample
from ._masks import batch_masks
from ._model import Model


def learning_rate_schedule(config: Config) -> optax.Schedule:
    """The learning rate per step: linear warm-up from 0, then cosine decay (the reference's schedule).

    ``config.lr_schedule = "cosine"``: ``optax.warmup_cosine_decay_schedule`` from 0 to
    ``learning_rate`` over ``min(warmup_steps, steps // 2)`` steps, then down to ``end_learning_rate``
    at ``steps`` (google-research ``mesh_diffusion/sin_mesh_ddm/train.py``, ``configs/default.py``:
    5e-4, 1000 warm-up steps, 1e-5 at the end). ``"constant"``: ``learning_rate`` throughout.

    Example:
      >>> lr = learning_rate_schedule(Config.tiny(steps=100, warmup_steps=10, learning_rate=1e-3))
      >>> [round(float(lr(s)), 6) for s in (0, 10, 100)]
      [0.0, 0.001, 1e-05]
    """
    if config.lr_schedule == "constant":
        return optax.constant_schedule(config.learning_rate)
    warmup = min(config.warmup_steps, config.steps // 2)
    return optax.warmup_cosine_decay_schedule(
        init_value=0.0,
        peak_value=config.learning_rate,
        warmup_steps=warmup,
        decay_steps=max(config.steps, warmup + 1),
        end_value=config.end_learning_rate,
    )


def optimizer(config: Config) -> optax.GradientTransformation:
    """The optimiser of :func:`~jmeshtex.fldm.train`: Adam on :func:`learning_rate_schedule` after global-norm clipping at 1.

    Example:
      >>> opt = optimizer(Config.tiny())
      >>> state = opt.init({"w": jnp.zeros(3)})
    """
    return flat(
        optax.chain(optax.clip_by_global_norm(1.0), optax.adam(learning_rate_schedule(config)))
    )


def _check_batch(config: Config, device_mesh: jax.sharding.Mesh) -> None:
    """Raise :class:`~jmeshtex.ConfigError` unless ``config.batch_size`` splits evenly over ``device_mesh``."""
    per = batch_multiple(device_mesh)
    if config.batch_size % per:
        raise ConfigError(
            f"fldm: batch_size={config.batch_size} copies cannot be split evenly over the {per} devices of the "
            f"mesh; use a batch_size that is a multiple of {per}, or train on fewer devices (devices=...)"
        )


def make_train_step(
    config: Config, device_mesh: jax.sharding.Mesh | None = None, *, channel_weight=None
):
    """The jitted optimiser step of :func:`~jmeshtex.fldm.train` (module docstring).

    Args:
      config: the :class:`~jmeshtex.fldm.Config` (schedule, prediction, ``diffusion_steps``, learning rate).
      device_mesh: None (a plain :func:`jax.jit` on the default device), or a :class:`jax.sharding.Mesh`
        with a ``"data"`` axis: the batch arguments (``z0``, ``geo``, ``labels``) are split along
        their leading axis over it, everything else replicated, outputs replicated
        (:func:`jmeshtex.parallel.data_parallel`).
      channel_weight: ``[d]`` loss weights of the latent channels (:func:`channel_weights`;
        None: all 1).

    ``config.loss`` picks the L2 or L1 loss; with ``config.accumulate = a`` the batch is split into
    ``a`` micro-batches whose gradients are averaged before one optimiser update (the same update
    as the whole batch at once, up to round-off).

    Returns:
      ``step(params, opt_state, z0 [B, V, d], geo [B, …], labels [B, V] or None, key, mask=None) ->
      (params, opt_state, loss)``: ``z0`` the scaled latents and ``geo`` the geometry of a batch
      (:func:`training_batch`), ``opt_state`` from ``optimizer(config).init(params)``, ``key`` the
      step's noise key, ``mask`` ``[B, V]`` the batch's inpainting masks (:func:`training_masks`;
      required with ``config.mask_conditioning``, ignored otherwise). With a mesh, ``B`` must be a
      multiple of its device count.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.fldm import build_dataset
      >>> cfg = Config.tiny(latent_channels=1, n_copies=1, copy_vertices=0, bucket=32)
      >>> data = build_dataset(icosphere(1), cfg, encode=lambda m: m.vertices[:, :1] + 0j,
      ...                      key=jax.random.key(0), progress=False)
      >>> params = init_denoiser(jax.random.key(1), cfg)
      >>> z0, geo, labels = training_batch(data, 0, 2, key=jax.random.key(2))
      >>> step = make_train_step(cfg)
      >>> params, opt_state, loss = step(params, optimizer(cfg).init(params), z0, geo, labels, jax.random.key(3))
      >>> bool(jnp.isfinite(loss))
      True
    """
    schedule = config.noise_schedule()
    opt = optimizer(config)

    def loss_fn(params, z0, geo, labels, t, eps, mask):
        zt = q_sample(schedule, z0, t, eps)

        def one(z, tt, g, lab, m, known):
            return denoise(params, config, z, tt, g, labels=lab, mask=m, known=known)

        known = z0 if config.mask_conditioning else None
        pred = jax.vmap(one)(zt, t, geo, labels, mask, known)
        weight = geo.fine.vertex_mask
        if config.mask_conditioning:  # the loss of the generated region only
            weight = weight & ~mask
        return epsilon_loss(
            pred,
            prediction_target(schedule, config.prediction, z0, t, eps),
            weight,
            kind=config.loss,
            channel_weight=channel_weight,
        )

    def grads_of(params, z0, geo, labels, t, eps, mask):
        a = config.accumulate
        if a == 1:
            return jax.value_and_grad(loss_fn)(params, z0, geo, labels, t, eps, mask)
        micro = jax.tree.map(
            lambda x: x.reshape(a, x.shape[0] // a, *x.shape[1:]), (z0, geo, labels, t, eps, mask)
        )

        def body(acc, xs):
            loss, g = jax.value_and_grad(loss_fn)(params, *xs)
            return jax.tree.map(jnp.add, acc, (loss, g)), None

        zero = (jnp.zeros((), z0.real.dtype), jax.tree.map(jnp.zeros_like, params))
        (loss, g), _ = jax.lax.scan(body, zero, micro)
        return loss / a, jax.tree.map(lambda x: x / a, g)

    def step(params, opt_state, z0, geo, labels, key, mask=None):
        if config.mask_conditioning and mask is None:
            raise InputError(
                "fldm: a mask-conditioned config's step needs the batch's masks (training_masks)"
            )
        if not config.mask_conditioning:
            mask = None
        kt, ke = jax.random.split(key)
        t = jax.random.randint(kt, (z0.shape[0],), 0, config.diffusion_steps)
        eps = tangent_noise(ke, z0.shape, dtype=z0.dtype)
        loss, grads = grads_of(params, z0, geo, labels, t, eps, mask)
        params, opt_state = optimizer_update(opt, conjugate_complex_grads(grads), opt_state, params)
        return params, opt_state, loss

    if device_mesh is None:
        return jax.jit(step)
    return data_parallel(step, device_mesh, batch_argnums=(2, 3, 4, 6))


def training_batch(
    data: Dataset, step: int, size: int, *, key: jax.Array, dtype=jnp.complex64
) -> tuple[np.ndarray, DenoiserGeometry, np.ndarray | None]:
    """The copies of training step ``step``: a function of ``(key, step)`` (drawn without
    replacement when the data set has enough copies). With several encodings per copy
    (``Dataset.encodings``), each drawn copy comes with one of them, uniformly.

    Args:
      data: the :class:`~jmeshtex.fldm.Dataset`.
      step: the optimiser step.
      size: batch size.
      key: PRNG key of the batch draws.
      dtype: complex dtype of the latents.

    Returns:
      ``(z0 [size, V₀, d] scaled latents, geometry with a leading [size] axis, labels [size, V₀] or
      None)``, host arrays for :func:`make_train_step`'s step.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.fldm import build_dataset
      >>> cfg = Config.tiny(latent_channels=1, n_copies=3, copy_vertices=30, bucket=32)
      >>> data = build_dataset(icosphere(1), cfg, encode=lambda m: m.vertices[:, :1] + 0j,
      ...                      key=jax.random.key(0), progress=False)
      >>> z0, geo, labels = training_batch(data, 5, 2, key=jax.random.key(1))
      >>> z0.shape, geo.fine.index.shape[0], labels
      ((2, 32, 1), 2, None)
    """
    idx = _batch_index(data, step, size, key)
    which = None
    if data.encodings is not None:  # one of the copy's K encodings, drawn after the copies
        which = host_rng(key, step, 2).integers(0, data.encodings.shape[1] + 1, size=len(idx))
    if isinstance(data.latents, np.ndarray):
        return _gather(data, idx, which, dtype, np)
    return _gather_on_device(data._replace(meshes=()), idx, which, jnp.dtype(dtype))


def _gather(data: Dataset, idx, which, dtype, xp):
    """The batch ``(z0, geometry, labels)`` of copies ``idx`` (encodings ``which``; 0: the first)."""
    latents = data.latents[idx]
    if which is not None:
        drawn = data.encodings[idx, xp.maximum(which - 1, 0)].astype(latents.dtype)
        latents = xp.where((which > 0)[:, None, None], drawn, latents)
    z0 = (latents * xp.asarray(data.scale).astype(latents.dtype)).astype(dtype)
    geo = batch_geometry(data, idx)
    labels = None if data.labels is None else data.labels[idx]
    return z0, geo, labels


@functools.partial(jax.jit, static_argnums=3)
def _gather_on_device(data: Dataset, idx, which, dtype):
    """:func:`_gather` as one compiled call: dispatched one by one, a step's two dozen small gathers
    cost as much as the training step itself on an accelerator (25 ms on an H200; compiled: 0.9 ms)."""
    return _gather(data, idx, which, dtype, jnp)


def _device_resident(data: Dataset, dtype) -> Dataset:
    """``data`` with its arrays on JAX's default device, so that a step's batch is gathered there.

    On an accelerator, gathering a batch on the host and sending it costs about as much as the step
    itself (on an H200: 14–20 ms for eight 10,000-vertex copies against a 28 ms step); the whole data
    set (a few megabytes a copy) is sent once instead, and :func:`_gather_on_device` gathers a batch
    in under a millisecond. :func:`training_batch` gives the same batch either way.
    """
    arrays = {k: getattr(data, k) for k in ("latents", "geometry", "labels", "encodings")}
    return data._replace(**to_jax(arrays, jnp.finfo(dtype).dtype))


def _batch_index(data: Dataset, step: int, size: int, key: jax.Array) -> np.ndarray:
    rng = host_rng(key, step)
    return rng.choice(data.num_copies, size=size, replace=data.num_copies < size)


def training_masks(data: Dataset, step: int, size: int, *, key: jax.Array) -> np.ndarray:
    """Random inpainting masks of the copies of training step ``step`` (``Config.mask_conditioning``).

    The copies are those of ``training_batch(data, step, size, key=key)``; each gets a mask of
    :func:`~jmeshtex.fldm.random_mask` (empty for a quarter of them, else a half-space cap), a function of
    ``(key, step)`` alone.

    Returns:
      ``[size, V₀]`` bool, True where the latents are known (False on padding).

    Example:
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.fldm import build_dataset
      >>> cfg = Config.tiny(latent_channels=1, n_copies=3, copy_vertices=30, bucket=32)
      >>> data = build_dataset(icosphere(1), cfg, encode=lambda m: m.vertices[:, :1] + 0j,
      ...                      key=jax.random.key(0), progress=False)
      >>> m = training_masks(data, 5, 2, key=jax.random.key(1))
      >>> m.shape, bool(m[:, 30:].any())
      ((2, 32), False)
    """
    idx = _batch_index(data, step, size, key)
    return batch_masks(data.meshes, idx, data.latents.shape[1], host_rng(key, step, 1))


def _split(key: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """``(init, batch, noise)`` keys of a run (module docstring)."""
    k_init, k_batch, k_noise = jax.random.split(key, 3)
    return k_init, k_batch, k_noise


def _check_data(data: Dataset, config: Config) -> None:
    if not isinstance(data, Dataset):
        raise InputError(
            f"expected a jmeshtex.fldm.Dataset (from build_dataset), got {type(data).__name__}"
        )
    if data.latents.shape[-1] != config.latent_channels:
        raise ConfigError(
            f"data has {data.latents.shape[-1]} latent channels, config.latent_channels={config.latent_channels}"
        )
    if (data.labels is None) != (config.num_labels == 0):
        raise ConfigError(
            "labels in the data and config.num_labels must agree (both set or both absent)"
        )


def init(data: Dataset, config: Config, *, key: jax.Array, dtype=jnp.complex64) -> Model:
    """The untrained model that ``train(data, config, key=key)`` starts from.

    A baseline for a trained model's samples (same noise, initial weights).

    Args:
      data: the :class:`Dataset` (its latent scale goes into the model).
      config: the :class:`Config`.
      key: the key that is (or would be) given to :func:`train`.
      dtype: complex dtype of the parameters.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.fldm import build_dataset
      >>> cfg = Config.tiny(latent_channels=1, n_copies=1, copy_vertices=0, bucket=32)
      >>> data = build_dataset(icosphere(1), cfg, encode=lambda m: m.vertices[:, :1] + 0j,
      ...                      key=jax.random.key(0), progress=False)
      >>> model = init(data, cfg, key=jax.random.key(1))
      >>> model.config == cfg, sorted(model.params)[:2]
      (True, ['down_0', 'embed_0'])
    """
    _check_data(data, config)
    return Model(init_denoiser(_split(key)[0], config, dtype=dtype), config, np.asarray(data.scale))


def _fingerprint(data: Dataset, config: Config, key: jax.Array, dtype) -> dict:
    """What a checkpoint must have been written by to be resumed (module docstring)."""
    return {
        "config": config.fingerprint(),
        "key": key_ints(key),
        "dtype": jnp.dtype(dtype).name,
        "data": {
            "shape": list(data.latents.shape),
            "scale": np.asarray(data.scale, np.float64).tolist(),
            # the latents themselves (and labels, further encodings, geometry): a folder trained
            # on other colours with the same shapes is another run, never resumed
            "digest": data_digest(data),
        },
    }


def data_digest(data: Dataset) -> str:
    """A hash of everything training reads from ``data`` (latents, further encodings, labels,
    vertex counts, geometry), for the checkpoint fingerprint.

    Example:
      >>> from jmeshtex.fldm import Config, build_dataset
      >>> from jmeshtex.data import icosphere
      >>> cfg = Config.tiny(n_copies=1, copy_vertices=40, latent_channels=1, bucket=32)
      >>> d = build_dataset(icosphere(1), cfg, encode=lambda m: m.vertices[:, :1] + 0j,
      ...                   key=jax.random.key(0), progress=False)
      >>> data_digest(d) == data_digest(d._replace(latents=2 * d.latents))
      False
    """
    import hashlib

    h = hashlib.sha1()
    parts = [getattr(data, f, None) for f in ("latents", "num_vertices", "encodings", "labels")]
    for a in [*parts, *jax.tree.leaves(getattr(data, "geometry", None))]:
        if a is None:
            h.update(b"none")
            continue
        a = np.ascontiguousarray(np.asarray(a))
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


def _batch_source(data: Dataset, config: Config, keep: np.ndarray, *, k_batch, k_noise, dtype):
    """``batches(step) -> ((z0, geo, labels, noise key[, masks]), step)``, a function of the step
    (module docstring); the copies stay on the host on CPU and in multi-process runs, else on the
    device. Dropped channels (``keep`` False) are zeroed."""
    on_host = jax.default_backend() == "cpu" or jax.process_count() > 1
    source = data if on_host else _device_resident(data, dtype)

    def batches(step: int):
        z0, geo, labels = training_batch(source, step, config.batch_size, key=k_batch, dtype=dtype)
        if not keep.all():  # collapsed_channels="drop"
            z0 = z0 * keep.astype(z0.dtype)  # (host or device batch alike)
        masks = ()
        if config.mask_conditioning:
            masks = (training_masks(data, step, config.batch_size, key=k_batch),)
        return (z0, geo, labels, jax.random.fold_in(k_noise, step), *masks), np.float32(step)

    return batches


def _driver_step(config: Config, device_mesh: jax.sharding.Mesh, *, channel_weight):
    """The training driver's step: one optimiser step of the denoiser and, with
    ``config.ema_decay > 0``, the weight average; it records the loss."""
    denoiser_step = make_train_step(config, device_mesh, channel_weight=channel_weight)

    def update(params, opt_state, batch):
        args, t = batch
        params, opt_state, loss = denoiser_step(params, opt_state, *args)
        return params, opt_state, {"loss": loss}, t

    return averaged_step(update, decay=config.ema_decay, device_mesh=device_mesh)


def train(
    data: Dataset,
    config: Config,
    *,
    key: jax.Array,
    progress: bool = True,
    checkpoint_dir: str | os.PathLike | None = None,
    stop_after: int | None = None,
    dtype=jnp.complex64,
    device_mesh: jax.sharding.Mesh | None = None,
    devices=None,
) -> TrainResult[Model]:
    """Train the denoiser on the copies of ``data`` for ``config.steps`` steps (resumable).

    Args:
      data: :func:`build_dataset` output.
      config: the :class:`Config` the data was built with.
      key: PRNG key of the initialisation, the batches and the noise (module docstring).
      progress: tqdm bar with ETA and the running loss.
      checkpoint_dir: :class:`~jmeshtex.io.Checkpoints` folder (None: nothing on disk). A
        checkpoint of the same run there is resumed.
      stop_after: run at most this many steps in this call (continue later from the checkpoint).
      dtype: complex dtype of parameters and latents.
      device_mesh: the :class:`jax.sharding.Mesh` to train on (its ``"data"`` axis splits the
        batch; module docstring). None: :func:`jmeshtex.parallel.data_mesh` over ``devices``.
      devices: the devices of the default mesh (None: every device; ``jax.devices()[:1]`` trains
        on one). Not with ``device_mesh``.

    Returns:
      :class:`~jmeshtex.TrainResult` with the :class:`Model` (host NumPy parameters, whatever mesh
      trained them), ``losses["loss"]`` (one per step done, resumed ones included), ``steps``
      (done in total) and ``resumed_from`` (the checkpoint step this call started from, or None).
      A checkpoint written on one mesh resumes on another.

    Raises:
      ConfigError: the data's channels or labels do not match the config; ``batch_size`` is not a
        multiple of the mesh's device count; ``device_mesh`` and ``devices`` both given;
        ``checkpoint_dir`` in a multi-process run (not supported yet).
      CheckpointMismatchError: ``checkpoint_dir`` holds a checkpoint of another run.
      TrainingDivergedError: a loss or the parameters became non-finite.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.fldm import build_dataset
      >>> cfg = Config.tiny(n_copies=2, copy_vertices=60, latent_channels=1, steps=2, bucket=32)
      >>> data = build_dataset(icosphere(1), cfg, encode=lambda m: m.vertices[:, :1] + 0j,
      ...                      key=jax.random.key(0), progress=False)
      >>> r = train(data, cfg, key=jax.random.key(1), progress=False)
      >>> r.steps, r.losses["loss"].shape, bool(np.isfinite(r.losses["loss"]).all())
      (2, (2,), True)
    """
    started = time.perf_counter()
    _check_data(data, config)
    device_mesh = resolve_mesh(device_mesh, devices)
    _check_batch(config, device_mesh)
    k_init, k_batch, k_noise = _split(key)
    weight, keep = channel_weights(data, config)
    batches = _batch_source(data, config, keep, k_batch=k_batch, k_noise=k_noise, dtype=dtype)
    step = _driver_step(
        config,
        device_mesh,
        channel_weight=weight if config.experimental.collapsed_channels == "downweight" else None,
    )
    params = init_denoiser(k_init, config, dtype=dtype)
    state = averaged_state(params, optimizer(config).init(params), decay=config.ema_decay)
    stats = _CheckpointStatistics(data, config, key=jax.random.fold_in(key, 7), dtype=dtype)
    stats.resume(checkpoint_dir, _fingerprint(data, config, key, dtype))
    result = fit(
        step,
        state,
        batches,
        steps=config.steps,
        stop_after=stop_after,
        checkpoints=CheckpointPolicy(
            checkpoint_dir,
            fingerprint=_fingerprint(data, config, key, dtype),
            every=config.checkpoint_every,
            meta=stats.meta,
        ),
        device_mesh=device_mesh,
        progress=Progress(progress, "FLDM train"),
        model=lambda s: Model(fetch(averaged_params(s)), config, np.asarray(data.scale)),
        started=started,
        on_step=stats.on_step,
    )
    result.extra["statistics"] = stats.history
    return result


def channel_weights(data: Dataset, config: Config) -> tuple[np.ndarray, np.ndarray]:
    """``(loss weight [d], kept [d] bool)`` of the latent channels (``config.experimental.collapsed_channels``).

    A channel is collapsed when its mean raw power ``mean |μ_c|²`` over the copies' real vertices is
    below ``config.experimental.collapsed_below`` times the strongest channel's. ``"keep"``: weights 1, all kept;
    ``"downweight"``: a collapsed channel's weight is its power ratio; ``"drop"``: weights 1, the
    collapsed channels not kept (zeroed in training).

    Example:
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.fldm import build_dataset
      >>> cfg = Config.tiny(latent_channels=2, n_copies=1, copy_vertices=0, bucket=32,
      ...                   collapsed_channels="downweight", collapsed_below=0.5)
      >>> enc = lambda m: np.stack([np.ones(m.num_vertices), 0.1 * np.ones(m.num_vertices)], 1) + 0j
      >>> data = build_dataset(icosphere(1), cfg, encode=enc, key=jax.random.key(0), progress=False)
      >>> w, kept = channel_weights(data, cfg)
      >>> w.round(4).tolist(), kept.tolist()
      ([1.0, 0.01], [True, True])
    """
    real = np.arange(data.latents.shape[1])[None] < np.asarray(data.num_vertices)[:, None]
    power = (np.abs(data.latents) ** 2 * real[..., None]).sum((0, 1)) / max(real.sum(), 1)
    ratio = power / max(float(power.max()), 1e-30)
    collapsed = ratio < config.experimental.collapsed_below
    weight = np.ones(len(power), np.float32)
    keep = np.ones(len(power), bool)
    if config.experimental.collapsed_channels == "downweight":
        weight = np.where(collapsed, ratio, 1.0).astype(np.float32)
    elif config.experimental.collapsed_channels == "drop":
        keep = ~collapsed
    return weight, keep


class _CheckpointStatistics:
    """The decoder-free statistics logged at every checkpoint (``config.experimental.stats_samples``).

    At each save point: ``stats_samples`` DDIM-``stats_ddim_steps`` samples of the current model
    (EMA weights when kept) on copy 0, and :func:`~jmeshtex.fldm.latent_statistics` of each; the
    record holds their mean per statistic and, once, the same statistics of copy 0's own latents
    (``"data"``). The history (a list of records by step) goes into every checkpoint's meta, is read
    back on resume and ends up in ``TrainResult.extra["statistics"]``.
    """

    def __init__(self, data: Dataset, config: Config, *, key, dtype):
        self.data, self.config, self.key, self.dtype = data, config, key, dtype
        self.history: list[dict] = []
        self.state = None
        self._geo = None

    def resume(self, checkpoint_dir, fingerprint) -> None:
        if checkpoint_dir is None or self.config.experimental.stats_samples == 0:
            return
        from ..io import Checkpoints

        ckpt = Checkpoints(checkpoint_dir, fingerprint=fingerprint)
        try:
            latest = ckpt.latest_step()
            if latest is not None:
                old = ckpt.read_meta(latest).get("statistics", [])
                self.history = [
                    r for r in old if isinstance(r, dict) and r.get("step", 0) <= latest
                ]
        finally:
            ckpt.close()

    def on_step(self, done, state, batch) -> None:
        self.state = state

    def meta(self, done: int) -> dict:
        if self.config.experimental.stats_samples == 0 or self.state is None:
            return {}
        from ._sample import sample
        from ._statistics import latent_statistics

        if self._geo is None:
            self._geo = denoiser_geometry(
                self.data.meshes[0], knn=self.config.knn, pool_ratio=self.config.pool_ratio
            )
        geo = self._geo
        V = self.data.meshes[0].num_vertices
        t0 = time.perf_counter()
        params = fetch(averaged_params(self.state))
        model = Model(params, self.config, np.asarray(self.data.scale))
        z = sample(
            model,
            geo,
            key=jax.random.fold_in(self.key, done),
            num_samples=self.config.experimental.stats_samples,
            steps=self.config.experimental.stats_ddim_steps,
            dtype=self.dtype,
        ).latents
        per = [latent_statistics(jnp.asarray(zi[:V]), geo.fine) for zi in z]
        record = {
            "step": int(done),
            **{k: float(np.mean([p[k] for p in per])) for k in per[0] if k != "power"},
            "power": np.mean([p["power"] for p in per], axis=0).tolist(),
            "seconds": time.perf_counter() - t0,
        }
        if not any("data" in r for r in self.history):
            ref = latent_statistics(jnp.asarray(self.data.latents[0, :V]), geo.fine)
            record["data"] = {k: v for k, v in ref.items()}
        self.history = [r for r in self.history if r.get("step") != done] + [record]
        return {"statistics": self.history}

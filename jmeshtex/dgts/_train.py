"""Hierarchical WGAN-GP training of DGTS (Hertz et al. 2020, §3.4), resumable.

Levels are trained one after another. At level ``L`` the input template runs through the frozen
generators ``0 … L−1`` (subdividing and rescaling in between) and the trainable generator ``L``; a
patch discriminator scores every face of the result against the level-``L`` training mesh:

.. math:: \\mathcal L_D = \\overline{D(G(z))} - \\overline{D(x_L)} + \\lambda\\,
   \\overline{\\big(\\lVert \\nabla_{\\hat\\phi_f} \\textstyle\\sum_g D(\\hat\\phi)_g \\rVert - 1\\big)^2},
   \\quad \\hat\\phi = \\alpha \\phi(x_L) + (1 - \\alpha) \\phi(G(z))

.. math:: \\mathcal L_G = -\\overline{D(G(z))} + \\gamma\\, \\mathrm{MSE}\\big(G(z^*, 0, …, 0), x_L\\big)

(gradient penalty on interpolated face features, one ``α ~ U(0, 1)`` per critic update, per-face
gradient norms; reconstruction with the fixed noise ``z*`` at the coarsest level, or at levels up
to ``Config.fixed_noise_levels − 1``, and zero noise above). Adam with step decay; one training
step is ``discriminator_steps`` critic updates then ``generator_steps`` generator updates
(:func:`critic_loss`, :func:`generator_loss`).

Equal to the official ``training.py``: from the same weights, training meshes, noise and ``α``, one
official iteration at each of two levels (the losses, the penalty, every gradient, Adam's moments,
the updated weights, and level 1's inputs from the frozen level 0) is reproduced to float32
rounding (``tests/dgts/test_official_training.py``, numbers from the official code run unchanged).

How it runs (each level is one run of the shared training driver):

- the frozen levels ``0 … L−1`` only make inputs for level ``L``; :func:`level_batch` runs them
  forward, level by level, on all noise draws of ``CHUNK`` steps at once;
- :func:`train_chunk` holds level ``L``'s generator and critic only, and runs ``CHUNK`` steps
  per call (``fori_loop``), so every level compiles one program of the same size;
- ``Config.shared_levels`` pads the small levels (masked faces and vertices, the
  padded-neighbourhood contract: no loss or update changes, tested) to one size so equal-width
  levels reuse one compiled step within a call;
- compilation is ahead of time, timed apart from the steps (:class:`LevelReport`); the CLI also
  enables JAX's persistent compilation cache (``jmeshtex dgts --help``);
- several training meshes of one template (e.g. remeshes of the reference from turned templates)
  train one model: each step draws one, whose mesh is the critic's real one and whose own ``z*``
  is reconstructed (beyond the paper).

Checkpoints (``checkpoint_dir``, :class:`jmeshtex.io.Checkpoints`): after every level, and every
``Config.checkpoint_every`` steps within a level (and where ``stop_after`` stops a call), the parameters of the completed levels, ``z*``, the
current level's networks and optimiser states and the loss histories are saved, numbered by the
steps done in all. :func:`train` with the same folder resumes from the newest one and gives the same
parameters as a run that was never interrupted (the noise of every chunk is drawn from the key and
the chunk's index). The folder is tied to the config, the key and the training meshes: another
run there raises :class:`~jmeshtex.CheckpointMismatchError`.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import time
from collections.abc import Sequence
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._config import is_int
from .._errors import ConfigError, InputError
from .._neighborhoods import FaceNeighborhood
from .._random import key_ints
from .._train_result import TrainResult
from .._training import CheckpointPolicy, Progress, fit, optimizer_update
from .._types import Array, Float, PRNGKey
from ..geometry import pad_to
from ..io import Checkpoints
from ..ops import FaceConvStackParams, face_features, masked_mean
from ..optim import flat
from ._config import Config
from ._model import Model, model_like, model_state
from ._multiscale import TrainingMeshes
from ._networks import (
    discriminator,
    discriminator_features,
    generator_level,
    hierarchy_geometry,
    init_level,
    upsample,
)

#: the ``kind`` recorded with every training checkpoint
CHECKPOINT_KIND = "jmeshtex.dgts.train"


@dataclasses.dataclass
class LevelReport:
    """What training one level measured (seconds and final losses), in ``train(...).extra["levels"]``.

    Attributes:
      level: the level, 0 the coarsest.
      steps: training steps of the level (``Config.steps``).
      faces: faces of the level's mesh.
      compile_seconds: compilation of the level's step and of its newest frozen level (the first
        chunk's frozen-level pass is counted here too), 0 where the process had compiled them.
      seconds: wall time of the level in the call that finished it, compilation included (a level
        resumed from a checkpoint counts only the steps after the checkpoint).
      seconds_per_step: ``(seconds − compile_seconds) / steps run``.
      losses: the last step's losses (``LOSS_NAMES``).
    """

    level: int
    steps: int
    faces: int
    compile_seconds: float
    seconds: float
    seconds_per_step: float
    losses: dict[str, float]


class _Opt(NamedTuple):
    g: Any
    d: Any


def _optimizer(config: Config, updates_per_step: int) -> optax.GradientTransformation:
    schedule = optax.exponential_decay(
        config.learning_rate,
        transition_steps=config.learning_rate_decay_every * max(updates_per_step, 1),
        decay_rate=config.learning_rate_decay,
        staircase=True,
    )
    return flat(optax.adam(schedule, b1=config.beta1, b2=config.beta2))


def gradient_penalty(
    d_params: FaceConvStackParams,
    real_features: Float[Array, "F 3 4"],
    fake_features: Float[Array, "F 3 4"],
    nbhd: FaceNeighborhood,
    alpha: Float[Array, ""],
    *,
    negative_slope: float,
    eps: float,
) -> Float[Array, ""]:
    """WGAN-GP term on features interpolated between a real and a fake mesh (same connectivity).

    .. math:: \\overline{(\\lVert \\nabla_{\\hat\\phi_f} \\textstyle\\sum_g D(\\hat\\phi)_g\\rVert_2 - 1)^2},
       \\quad \\hat\\phi = \\alpha\\,\\phi_{\\text{real}} + (1 - \\alpha)\\,\\phi_{\\text{fake}}

    The norm is taken per face over its ``3 × 4`` features (the reference code's ``norm(dim=1)``);
    the mean runs over real faces only (``nbhd.face_mask``), so padded faces change nothing.

    Args:
      d_params: the critic's face-convolution stack (last width 1).
      real_features, fake_features: ``[F, 3, 4]`` face features (:func:`~jmeshtex.ops.face_features`)
        of the real and the generated mesh.
      nbhd: their face neighbourhood.
      alpha: interpolation weight in ``[0, 1]``.
      negative_slope, eps: leaky-ReLU slope and instance-norm regulariser of the critic.

    Returns:
      The scalar penalty.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.geometry import face_neighborhood
      >>> from jmeshtex.ops import init_face_conv_stack
      >>> v, f = icosahedron()
      >>> nb = face_neighborhood(f)
      >>> phi = face_features(jnp.asarray(v, jnp.float32), nb)
      >>> d = init_face_conv_stack(jax.random.key(0), (8, 1))
      >>> gradient_penalty(d, phi, 1.1 * phi, nb, jnp.float32(0.5), negative_slope=0.2, eps=1e-5).shape
      ()
    """
    x = alpha * real_features + (1 - alpha) * fake_features

    def total(x):
        return jnp.sum(
            discriminator_features(d_params, x, nbhd, negative_slope=negative_slope, eps=eps)
        )

    g = jax.grad(total)(x)
    sq = jnp.sum(g * g, axis=(1, 2))
    norm = jnp.sqrt(sq + jnp.asarray(1e-12, sq.dtype))
    return masked_mean((norm - 1) ** 2, nbhd.face_mask)


#: training steps run by one compiled call (a ``fori_loop`` inside): fewer dispatches, and the
#: frozen levels run once per chunk, batched over all its noise draws.
CHUNK = 10


class LevelBatch(NamedTuple):
    """Inputs of ``CHUNK`` training steps of level ``L`` (``S = D + G`` fake meshes each).

    Attributes:
      fake_base: ``[K, S, V_L, 3]`` outputs of the frozen levels ``0 … L−1`` (subdivided and scaled
        into level ``L``'s frame) for fresh noise; the template itself at level 0.
      fake_noise: ``[K, S, V_L, 3]`` the level-``L`` noise of those fakes.
      rec_base, rec_noise: ``[K, G, V_L, 3]`` the same for the reconstruction (its fixed noise,
        ``z*`` at level 0 and zero above unless ``Config.fixed_noise_levels`` says otherwise, from
        ``reconstruction_start`` on; fresh noise below it).
      alpha: ``[K, D]`` gradient-penalty interpolation weights.
      real: ``[K, V_L, 3]`` each step's real mesh: the level-``L`` training mesh of the step's
        reference (one reference drawn per step when training on several).
    """

    fake_base: Float[Array, "K S V 3"]
    fake_noise: Float[Array, "K S V 3"]
    rec_base: Float[Array, "K G V 3"]
    rec_noise: Float[Array, "K G V 3"]
    alpha: Float[Array, "K D"]
    real: Float[Array, "K V 3"]


def _level_output(g, base, z, nbhd: FaceNeighborhood, config: Config):
    """``b + G(b, z)``: a generator level's output on its input ``base`` and noise ``z``."""
    return base + generator_level(
        g, base, nbhd, z, negative_slope=config.negative_slope, eps=config.eps, y_sign=config.y_sign
    )


@functools.partial(jax.jit, static_argnames=("config",))
def _advance(params, vertices, noise, geometry, *, config: Config):
    """One frozen level on a batch: ``s·U(v + G(v, z))`` for every row (forward only)."""
    out = jax.vmap(lambda v, z: _level_output(params, v, z, geometry.nbhd, config))(vertices, noise)
    return jax.vmap(lambda v: upsample(v, geometry.edge_vertices, scale=config.scale_factor))(out)


@functools.partial(jax.jit, static_argnames=("shape", "amplitude"))
def _noise(key, fixed, *, shape: tuple[int, ...], amplitude: float):
    """``[n + m, V, 3]``: ``n`` fresh Gaussian draws, then the ``m`` fixed rows ``fixed [m, V, 3]``."""
    fresh = amplitude * jax.random.normal(key, shape, fixed.dtype)
    return jnp.concatenate([fresh, fixed], axis=0)


def level_batch(
    model_levels,
    geos,
    templates,
    z_stars,
    reals,
    key,
    *,
    config: Config,
    chunk: int,
    z_finer: Sequence = (),
    noise: Sequence | None = None,
    alpha: Float[Array, "K D"] | None = None,
) -> LevelBatch:
    """Draw the noise of ``chunk`` steps of level ``L = len(model_levels)`` and run the frozen
    levels ``0 … L−1`` on it (forward only).

    All draws of the chunk (``chunk·(D + G)`` fakes, and the reconstruction) go through each frozen
    level as one batch, so each level's compiled pass is reused by every later level and chunk.

    Args:
      model_levels: the frozen levels' generators.
      geos: the :class:`~jmeshtex.dgts.core.LevelGeometry` of levels ``0 … L``.
      templates, z_stars: ``[R, V_0, 3]`` each reference's template and fixed noise ``z*``.
      reals: ``[R, V_L, 3]`` each reference's level-``L`` training mesh.
      key: PRNG key of the chunk's draws.
      config, chunk: the training config and the steps of the chunk.
      z_finer: ``[R, V_l, 3]`` each reference's fixed reconstruction noise of levels ``1, 2, …``
        below ``config.experimental.fixed_noise_levels`` (zero noise at the levels it does not reach).
      noise, alpha: given, used instead of the draws from ``key`` (to replay another
        implementation's draws, e.g. the official code's): ``noise[l]`` the fresh
        noise of level ``l = 0 … L``, ``[N, V_l, 3]`` already scaled by the amplitude, rows as
        drawn: the ``chunk·(D + G)`` fakes step by step (each step's ``D`` critic updates, then its
        ``G`` generator updates), then, below ``reconstruction_start``, the ``chunk·G``
        reconstructions; ``alpha`` ``[chunk, D]`` the penalty's weights.

    Returns:
      :class:`LevelBatch`. Each step draws one reference (the first when ``R = 1``): its fakes
      start from its template, its reconstruction and real mesh are its own. With ``L ≥ reconstruction_start`` the reconstructions are ``R`` fixed rows
      (``z*`` at level 0, ``z_finer`` above it, then zero noise), run once and gathered per step.
    """
    c, L, dtype, R = config, len(model_levels), templates.dtype, int(templates.shape[0])
    D, G = c.discriminator_steps, c.generator_steps
    sizes = [int(g.nbhd.vertex_mask.shape[0]) for g in geos[: L + 1]]
    fixed_rec = L >= c.reconstruction_start
    n_fresh = chunk * (D + G) + (0 if fixed_rec else chunk * G)
    keys = jax.random.split(key, L + 2)
    ref = jnp.zeros((chunk,), jnp.int32)  # each step's reference
    if R > 1:
        ref = jax.random.randint(jax.random.fold_in(key, L + 2), (chunk,), 0, R, jnp.int32)
    rec_ref = jnp.arange(R, dtype=jnp.int32) if fixed_rec else jnp.repeat(ref, G)
    rows = jnp.concatenate([jnp.repeat(ref, D + G), rec_ref])  # each row's reference
    # "reconstructed": every row's frozen levels run on the reconstruction's noise, so they run
    # once per reference
    shared = c.experimental.fake_inputs == "reconstructed"
    v = templates.astype(dtype) if shared else templates.astype(dtype)[rows]

    def rec_noise(level: int):  # the reconstruction's noise of every reference at ``level``
        if level == 0:
            return z_stars.astype(dtype)
        if level <= len(z_finer):
            return jnp.asarray(z_finer[level - 1], dtype)
        return jnp.zeros((R, sizes[level], 3), dtype)

    for level in range(L + 1):
        fixed = rec_noise(level) if fixed_rec else jnp.zeros((0, sizes[level], 3), dtype)
        if level < L and shared:
            z = rec_noise(level)
        else:
            given = None if noise is None else noise[level]
            z = _fresh_noise(keys[level], fixed, given, (n_fresh, sizes[level], 3), c, level)
        if level < L:
            v = _advance(model_levels[level], v, z, geos[level], config=c)
    if shared:  # z: level L's noise
        v = v[rows]
    if alpha is None:
        alpha = jax.random.uniform(keys[L + 1], (chunk, D), dtype)
    elif np.shape(alpha) != (chunk, D):
        raise InputError(f"level_batch: alpha must be [{chunk}, {D}], got {np.shape(alpha)}")
    return _batch_of_rows(v, z, ref, jnp.asarray(alpha, dtype), reals.astype(dtype), c, fixed_rec)


def _fresh_noise(key, fixed, given, shape: tuple[int, int, int], config: Config, level: int):
    """``[n + m, V, 3]``: ``n`` fresh draws (from ``key``, or ``given`` ones) then ``fixed``'s rows."""
    if given is None:
        return _noise(key, fixed, shape=shape, amplitude=float(config.noise_amplitude))
    z = jnp.concatenate([jnp.asarray(given, fixed.dtype), fixed], axis=0)
    if z.shape != (shape[0] + fixed.shape[0], *shape[1:]):
        raise InputError(
            f"level_batch: noise[{level}] must be [{shape[0]}, {shape[1]}, 3], "
            f"got {tuple(np.shape(given))}"
        )
    return z


def _batch_of_rows(v, z, ref, alpha, reals, config: Config, fixed_rec: bool) -> LevelBatch:
    """The :class:`LevelBatch` of level-``L`` rows: bases ``v`` and noises ``z`` (``[N, V, 3]``: the
    fakes step by step, then the reconstructions), each step's reference ``ref`` ``[K]``."""
    (chunk,), D, G, V = ref.shape, config.discriminator_steps, config.generator_steps, v.shape[1]
    n_fake = chunk * (D + G)
    fake_base = v[:n_fake].reshape(chunk, D + G, V, 3)
    fake_noise = z[:n_fake].reshape(chunk, D + G, V, 3)
    if fixed_rec:  # one row per reference, gathered per step
        rec_base = jnp.broadcast_to(v[n_fake + ref][:, None], (chunk, G, V, 3))
        rec_noise = jnp.broadcast_to(z[n_fake + ref][:, None], (chunk, G, V, 3))
    else:
        rec_base = v[n_fake:].reshape(chunk, G, V, 3)
        rec_noise = z[n_fake:].reshape(chunk, G, V, 3)
    return LevelBatch(fake_base, fake_noise, rec_base, rec_noise, alpha, reals[ref])


def critic_loss(
    d: FaceConvStackParams,
    fake: Float[Array, "V 3"],
    real: Float[Array, "V 3"],
    alpha: Float[Array, ""],
    nbhd: FaceNeighborhood,
    *,
    config: Config,
) -> tuple[Float[Array, ""], Float[Array, "3"]]:
    """The critic's loss of one update (module docstring, :math:`\\mathcal L_D`).

    .. math:: \\overline{D(\\text{fake})} - \\overline{D(\\text{real})}
       + w_{gp}\\, \\mathrm{GP}(\\alpha)

    (the reference ``discriminator_iter``: ``error_fake − error_real`` plus ``penalty_weight`` times
    the penalty, means over the real faces ``nbhd.face_mask``).

    Args:
      d: the critic's face-convolution stack.
      fake, real: ``[V, 3]`` a generated mesh (treated as a constant) and the level's training mesh.
      alpha: the penalty's interpolation weight.
      nbhd: their face neighbourhood.
      config: ``penalty_weight``, ``negative_slope``, ``eps``.

    Returns:
      ``(loss, [mean score on real, mean score on fake, penalty])`` (the penalty unweighted).

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.geometry import face_neighborhood, to_jax
      >>> from jmeshtex.ops import init_face_conv_stack
      >>> v, f = icosahedron()
      >>> nb, x = to_jax(face_neighborhood(f)), jnp.asarray(v, jnp.float32)
      >>> d = init_face_conv_stack(jax.random.key(0), (8, 1))
      >>> loss, aux = critic_loss(d, 1.1 * x, x, jnp.float32(0.5), nb, config=Config())
      >>> loss.shape, aux.shape
      ((), (3,))
    """
    c = config
    kw = {"negative_slope": c.negative_slope, "eps": c.eps}
    real_f, fake_f = face_features(real, nbhd), face_features(fake, nbhd)
    s_real = masked_mean(discriminator_features(d, real_f, nbhd, **kw), nbhd.face_mask)
    s_fake = masked_mean(discriminator_features(d, fake_f, nbhd, **kw), nbhd.face_mask)
    gp = gradient_penalty(d, real_f, fake_f, nbhd, alpha, **kw)
    return s_fake - s_real + c.penalty_weight * gp, jnp.stack([s_real, s_fake, gp])


def generator_loss(
    g: FaceConvStackParams,
    d: FaceConvStackParams,
    base: Float[Array, "V 3"],
    z: Float[Array, "V 3"],
    rec_base: Float[Array, "V 3"],
    rec_z: Float[Array, "V 3"],
    real: Float[Array, "V 3"],
    nbhd: FaceNeighborhood,
    *,
    config: Config,
) -> tuple[Float[Array, ""], Float[Array, "2"]]:
    """The generator's loss of one update (module docstring, :math:`\\mathcal L_G`).

    .. math:: -\\overline{D(b + G(b, z))} + \\gamma\\,
       \\mathrm{MSE}\\big(b^* + G(b^*, z^*),\\ x_L\\big)

    (the reference ``generator_iter``: ``reconstruction_weight · error_rec − error_fake``, the MSE
    over all vertex coordinates, ``nn.MSELoss``).

    Args:
      g, d: the generator and the critic of the level.
      base, z: ``[V, 3]`` the fake's input (the frozen levels' output, or the template at level 0)
        and its level noise.
      rec_base, rec_z: the same for the reconstruction.
      real: ``[V, 3]`` the level's training mesh.
      nbhd: the level's face neighbourhood.
      config: ``reconstruction_weight``, ``negative_slope``, ``eps``, ``y_sign``.

    Returns:
      ``(loss, [−mean critic score on the fake, reconstruction MSE])``.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.geometry import face_neighborhood, to_jax
      >>> from jmeshtex.ops import init_face_conv_stack
      >>> v, f = icosahedron()
      >>> nb, x = to_jax(face_neighborhood(f)), jnp.asarray(v, jnp.float32)
      >>> g = init_face_conv_stack(jax.random.key(0), (8, 3))
      >>> d = init_face_conv_stack(jax.random.key(1), (8, 1))
      >>> loss, aux = generator_loss(g, d, x, 0.1 * x, x, 0 * x, x, nb, config=Config())
      >>> aux.shape
      (2,)
    """
    c = config
    kw = {"negative_slope": c.negative_slope, "eps": c.eps}
    # two calls, not a vmap over both: the vmapped gathers cost ~25 % more compile and run (CPU)
    fake = _level_output(g, base, z, nbhd, c)
    rec = _level_output(g, rec_base, rec_z, nbhd, c)
    adv = -masked_mean(discriminator(d, fake, nbhd, **kw), nbhd.face_mask)
    mse = masked_mean(jnp.mean((rec - real) ** 2, axis=1), nbhd.vertex_mask)
    return adv + c.reconstruction_weight * mse, jnp.stack([adv, mse])


@functools.partial(jax.jit, static_argnames=("config",))
def train_chunk(g, d, opt, nbhd, batch: LevelBatch, n, *, config: Config):
    """``n ≤ K`` WGAN-GP steps of one level on the inputs ``batch`` (one compiled call).

    Each step: ``discriminator_steps`` critic updates, then ``generator_steps`` generator
    updates (module docstring losses). Only level ``L``'s networks are in here: the frozen levels
    are inputs (:func:`level_batch`), so every level compiles the same small program, and the
    level-``L`` mesh may be padded (``nbhd.face_mask`` / ``vertex_mask``) without changing a loss.

    Returns:
      ``(g, d, opt, losses)``; ``losses[name]`` is ``[K]``, the step's losses for the first ``n``
      entries (the last critic and generator update of each step) and 0 after them.
    """
    c = config
    opt_d = _optimizer(c, c.discriminator_steps)
    opt_g = _optimizer(c, c.generator_steps)

    def d_loss(d, fake, alpha, real):
        return critic_loss(d, fake, real, alpha, nbhd, config=c)

    def g_loss(g, d, base, z, rec_base, rec_z, real):
        return generator_loss(g, d, base, z, rec_base, rec_z, real, nbhd, config=c)

    def step(i, carry):
        g, d, opt, history = carry
        b = jax.tree.map(lambda x: x[i], batch)
        D = c.discriminator_steps

        def d_step(carry, inputs):
            d, state = carry
            base, z, alpha = inputs
            fake = jax.lax.stop_gradient(_level_output(g, base, z, nbhd, c))
            (_, aux), grads = jax.value_and_grad(d_loss, has_aux=True)(d, fake, alpha, b.real)
            return optimizer_update(opt_d, grads, state, d), aux

        def g_step(carry, inputs):
            g, state = carry
            base, z, rbase, rz = inputs
            (_, aux), grads = jax.value_and_grad(g_loss, has_aux=True)(
                g, d, base, z, rbase, rz, b.real
            )
            return optimizer_update(opt_g, grads, state, g), aux

        (d, sd), d_aux = jax.lax.scan(
            d_step, (d, opt.d), (b.fake_base[:D], b.fake_noise[:D], b.alpha)
        )
        (g, sg), g_aux = jax.lax.scan(
            g_step, (g, opt.g), (b.fake_base[D:], b.fake_noise[D:], b.rec_base, b.rec_noise)
        )
        last_d = d_aux[-1] if D else jnp.zeros(3, b.real.dtype)
        return g, d, _Opt(sg, sd), history.at[i].set(jnp.concatenate([last_d, g_aux[-1]]))

    K = batch.alpha.shape[0]
    history = jnp.zeros((K, len(LOSS_NAMES)), batch.real.dtype)
    g, d, opt, history = jax.lax.fori_loop(0, n, step, (g, d, opt, history))
    return g, d, opt, {name: history[:, i] for i, name in enumerate(LOSS_NAMES)}


#: the losses :func:`train_chunk` reports per step (critic on real / fake, penalty, generator
#: adversarial / reconstruction MSE); the keys of ``train(...).losses``
LOSS_NAMES = ("d_real", "d_fake", "penalty", "g_adv", "g_rec")


# ----------------------------------------------------------------------------------------------
# checkpoints
# ----------------------------------------------------------------------------------------------


def _fingerprint(references: tuple[TrainingMeshes, ...], config: Config, key: PRNGKey) -> dict:
    """What a checkpoint folder is tied to: the config (``Config.fingerprint``), the key and a hash
    of the training meshes (of every reference, in order)."""
    h = hashlib.sha256()
    for meshes in references:
        for a in (meshes.template, *meshes.vertices, *meshes.faces):
            a = np.ascontiguousarray(a)
            h.update(str((a.shape, a.dtype.str)).encode())
            h.update(a.tobytes())
    return {
        "config": config.fingerprint(),
        "key": key_ints(key),
        "meshes": h.hexdigest(),
    }


def _level_state(config: Config, level: int, g, d) -> dict:
    """The state of a level in progress: its networks and their optimiser states."""
    return {
        "g": g,
        "d": d,
        "opt": _Opt(
            _optimizer(config, config.generator_steps).init(g),
            _optimizer(config, config.discriminator_steps).init(d),
        ),
    }


def _checkpoint_like(config: Config, meta: dict, sizes: Sequence[int]) -> dict:
    """The structure, shapes and dtypes of the checkpoint ``meta`` describes (for restoring);
    ``sizes``: the training levels' vertex counts."""
    finer = sizes[1 : config.experimental.fixed_noise_levels]
    like = {"model": model_like(config, int(meta["completed_levels"]), sizes[0], finer)}
    if meta["level_steps"]:
        level = int(meta["completed_levels"])
        key = jax.random.key(0)
        like["current"] = _level_state(
            config,
            level,
            init_level(config, level, generator=True, key=key),
            init_level(config, level, generator=False, key=key),
        )
    return like


# ----------------------------------------------------------------------------------------------
# the training loop
# ----------------------------------------------------------------------------------------------


def train(
    meshes: TrainingMeshes | Sequence[TrainingMeshes],
    config: Config,
    *,
    key: PRNGKey,
    levels: int | None = None,
    progress: bool = True,
    checkpoint_dir: str | os.PathLike | None = None,
    stop_after: int | None = None,
    device_mesh: jax.sharding.Mesh | None = None,
    snapshot_every: int | None = None,
) -> TrainResult[Model]:
    """Train the DGTS hierarchy on multi-scale training meshes, level by level (§3.4).

    Args:
      meshes: from :func:`~jmeshtex.dgts.training_meshes`; or several fitted from one template
        (same faces at every level, e.g. one reference remeshed under several template rotations,
        ``training_meshes(..., rotation=)``). Each step then draws one: the critic's real mesh and
        the reconstruction are that one's, each with its own ``z*`` (the model keeps the first's).
        Beyond the paper, which trains on one.
      config: :class:`~jmeshtex.dgts.Config` (``Config()`` is the paper's; ``checkpoint_every``).
      key: PRNG key of the initialisation, ``z*`` and every noise draw.
      levels: train only the first ``levels`` levels (default: all of ``meshes``).
      progress: show a tqdm progress bar with ETA per level.
      checkpoint_dir: checkpoint folder (module docstring); when it already holds checkpoints of
        this run (same config up to ``checkpoint_every``, key and meshes), training resumes from
        the newest. None: nothing on disk.
      stop_after: run at most this many steps (over all levels) in this call, checkpointing where
        it stops (call again with the same folder to continue); None: to the end.
      device_mesh: a one-device :class:`jax.sharding.Mesh` to train on (None: JAX's default
        device). A DGTS step reads one training mesh, so there is no batch to split: a mesh of
        several devices is refused (the contract's keyword, kept so every method takes it).
      snapshot_every: every this many steps (rounded up to a multiple of ``CHUNK``) and at the end
        of each level, record one sample and the reconstruction of the level's current generator
        (``[V_l, 3]`` float64, level ``l``'s frame) in ``extra["snapshots"]`` as dicts
        ``{"level", "step", "sample", "reconstruction"}`` (training progress, for figures).

    Returns:
      :class:`~jmeshtex.TrainResult`: ``model`` (a :class:`~jmeshtex.dgts.Model` of the completed
      levels), ``losses[name]`` (``LOSS_NAMES``) of every step done, level after level (level
      ``l``'s at ``[l·steps, (l+1)·steps)``), ``steps`` (done in all), ``seconds``,
      ``resumed_from`` (the checkpoint step resumed from, or None), ``extra["levels"]`` (one
      :class:`LevelReport` per completed level), ``extra["compiled_steps"]`` (level steps compiled
      by this call; padded levels share one) and ``extra["snapshots"]`` with ``snapshot_every``.

    Raises:
      ConfigError: ``levels`` outside ``[1, meshes.num_levels]``; ``stop_after`` or
        ``snapshot_every`` not a non-negative / positive integer; a ``device_mesh`` of several
        devices.
      InputError: training meshes whose levels are not successive midpoint subdivisions, or
        several that do not share the first's levels and faces.
      CheckpointMismatchError: ``checkpoint_dir`` holds a run with another config, key or meshes.
      TrainingDivergedError: a loss or a parameter is not finite (nothing non-finite is saved).

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.dgts import PrepareConfig, training_meshes
      >>> tm = training_meshes(icosahedron(), icosahedron(), config=PrepareConfig(levels=2, steps=0),
      ...                      key=jax.random.key(0))
      >>> cfg = Config(num_layers=3, start_features=4, min_features=4, max_features=4, steps=2, shared_levels=2)
      >>> result = train(tm, cfg, key=jax.random.key(3), progress=False)
      >>> result.model.num_levels, result.steps, result.losses["g_rec"].shape
      (2, 4, (4,))
      >>> [r.faces for r in result.extra["levels"]]
      [20, 80]
    """
    t_start = time.perf_counter()
    if stop_after is not None and not is_int(stop_after, 0):
        raise ConfigError(f"stop_after must be an int >= 0 or None, got {stop_after!r}")
    device = _one_device(device_mesh)
    run, budget = _Hierarchy.start(meshes, config, key, levels, snapshot_every), stop_after
    fingerprint = _fingerprint(run.references, config, key)
    ckpt = None if checkpoint_dir is None else Checkpoints(checkpoint_dir, fingerprint=fingerprint)
    with jax.default_device(device):
        try:
            if ckpt is not None:
                run.restore(ckpt)
            for level in range(len(run.gs), run.total):
                ran, complete = run.train_level(level, ckpt, progress, budget)
                budget = None if budget is None else budget - ran
                if not complete:
                    break
        finally:
            if ckpt is not None:
                ckpt.close()
    return run.result(t_start)


def _one_device(device_mesh: jax.sharding.Mesh | None):
    """The device of a one-device mesh (None: JAX's default); a larger mesh is refused."""
    if device_mesh is None:
        return None
    if not isinstance(device_mesh, jax.sharding.Mesh):
        raise ConfigError(f"device_mesh must be a jax.sharding.Mesh or None, got {device_mesh!r}")
    if device_mesh.size != 1:
        raise ConfigError(
            f"dgts.train reads one training mesh per step, so a device_mesh of "
            f"{device_mesh.size} devices has no batch to split. Fix: pass None, or a one-device mesh"
        )
    return device_mesh.devices.flat[0]


@dataclasses.dataclass
class _Hierarchy:
    """One :func:`train` call: the level-independent inputs, the frozen levels trained so far, the
    loss histories and reports, and the level in progress restored from a checkpoint."""

    config: Config
    references: tuple[TrainingMeshes, ...]
    total: int
    geos: list
    padded: list
    keys: tuple  # (initialisation, fixed noise, training)
    z_star: np.ndarray
    z_star_finer: tuple
    snap_every: int | None
    chunk_step: Any  # the jitted chunk of steps, one per call: equal-sized levels share its compile
    gs: list = dataclasses.field(default_factory=list)
    ds: list = dataclasses.field(default_factory=list)
    history: dict = dataclasses.field(default_factory=lambda: {n: [] for n in LOSS_NAMES})
    reports: list = dataclasses.field(default_factory=list)
    snapshots: list = dataclasses.field(default_factory=list)
    current: dict | None = None  # the restored state of the level in progress
    current_steps: int = 0
    resumed_from: int | None = None
    partial: int = 0  # steps done in a level this call stopped in (``stop_after``)
    compiled: dict = dataclasses.field(default_factory=dict)  # equal-sized levels share one
    unpadded: dict = dataclasses.field(default_factory=dict)  # the newest batch, for snapshots

    @classmethod
    def start(cls, meshes, config: Config, key, levels, snapshot_every) -> _Hierarchy:
        """Check the arguments, build the (padded) geometry of the levels and draw ``z*``."""
        references = _references(meshes)
        meshes = references[0]
        total = meshes.num_levels if levels is None else levels
        if not is_int(total, 1) or total > meshes.num_levels:
            raise ConfigError(
                f"levels must be an int in [1, {meshes.num_levels}] (the training meshes' levels), "
                f"got {levels!r}"
            )
        if snapshot_every is not None and not is_int(snapshot_every, 1):
            raise ConfigError(f"snapshot_every must be an int >= 1, got {snapshot_every!r}")
        V = [len(v) for v in meshes.vertices]
        # the padded sizes come from the training meshes, not from `levels`: resuming stays exact
        n_geo = max(int(total), min(config.shared_levels, meshes.num_levels))
        geos, faces = hierarchy_geometry(meshes.faces[0], V[0], n_geo)
        for level in range(n_geo):
            if not np.array_equal(faces[level], meshes.faces[level]):
                raise InputError(
                    f"training mesh level {level} is not the midpoint subdivision of level "
                    f"{level - 1}"
                )
        keys = tuple(jax.random.split(key, 3))
        k_z, amplitude = keys[1], config.noise_amplitude
        return cls(
            config=config,
            references=references,
            total=int(total),
            geos=geos,
            padded=_padded_sizes(geos, config.shared_levels),
            keys=keys,
            z_star=np.asarray(amplitude * jax.random.normal(k_z, (V[0], 3), jnp.float32)),
            z_star_finer=tuple(  # reference r's at level l: key fold_in(k_finer, l), then r
                np.asarray(
                    amplitude
                    * jax.random.normal(_finer_key(k_z, level, 0), (V[level], 3), jnp.float32)
                )
                for level in range(1, min(config.experimental.fixed_noise_levels, len(V)))
            ),
            snap_every=None if snapshot_every is None else -(-int(snapshot_every) // CHUNK),
            chunk_step=jax.jit(functools.partial(_chunk_step, config=config)),
        )

    def restore(self, ckpt: Checkpoints) -> None:
        """The frozen levels, ``z*``, histories and the level in progress of the newest checkpoint."""
        step = ckpt.latest_step()
        if step is None:
            return
        meta = ckpt.read_meta(step)
        if meta.get("kind") != CHECKPOINT_KIND:
            raise InputError(
                f"{ckpt.directory} holds {meta.get('kind')!r}, not DGTS training checkpoints"
            )
        sizes = [len(v) for v in self.references[0].vertices]
        state, meta = ckpt.restore(_checkpoint_like(self.config, meta, sizes), step=step)
        model = state["model"]
        self.gs, self.ds = list(model["generators"]), list(model["discriminators"])
        self.z_star = np.asarray(model["z_star"], np.float32)
        self.z_star_finer = tuple(np.asarray(z, np.float32) for z in model["z_star_finer"])
        self.current, self.current_steps = state.get("current"), int(meta["level_steps"])
        self.history = {name: list(meta["losses"][name]) for name in LOSS_NAMES}
        self.reports = [LevelReport(**r) for r in meta["levels"]]
        self.resumed_from = step

    def fixed_noise(self) -> tuple[jax.Array, tuple]:
        """Every reference's ``z*`` ``[R, V_0, 3]`` and fixed finer noise (the first's restored)."""
        c, k_z, R = self.config, self.keys[1], len(self.references)

        def draw(first, key_of):
            first = jnp.asarray(first, jnp.float32)
            rest = [
                c.noise_amplitude * jax.random.normal(key_of(r), first.shape, jnp.float32)
                for r in range(1, R)
            ]
            return jnp.stack([first, *rest])

        z_stars = draw(self.z_star, lambda r: jax.random.fold_in(k_z, r))
        z_finer = tuple(
            draw(z, lambda r, level=level: _finer_key(k_z, level, r))
            for level, z in enumerate(self.z_star_finer, start=1)
        )
        return z_stars, z_finer

    def model(self) -> Model:
        c = self.config
        return Model(c, tuple(self.gs), tuple(self.ds), self.z_star, self.z_star_finer)

    def record(self, done: int) -> dict:
        """The meta data of a checkpoint ``done`` steps into the level in progress."""
        return {
            "kind": CHECKPOINT_KIND,
            "config": self.config.to_dict(),
            "completed_levels": len(self.gs),
            "level_steps": done,
            "levels": [dataclasses.asdict(r) for r in self.reports],
        }

    def batches(self, level: int, t_batch: list):
        """The level's ``first step -> (nbhd, batch, n)`` (its frozen levels' pass per chunk)."""
        c, nbhd = self.config, self.geos[level].nbhd
        reals = jnp.stack([jnp.asarray(m.vertices[level], jnp.float32) for m in self.references])
        templates = jnp.stack([jnp.asarray(m.template, jnp.float32) for m in self.references])
        frozen, k_level = tuple(self.gs), jax.random.fold_in(self.keys[2], level)
        z_stars, z_finer = self.fixed_noise()

        def batches(i: int):
            t = time.perf_counter()
            key = jax.random.fold_in(k_level, i // CHUNK)
            args = (frozen, self.geos[: level + 1], templates, z_stars, reals, key)
            batch = level_batch(*args, config=c, chunk=CHUNK, z_finer=z_finer)
            if not t_batch:  # the first chunk's frozen-level pass compiles new shapes
                jax.block_until_ready(batch)
                t_batch.append(time.perf_counter() - t)
            self.unpadded["batch"] = padded = nbhd, batch
            if level < len(self.padded):
                padded = pad_level(nbhd, batch, self.padded[level])
            return (*padded, jnp.int32(min(CHUNK, c.steps - i)))

        return batches

    def snapshot(self, level: int):
        """``fit``'s ``on_step``: record the level's sample and reconstruction (``snapshot_every``)."""

        def on_step(done: int, state, batch) -> None:
            if -(-done // CHUNK) % self.snap_every == 0 or done == self.config.steps:
                sample, rec = _snapshot(state["g"], *self.unpadded["batch"], config=self.config)
                self.snapshots.append(
                    {"level": level, "step": done, "sample": sample, "reconstruction": rec}
                )

        return None if self.snap_every is None else on_step

    def train_level(self, level: int, ckpt, progress: bool, budget: int | None) -> tuple[int, bool]:
        """Train ``level`` (one :func:`fit` call) from its restored or initial state; the steps run
        and whether the level is complete (it is unless ``budget`` ran out)."""
        c, S = self.config, self.config.steps
        if self.current is not None:
            state, start, self.current = self.current, self.current_steps, None
        else:
            state, start = (
                _level_state(c, level, *_initial_params(c, level, self.keys[0], self.gs, self.ds)),
                0,
            )
        end = S if budget is None else min(S, start + budget)
        every = c.checkpoint_every
        frozen = self.model_state() if ckpt is not None else None
        t_batch: list = []
        run = fit(
            self.chunk_step,
            state,
            self.batches(level, t_batch),
            steps=S,
            stop_after=end - start,
            steps_per_call=CHUNK,
            checkpoints=CheckpointPolicy(
                ckpt,
                every=None if every is None else -(-every // CHUNK) * CHUNK,
                final=end < S,  # a level that stops early is saved where it stops
                offset=level * S,
                saved=lambda state: {"model": frozen, "current": state},
                meta=self.record,
            ),
            start=start,
            history=self.history,
            progress=Progress(progress, f"DGTS level {level + 1}/{self.total}", ("g_rec", "g_adv")),
            on_step=self.snapshot(level),
            compiled=self.compiled,
        )
        self.history = {k: list(v) for k, v in run.losses.items()}
        if end < S:
            self.partial = end
            return end - start, False
        self.finish_level(level, run, start, t_batch[0] if t_batch else 0.0, ckpt)
        return end - start, True

    def model_state(self) -> dict:
        return model_state(self.model())

    def finish_level(self, level: int, run: TrainResult, start: int, t_batch: float, ckpt) -> None:
        """Report the level, freeze its networks and checkpoint the completed levels."""
        S, compile_seconds = self.config.steps, run.compile_seconds + t_batch
        self.reports.append(
            LevelReport(
                level=level,
                steps=S,
                faces=int(len(self.references[0].faces[level])),
                compile_seconds=compile_seconds,
                seconds=run.seconds,
                seconds_per_step=(run.seconds - compile_seconds) / max(S - start, 1),
                losses={k: v[-1] for k, v in self.history.items()} if S else {},
            )
        )
        self.gs.append(run.model["g"])
        self.ds.append(run.model["d"])
        if ckpt is not None:
            meta = {**self.record(0), "losses": self.history}
            ckpt.save((level + 1) * S, {"model": self.model_state()}, meta=meta)

    def result(self, t_start: float) -> TrainResult[Model]:
        total, S = self.total, self.config.steps
        done = len(self.gs[:total])
        return TrainResult(
            model=Model(
                self.config,
                tuple(self.gs[:total]),
                tuple(self.ds[:total]),
                self.z_star,
                self.z_star_finer,
            ),
            losses={k: np.asarray(v[: total * S], np.float64) for k, v in self.history.items()},
            steps=done * S + self.partial,
            seconds=time.perf_counter() - t_start,
            compile_seconds=sum(r.compile_seconds for r in self.reports[:total]),
            resumed_from=self.resumed_from,
            extra={
                "levels": self.reports[:total],
                "compiled_steps": len(self.compiled),
                **({"snapshots": self.snapshots} if self.snap_every else {}),
            },
        )


def _finer_key(k_z, level: int, reference: int):
    """The key of reference ``reference``'s fixed reconstruction noise at ``level ≥ 1``."""
    return jax.random.fold_in(jax.random.fold_in(jax.random.fold_in(k_z, 2**31), level), reference)


def _references(meshes) -> tuple[TrainingMeshes, ...]:
    """``meshes`` as a non-empty tuple of :class:`TrainingMeshes` sharing the first's levels and faces."""
    references = (meshes,) if isinstance(meshes, TrainingMeshes) else tuple(meshes)
    if not references or not all(isinstance(m, TrainingMeshes) for m in references):
        raise InputError(
            "train: meshes must be TrainingMeshes (from dgts.training_meshes) or a non-empty "
            "sequence of them"
        )
    first = references[0]
    for r, m in enumerate(references[1:], 1):
        same = m.num_levels == first.num_levels and all(
            np.array_equal(a, b) for a, b in zip(m.faces, first.faces, strict=True)
        )
        if not same or np.shape(m.template) != np.shape(first.template):
            raise InputError(
                f"train: training meshes {r} do not share the levels and faces of training meshes "
                "0; fit every reference from the same template with the same PrepareConfig.levels"
            )
    return references


def _chunk_step(state: dict, batch: tuple, *, config: Config):
    """:func:`train_chunk` as the driver's ``(state, batch) -> (state, losses)``."""
    g, d, opt, losses = train_chunk(state["g"], state["d"], state["opt"], *batch, config=config)
    return {"g": g, "d": d, "opt": opt}, losses


def _snapshot(g, nbhd, batch: LevelBatch, *, config: Config) -> tuple[np.ndarray, np.ndarray]:
    """The current generator's sample and reconstruction on the first row of ``batch`` (float64)."""
    out = _generate_pair(
        g,
        nbhd,
        batch.fake_base[0, 0],
        batch.fake_noise[0, 0],
        batch.rec_base[0, 0],
        batch.rec_noise[0, 0],
        config=config,
    )
    return tuple(np.asarray(x, np.float64) for x in out)


@functools.partial(jax.jit, static_argnames=("config",))
def _generate_pair(g, nbhd, base, z, rec_base, rec_z, *, config: Config):
    return _level_output(g, base, z, nbhd, config), _level_output(g, rec_base, rec_z, nbhd, config)


def _padded_sizes(geos, shared_levels: int) -> list[dict[str, int]]:
    """Target sizes (``F``, ``V``, ``M``) of the levels padded to share one step (``shared_levels``)."""
    shared = geos[: min(int(shared_levels), len(geos))]
    if len(shared) < 2:
        return []
    last = shared[-1].nbhd
    size = {
        "F": int(last.faces.shape[0]),
        "V": int(last.vertex_mask.shape[0]),
        "M": max(int(g.nbhd.vertex_faces.shape[1]) for g in shared),
    }
    return [size] * len(shared)


def pad_level(nbhd: FaceNeighborhood, batch: LevelBatch, size: dict[str, int]):
    """Pad one level's training inputs to ``size`` (``F``, ``V``, ``M``): masked faces and vertices.

    Padded vertices sit at the origin with zero noise and belong to no real face, padded faces are
    masked out of every feature, norm and mean (:func:`train_chunk`), so training on the padded level
    gives the same parameters as on the level itself (tested).
    """
    extra = size["V"] - int(batch.real.shape[-2])

    def rows(x):
        return jnp.pad(x, [(0, 0)] * (x.ndim - 2) + [(0, extra), (0, 0)])

    batch = batch._replace(
        **{
            k: rows(getattr(batch, k))
            for k in ("fake_base", "fake_noise", "rec_base", "rec_noise", "real")
        }
    )
    return pad_to(nbhd, size), batch


def _initial_params(config: Config, level: int, key, gs: list, ds: list):
    """Fresh parameters of ``level``, or the previous level's where the widths match (warm start)."""
    out = []
    for generator, previous, k in zip(
        (True, False), (gs, ds), jax.random.split(jax.random.fold_in(key, level)), strict=True
    ):
        same = level > 0 and config.level_features(
            level, generator=generator
        ) == config.level_features(level - 1, generator=generator)
        out.append(previous[-1] if same else init_level(config, level, generator=generator, key=k))
    return out[0], out[1]

"""Diffusion in the tangent bundle: schedules, forward process, ε-loss, DDPM / DDIM samplers, inpainting.

Field Latent Diffusion (Mitchel, Esteves, Makadia, CVPR 2024, §5 and supplement §8.2) diffuses the
FL-VAE's tangent-vector latents ``z ∈ ℂ^{V×d}`` with circular complex Gaussian noise
(:func:`jmeshtex.ops.tangent_noise`, ``E|ε|² = 1``), which has the same law in every gauge, so every
step below commutes with frame rotations as long as the denoiser does.

- forward process (eq. 8): ``z_t = √ᾱ_t z_0 + √(1 − ᾱ_t) ε``;
- training loss (eq. 10): ``E ‖ε − ε_θ(z_t, t)‖²`` over real vertices and channels;
- what the network predicts (:data:`PREDICTIONS`): ``"epsilon"``, the paper's ``ε_θ`` (eq. 10), or
  ``"v"`` (Salimans & Ho 2022), ``v = √ᾱ_t ε − √(1 − ᾱ_t) z_0``, read back as
  ``ε̂ = √(1 − ᾱ_t) z_t + √ᾱ_t v̂``. The v-loss is the ε-loss plus the ``z_0``-loss,
  ``|v − v̂|² = |ε − ε̂|² + |z_0 − ẑ_0|²``: at high noise the ε-loss is blind to an error that the
  samplers amplify by ``√((1 − ᾱ_t)/ᾱ_t)`` (156 at ``t = T−1`` of the linear schedule) in
  ``ẑ_0``, and a small denoiser's ε-residual of a few percent there drives the samples' magnitude
  several times past the data's (measured on Spot, ``docs/results.md``);
- latent scaling (eq. 38–39): per channel ``s_c = (E_v |μ_vc|²)^{-1/2}`` so that the scaled latents
  have ``E|z|² = 1`` like the noise; the sampler divides by ``s`` before decoding;
- ancestral DDPM (eq. 11, 29–31):
  ``z_{t−1} = (z_t − β_t/√(1−ᾱ_t) ε_θ)/√α_t + σ_t ε'`` with ``σ_t² = β̃_t = β_t (1−ᾱ_{t−1})/(1−ᾱ_t)``;
- DDIM (Song et al. 2021, eq. 12) on a sub-sequence of timesteps, ``η = 0`` deterministic;
- inpainting (eq. 14): after every step, the known region is replaced by the known latents noised to
  the new timestep, and at ``t = 0`` by the known latents themselves.

Timesteps are 0-based: ``t ∈ {0, …, T−1}``, ``ᾱ_t = Π_{s≤t} (1 − β_s)``, and the "previous"
``ᾱ_{−1} = 1``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._config import is_finite_number, is_int
from .._errors import ConfigError, InputError
from .._types import Array, Bool, Complex, Float, Int, PRNGKey
from ..ops import tangent_noise

SCHEDULES = ("linear", "cosine")
PREDICTIONS = ("epsilon", "v")
LOSS_NAMES = {"epsilon": "ε-loss", "v": "v-loss"}  #: how reports name each prediction's loss


class Schedule(NamedTuple):
    """A noise schedule of ``T`` steps (float64 NumPy on the host; cast inside the samplers).

    Attributes:
      betas: ``[T]`` ``β_t``.
      alphas: ``[T]`` ``α_t = 1 − β_t``.
      alpha_bars: ``[T]`` ``ᾱ_t = Π_{s ≤ t} α_s``.
    """

    betas: Float[np.ndarray, " T"]
    alphas: Float[np.ndarray, " T"]
    alpha_bars: Float[np.ndarray, " T"]

    @property
    def num_steps(self) -> int:
        return int(self.betas.shape[0])


def make_schedule(kind: str = "linear", *, num_steps: int = 1000, shift: float = 1.0) -> Schedule:
    """The linear (Ho et al. 2020) or cosine (Nichol & Dhariwal 2021) β schedule, optionally shifted.

    .. math:: \\text{linear: } \\beta_t = \\beta_1 + \\tfrac{t}{T-1}(\\beta_T - \\beta_1),\\;
       \\beta_1 = 10^{-4}\\tfrac{1000}{T},\\ \\beta_T = 0.02\\tfrac{1000}{T};\\qquad
       \\text{cosine: } \\bar\\alpha(t) = \\frac{\\cos^2(\\frac{t/T + s}{1 + s}\\frac{\\pi}{2})}
       {\\cos^2(\\frac{s}{1+s}\\frac{\\pi}{2})},\\ s = 0.008,\\ \\beta_t \\le 0.999

    ``shift`` > 1 moves every step to more noise, dividing its signal-to-noise ratio
    ``ᾱ/(1 − ᾱ)`` by ``shift²`` (log-SNR − 2 log shift; Hoogeboom et al. 2023, "simple diffusion",
    beyond the paper): a field of many vertices keeps its coarse layout visible at a per-vertex SNR
    where a small image has lost it, so the unshifted schedule decides the layout in a few of its
    first steps. ``β`` is recomputed from the shifted ``ᾱ`` (clipped at 0.999 as before).

    Args:
      kind: ``"linear"`` or ``"cosine"``.
      num_steps: ``T`` (the paper: 1000).
      shift: the SNR shift factor (1: the plain schedule).

    Returns:
      :class:`Schedule`.

    Example:
      >>> s = make_schedule("linear")
      >>> s.num_steps, float(s.betas[0]), round(float(s.betas[-1]), 4), bool(s.alpha_bars[-1] < 1e-4)
      (1000, 0.0001, 0.02, True)
    """
    if kind not in SCHEDULES:
        raise ConfigError(f"schedule must be one of {SCHEDULES}, got {kind!r}")
    if not is_int(num_steps, 2):
        raise ConfigError(f"num_steps must be an integer >= 2, got {num_steps!r}")
    if not (is_finite_number(shift) and shift > 0):
        raise ConfigError(f"shift must be a finite number > 0, got {shift!r}")
    T = int(num_steps)
    if kind == "linear":
        scale = 1000.0 / T
        betas = np.minimum(np.linspace(1e-4 * scale, 0.02 * scale, T, dtype=np.float64), 0.999)
    else:
        s = 0.008
        x = np.arange(T + 1, dtype=np.float64) / T
        f = np.cos((x + s) / (1 + s) * math.pi / 2) ** 2
        betas = np.clip(1.0 - f[1:] / f[:-1], 0.0, 0.999)
    if shift != 1.0:
        ab = np.cumprod(1.0 - betas)
        ab = ab / (ab + shift**2 * (1.0 - ab))  # SNR / shift²
        betas = np.clip(1.0 - ab / np.concatenate([[1.0], ab[:-1]]), 0.0, 0.999)
    alphas = 1.0 - betas
    return Schedule(betas=betas, alphas=alphas, alpha_bars=np.cumprod(alphas))


def _coef(values: np.ndarray, t, like: Array) -> Array:
    """``values[t]`` as a real array broadcastable against ``like`` ([B] or scalar t)."""
    from ..ops import real_dtype

    v = jnp.asarray(values, dtype=real_dtype(like.dtype))[t]
    return v.reshape(v.shape + (1,) * (like.ndim - v.ndim)).astype(like.dtype)


def _signal_noise(schedule: Schedule, t, like: Array) -> tuple[Array, Array]:
    """``(√ᾱ_t, √(1 − ᾱ_t))`` broadcastable against ``like``."""
    return _coef(np.sqrt(schedule.alpha_bars), t, like), _coef(
        np.sqrt(1.0 - schedule.alpha_bars), t, like
    )


def q_sample(
    schedule: Schedule,
    z0: Complex[Array, "*B V C"],
    t: Int[Array, "*B"],
    noise: Complex[Array, "*B V C"],
) -> Complex[Array, "*B V C"]:
    """Forward diffusion to timestep ``t`` (eq. 8).

    .. math:: z_t = \\sqrt{\\bar\\alpha_t}\\, z_0 + \\sqrt{1 - \\bar\\alpha_t}\\, \\varepsilon

    Args:
      schedule: the noise schedule.
      z0: clean (scaled) latents, tangent vectors in each vertex's frame; optional leading batch.
      t: timesteps, shape of the batch dimensions (or a scalar).
      noise: ``ε``, same shape as ``z0`` (:func:`jmeshtex.ops.tangent_noise`).

    Returns:
      ``z_t``, same shape and dtype as ``z0``.

    Example:
      >>> s = make_schedule("linear")
      >>> z = jnp.ones((3, 2), jnp.complex64)
      >>> zt = q_sample(s, z, jnp.array(999), jnp.zeros_like(z))
      >>> bool(jnp.abs(zt).max() < 0.01)
      True
    """
    a, b = _signal_noise(schedule, t, z0)
    return a * z0 + b * noise.astype(z0.dtype)


def epsilon_loss(
    eps_pred: Complex[Array, "*B V C"],
    eps: Complex[Array, "*B V C"],
    vertex_mask: Bool[Array, "*B V"] | None = None,
    *,
    kind: str = "l2",
    channel_weight: Float[Array, " C"] | None = None,
) -> Float[Array, ""]:
    """The ε-prediction loss (eq. 10): mean squared modulus of the error over real vertices and channels.

    .. math:: L = \\frac{1}{|\\{v\\}|\\, C} \\sum_{v\\ \\mathrm{real}} \\sum_c |\\varepsilon_{vc} - \\hat\\varepsilon_{vc}|^2

    Args:
      eps_pred: predicted noise.
      eps: the noise that was added.
      vertex_mask: True for real vertices (padding excluded); None: all.
      kind: ``"l2"`` (squared modulus, eq. 10) or ``"l1"`` (modulus, the released ``get_l1_loss``).
      channel_weight: ``[C]`` weights of the channels' errors (None: all 1); the mean stays over
        ``C`` channels.

    Returns:
      Scalar real loss.

    Example:
      >>> float(epsilon_loss(jnp.array([[1j], [5.0]]), jnp.zeros((2, 1), complex), jnp.array([True, False])))
      1.0
    """
    err = jnp.abs(eps_pred - eps.astype(eps_pred.dtype))
    if kind == "l2":
        err = err**2
    elif kind != "l1":
        raise ConfigError(f"epsilon_loss: kind must be 'l1' or 'l2', got {kind!r}")
    if channel_weight is not None:
        err = err * jnp.asarray(channel_weight, err.dtype)
    if vertex_mask is None:
        return jnp.mean(err)
    w = vertex_mask.astype(err.dtype)[..., None]
    return jnp.sum(err * w) / jnp.maximum(jnp.sum(w) * err.shape[-1], 1.0)


def _check_prediction(prediction: str) -> None:
    if prediction not in PREDICTIONS:
        raise ConfigError(f"prediction must be one of {PREDICTIONS}, got {prediction!r}")


def prediction_target(
    schedule: Schedule,
    prediction: str,
    z0: Complex[Array, "*B V C"],
    t: Int[Array, "*B"],
    noise: Complex[Array, "*B V C"],
) -> Complex[Array, "*B V C"]:
    """What the network is trained to output for ``z_t = q_sample(schedule, z0, t, noise)``.

    .. math:: \\text{epsilon: } \\varepsilon,\\qquad
       \\text{v: } v = \\sqrt{\\bar\\alpha_t}\\,\\varepsilon - \\sqrt{1 - \\bar\\alpha_t}\\, z_0

    Args:
      schedule: the noise schedule.
      prediction: ``"epsilon"`` or ``"v"``.
      z0: clean (scaled) latents; optional leading batch.
      t: timesteps, shape of the batch dimensions (or a scalar).
      noise: the ``ε`` that made ``z_t``.

    Returns:
      The target, same shape as ``z0``; the loss is :func:`epsilon_loss` (masked mean ``|·|²``) of
      the network output against it.

    Example:
      >>> s = make_schedule("linear")
      >>> z0, e = jnp.ones((2, 1), jnp.complex64), 1j * jnp.ones((2, 1), jnp.complex64)
      >>> v = prediction_target(s, "v", z0, jnp.array(999), e)
      >>> bool(jnp.allclose(v, -z0, atol=0.01))  # v ≈ −z0 at high noise
      True
    """
    _check_prediction(prediction)
    if prediction == "epsilon":
        return noise.astype(z0.dtype)
    a, b = _signal_noise(schedule, t, z0)
    return a * noise.astype(z0.dtype) - b * z0


def epsilon_from_output(
    schedule: Schedule,
    prediction: str,
    z_t: Complex[Array, "*B V C"],
    t: Int[Array, "*B"],
    output: Complex[Array, "*B V C"],
) -> Complex[Array, "*B V C"]:
    """The noise estimate ``ε̂`` from the network's output, for the samplers.

    .. math:: \\text{epsilon: } \\hat\\varepsilon = \\text{output},\\qquad
       \\text{v: } \\hat\\varepsilon = \\sqrt{1 - \\bar\\alpha_t}\\, z_t + \\sqrt{\\bar\\alpha_t}\\, \\hat v

    Per-timestep scalars only, so it commutes with gauge changes and isometries like the network.

    Example:
      >>> s = make_schedule("linear", num_steps=100)
      >>> z0, e = jnp.ones((2, 1), jnp.complex64), 0.5j * jnp.ones((2, 1), jnp.complex64)
      >>> t = jnp.array(40)
      >>> v = prediction_target(s, "v", z0, t, e)
      >>> bool(jnp.allclose(epsilon_from_output(s, "v", q_sample(s, z0, t, e), t, v), e, atol=1e-6))
      True
    """
    _check_prediction(prediction)
    if prediction == "epsilon":
        return output.astype(z_t.dtype)
    a, b = _signal_noise(schedule, t, z_t)
    return b * z_t + a * output.astype(z_t.dtype)


def latent_scale(
    mu: Complex[Array, "*B V C"],
    vertex_mask: Bool[Array, "*B V"] | None = None,
    *,
    per_channel: bool = True,
    released: bool = False,
) -> Float[np.ndarray, " C"]:
    """Per-channel scale that gives the latents unit mean squared modulus (eq. 38–39).

    .. math:: s_c = \\Big(\\frac{1}{N}\\sum_{v\\ \\mathrm{real}} |\\mu_{vc}|^2\\Big)^{-1/2}

    No centring: a mean of tangent vectors in different frames is not gauge-invariant; ``|μ|`` is.

    Args:
      mu: latents (any leading batch dims).
      vertex_mask: True for real vertices; None: all.
      per_channel: True: one scale per channel; False: one σ for all channels, repeated ``C``
        times (the mean power over channels becomes 1).
      released: the released ``train.py``'s noise scale instead (``per_channel`` ignored): it
        trains on the raw latents with noise ``σ·N(0, 1)`` per real component, ``σ = √2·mean|μ|``
        over all channels, which is unit complex noise on ``μ / (√2 σ)``: ``s = 1 / (2 mean|μ|)``
        for every channel (the data's mean power becomes ``E|μ|² / (4 (E|μ|)²)``, below 1).

    Returns:
      ``[C]`` float64 NumPy scales; train on ``s·μ``, decode ``z/s``.

    Example:
      >>> latent_scale(np.array([[2.0 + 0j, 1j], [2j, -1.0 + 0j]])).tolist()
      [0.5, 1.0]
    """
    if released:
        a = np.abs(np.asarray(mu))
        w = np.ones(a.shape[:-1]) if vertex_mask is None else np.asarray(vertex_mask, np.float64)
        mean_mag = (a * w[..., None]).sum() / max(w.sum() * a.shape[-1], 1.0)
        if not np.isfinite(mean_mag) or mean_mag <= 0:
            raise InputError("latent_scale: latents must be finite and not identically zero")
        return np.full(a.shape[-1], 1.0 / (2.0 * mean_mag))
    m = np.abs(np.asarray(mu)) ** 2
    if vertex_mask is None:
        mean = m.reshape(-1, m.shape[-1]).mean(0)
    else:
        w = np.asarray(vertex_mask, np.float64)[..., None]
        mean = (m * w).reshape(-1, m.shape[-1]).sum(0) / max(w.sum(), 1.0)
    if not np.all(np.isfinite(mean)) or (np.any(mean <= 0) if per_channel else mean.sum() <= 0):
        raise InputError(
            "latent_scale: latents must be finite and not identically zero in any channel"
        )
    if not per_channel:
        mean = np.full_like(mean, mean.mean())
    return 1.0 / np.sqrt(mean)


def ddpm_step(
    schedule: Schedule,
    z_t: Complex[Array, "V C"],
    t: Int[Array, ""],
    eps_pred: Complex[Array, "V C"],
    noise: Complex[Array, "V C"],
) -> Complex[Array, "V C"]:
    """One ancestral DDPM step ``t → t−1`` (eq. 11, 29–31).

    .. math:: z_{t-1} = \\frac{1}{\\sqrt{\\alpha_t}}\\Big(z_t - \\frac{\\beta_t}{\\sqrt{1-\\bar\\alpha_t}}
       \\hat\\varepsilon\\Big) + \\sigma_t \\varepsilon',\\qquad
       \\sigma_t^2 = \\frac{1-\\bar\\alpha_{t-1}}{1-\\bar\\alpha_t}\\beta_t,\\ \\sigma_0 = 0

    Args:
      schedule: the noise schedule.
      z_t: current latents.
      t: current timestep (scalar int).
      eps_pred: the denoiser's ``ε̂(z_t, t)``.
      noise: fresh tangent noise ``ε'`` (ignored at ``t = 0``).

    Returns:
      ``z_{t−1}``.

    Example:
      >>> s = make_schedule("linear", num_steps=100)
      >>> z = jnp.ones((2, 1), jnp.complex64)
      >>> bool(jnp.allclose(ddpm_step(s, z, jnp.array(0), jnp.zeros_like(z), z), z / float(np.sqrt(s.alphas[0]))))
      True
    """
    ab_prev = np.concatenate([[1.0], schedule.alpha_bars[:-1]])
    sigma = np.sqrt(schedule.betas * (1.0 - ab_prev) / (1.0 - schedule.alpha_bars))
    c1 = _coef(1.0 / np.sqrt(schedule.alphas), t, z_t)
    c2 = _coef(schedule.betas / np.sqrt(1.0 - schedule.alpha_bars), t, z_t)
    return c1 * (z_t - c2 * eps_pred.astype(z_t.dtype)) + _coef(sigma, t, z_t) * noise.astype(
        z_t.dtype
    )


def ddim_step(
    schedule: Schedule,
    z_t: Complex[Array, "V C"],
    t: Int[Array, ""],
    t_prev: Int[Array, ""],
    eps_pred: Complex[Array, "V C"],
    noise: Complex[Array, "V C"],
    *,
    eta: float = 0.0,
) -> Complex[Array, "V C"]:
    """One DDIM step ``t → t_prev`` (Song et al. 2021, eq. 12; ``t_prev = −1`` means the clean end).

    .. math:: \\hat z_0 = \\frac{z_t - \\sqrt{1-\\bar\\alpha_t}\\hat\\varepsilon}{\\sqrt{\\bar\\alpha_t}},\\quad
       z_{t'} = \\sqrt{\\bar\\alpha_{t'}}\\hat z_0 + \\sqrt{1-\\bar\\alpha_{t'}-\\sigma^2}\\,\\hat\\varepsilon
       + \\sigma\\varepsilon',\\quad
       \\sigma = \\eta\\sqrt{\\frac{1-\\bar\\alpha_{t'}}{1-\\bar\\alpha_t}\\Big(1-\\frac{\\bar\\alpha_t}{\\bar\\alpha_{t'}}\\Big)}

    Args:
      schedule: the noise schedule.
      z_t: current latents.
      t: current timestep.
      t_prev: next (smaller) timestep, ``−1`` for the final clean estimate (``ᾱ_{−1} = 1``).
      eps_pred: ``ε̂(z_t, t)``.
      noise: fresh noise (unused when ``eta = 0``).
      eta: 0 (deterministic DDIM) … 1 (DDPM-like variance).

    Returns:
      ``z_{t_prev}``.

    Example:
      >>> s = make_schedule("linear", num_steps=100)
      >>> z0 = jnp.ones((2, 1), jnp.complex64); e = 0.5j * z0
      >>> zt = q_sample(s, z0, jnp.array(30), e)
      >>> bool(jnp.allclose(ddim_step(s, zt, jnp.array(30), jnp.array(-1), e, e), z0))
      True
    """
    from ..ops import real_dtype

    ab = jnp.asarray(
        np.concatenate([schedule.alpha_bars, [1.0]]), real_dtype(z_t.dtype)
    )  # [-1] -> 1.0
    a_t, a_p = ab[t], ab[t_prev]
    sig = eta * jnp.sqrt(jnp.maximum((1.0 - a_p) / (1.0 - a_t) * (1.0 - a_t / a_p), 0.0))
    direction = jnp.sqrt(jnp.maximum(1.0 - a_p - sig * sig, 0.0)).astype(z_t.dtype)
    sigma = sig.astype(z_t.dtype)
    eps_pred = eps_pred.astype(z_t.dtype)
    z0 = (z_t - jnp.sqrt(1.0 - a_t).astype(z_t.dtype) * eps_pred) / jnp.sqrt(a_t).astype(z_t.dtype)
    a_p = a_p.astype(z_t.dtype)
    return jnp.sqrt(a_p) * z0 + direction * eps_pred + sigma * noise.astype(z_t.dtype)


def timestep_sequence(diffusion_steps: int, sample_steps: int) -> np.ndarray:
    """Evenly spaced decreasing timesteps for DDIM, from ``T−1`` down to 0.

    Args:
      diffusion_steps: ``T``.
      sample_steps: how many timesteps to visit (``1 … T``).

    Example:
      >>> timestep_sequence(1000, 4).tolist()
      [999, 666, 333, 0]
    """
    if not 1 <= sample_steps <= diffusion_steps:
        raise ConfigError(f"sampling steps must be in [1, {diffusion_steps}], got {sample_steps}")
    return np.round(np.linspace(diffusion_steps - 1, 0, sample_steps)).astype(np.int32)


class Inpaint(NamedTuple):
    """What inpainting keeps: latents ``z0`` (scaled, as the model sees them) where ``mask`` is True.

    Attributes:
      z0: ``[V, C]`` known latents.
      mask: ``[V]`` True where the latents are known and kept.
    """

    z0: Complex[Array, "V C"]
    mask: Bool[Array, " V"]


def sample_from_noise(
    denoise: Callable[[Array, Array], Array],
    schedule: Schedule,
    z_T: Complex[Array, "V C"],
    step_noise: Complex[Array, "S V C"],
    *,
    method: str = "ddim",
    num_steps: int = 50,
    eta: float = 0.0,
    inpaint: Inpaint | None = None,
    inpaint_noise: Complex[Array, "S V C"] | None = None,
) -> Complex[Array, "V C"]:
    """Run the reverse process from given noise: a deterministic function of ``(z_T, step_noise)``.

    Every random draw is an argument, so the sampler is a plain map from noise to samples; a gauge
    change or isometry applied to the noise gives the transformed sample (the distributional
    equivariance the harness checks). :func:`~jmeshtex.fldm.sample` draws the noise from a key.

    Inpainting (eq. 14): after each step to timestep ``t'``, ``z_{t'}[mask] = √ᾱ_{t'} z0 +
    √(1−ᾱ_{t'}) ε''`` with ``ε'' = inpaint_noise[i]``; after the last step ``z[mask] = z0`` exactly.

    Args:
      denoise: ``(z_t [V, C], t scalar int32) -> ε̂ [V, C]`` (geometry and parameters closed over).
      schedule: the noise schedule.
      z_T: ``[V, C]`` initial noise.
      step_noise: ``[S, V, C]`` per-step noise (``S = T`` for DDPM, ``num_steps`` for DDIM).
      method: ``"ddpm"`` (ancestral, all ``T`` steps) or ``"ddim"``.
      num_steps: DDIM steps (ignored by DDPM).
      eta: DDIM ``η``.
      inpaint: optional :class:`Inpaint`.
      inpaint_noise: ``[S, V, C]`` noise for the known region (required with ``inpaint``).

    Returns:
      ``[V, C]`` clean latents (scaled).

    Example:
      >>> s = make_schedule("linear", num_steps=20)
      >>> z = sample_from_noise(lambda z, t: jnp.zeros_like(z), s, jnp.ones((3, 1), jnp.complex64),
      ...                       jnp.zeros((4, 3, 1), jnp.complex64), method="ddim", num_steps=4)
      >>> z.shape, bool(jnp.allclose(z, float(np.sqrt(1 / s.alpha_bars[-1]))))
      ((3, 1), True)
    """
    if method not in ("ddpm", "ddim"):
        raise ConfigError(f"method must be 'ddpm' or 'ddim', got {method!r}")
    T = schedule.num_steps
    if method == "ddpm":
        ts = np.arange(T - 1, -1, -1, dtype=np.int32)
        prev = ts - 1
    else:
        ts = timestep_sequence(T, num_steps)
        prev = np.concatenate([ts[1:], [-1]]).astype(np.int32)
    if step_noise.shape != (len(ts), *z_T.shape):
        raise InputError(
            f"step_noise must have shape {(len(ts), *z_T.shape)} for {method}, got {step_noise.shape}"
        )
    if inpaint is not None and (inpaint_noise is None or inpaint_noise.shape != step_noise.shape):
        raise InputError(f"inpainting needs inpaint_noise of shape {step_noise.shape}")
    ab = jnp.asarray(np.concatenate([schedule.alpha_bars, [1.0]]))

    def step(z, inputs):
        t, tp, noise, known_noise = inputs
        eps = denoise(z, t)
        if method == "ddpm":
            z = ddpm_step(schedule, z, t, eps, noise)
        else:
            z = ddim_step(schedule, z, t, tp, eps, noise, eta=eta)
        if inpaint is not None:
            a = ab[tp].astype(z.real.dtype)
            known = (
                jnp.sqrt(a).astype(z.dtype) * inpaint.z0.astype(z.dtype)
                + jnp.sqrt(1 - a).astype(z.dtype) * known_noise
            )
            z = jnp.where(inpaint.mask[:, None], known, z)
        return z, None

    known_noise = step_noise if inpaint_noise is None else inpaint_noise.astype(step_noise.dtype)
    z, _ = jax.lax.scan(step, z_T, (jnp.asarray(ts), jnp.asarray(prev), step_noise, known_noise))
    if inpaint is not None:  # t' = -1 gave ᾱ = 1 already; this makes the kept region bit-exact
        z = jnp.where(inpaint.mask[:, None], inpaint.z0.astype(z.dtype), z)
    return z


def draw_sampling_noise(
    key: PRNGKey,
    shape: tuple[int, int],
    *,
    method: str,
    num_steps: int,
    diffusion_steps: int,
    inpaint: bool = False,
    dtype=jnp.complex64,
) -> tuple[Array, Array, Array | None]:
    """Tangent noise for :func:`sample_from_noise`: ``(z_T, step_noise, inpaint_noise or None)``.

    Args:
      key: PRNG key; the same key gives the same noise.
      shape: ``(V, C)`` of one latent field.
      method: ``"ddpm"`` (``diffusion_steps`` steps of noise) or ``"ddim"`` (``num_steps``).
      num_steps: DDIM steps (ignored by DDPM).
      diffusion_steps: ``T`` of the schedule.
      inpaint: also draw the noise of the known region.
      dtype: complex dtype.

    Example:
      >>> zT, steps, known = draw_sampling_noise(jax.random.key(0), (5, 2), method="ddim", num_steps=3,
      ...                                        diffusion_steps=100)
      >>> zT.shape, steps.shape, known
      ((5, 2), (3, 5, 2), None)
    """
    s = diffusion_steps if method == "ddpm" else num_steps
    k0, k1, k2 = jax.random.split(key, 3)
    z_T = tangent_noise(k0, shape, dtype=dtype)
    steps = tangent_noise(k1, (s, *shape), dtype=dtype)
    known = tangent_noise(k2, (s, *shape), dtype=dtype) if inpaint else None
    return z_T, steps, known

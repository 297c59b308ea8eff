"""The FL-VAE training objective: KL of the tangent-space posterior, reparameterised draws, the loss.

The posterior at each vertex is an isotropic Gaussian ``N(μ, σ² I₂)`` in every tangent plane
(paper eq. 26–28): isotropic, so its KL and its noise do not depend on the frame. The loss is the
L1 reconstruction of the one-ring samples from a draw of the latents plus ``λ`` times the KL.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._errors import InputError
from .._types import Array, Bool, Complex, Float, Int, PRNGKey
from ._config import Config
from ._decoder import blend_log_predictions, decode_barycentric_raw, decode_points_raw
from ._model import FieldLatents, Params, _check_samples, encode_samples


def kl_per_channel(latents: FieldLatents) -> Float[Array, "V d"]:
    """KL of the tangent-space posterior ``N(μ, σ² I₂)`` to ``N(0, I₂)``, in nats, per vertex and channel.

    .. math:: \\mathrm{KL}_{pc} = \\sigma_{pc}^2 + \\tfrac12 |\\mu_{pc}|^2 - 1 - 2 \\log\\sigma_{pc}

    A channel whose KL is near 0 everywhere carries nothing (posterior collapse).

    Example:
      >>> import jax.numpy as jnp
      >>> lat = FieldLatents(jnp.array([[0.0, 2.0]], jnp.complex64), jnp.zeros((1, 2), jnp.float32))
      >>> kl_per_channel(lat).tolist()
      [[0.0, 2.0]]
    """
    mu, ls = latents.mu, latents.log_sigma
    abs2 = mu.real * mu.real + mu.imag * mu.imag
    return jnp.exp(2 * ls) + 0.5 * abs2 - 1 - 2 * ls


def kl_divergence(latents: FieldLatents) -> Float[Array, " V"]:
    """KL of the tangent-space posterior ``N(μ, σ² I₂)`` per channel to ``N(0, I₂)``, mean over channels.

    .. math:: \\mathrm{KL}_p = \\frac1d \\sum_c \\big(\\sigma_c^2 + \\tfrac12 |\\mu_c|^2 - 1 - 2 \\log\\sigma_c\\big)

    (paper eq. 26–28: a Gaussian in each tangent plane, isotropic so that it is gauge-invariant).

    Example:
      >>> import jax.numpy as jnp
      >>> kl_divergence(FieldLatents(jnp.zeros((2, 3), jnp.complex64), jnp.zeros((2, 3), jnp.float32))).tolist()
      [0.0, 0.0]
    """
    return jnp.mean(kl_per_channel(latents), axis=-1)


def sample_latents(latents: FieldLatents, *, key: PRNGKey) -> Complex[Array, "V d"]:
    """Reparameterised draw ``z = μ + σ (ε_r + i ε_i)``, ``ε ~ N(0, 1)`` (rotation-invariant noise).

    Args:
      latents: :class:`~jmeshtex.fl.FieldLatents` ``[V, d]``.
      key: PRNG key of the noise.

    Returns:
      ``[V, d]`` complex draws, in the latents' frames (the noise is isotropic, so a gauge change
      of the latents changes the draw by the same rotation in distribution).

    Example:
      >>> import jax, jax.numpy as jnp
      >>> lat = FieldLatents(jnp.ones((2, 3), jnp.complex64), jnp.full((2, 3), -30.0, jnp.float32))
      >>> z = sample_latents(lat, key=jax.random.key(0))
      >>> z.shape, bool(jnp.allclose(z, lat.mu))  # σ = e^-30: the draw is the mean
      ((2, 3), True)
    """
    rdt = latents.log_sigma.dtype
    eps = jax.random.normal(key, (2, *latents.mu.shape), rdt)
    sigma = jnp.exp(latents.log_sigma)
    return latents.mu + jax.lax.complex(sigma * eps[0], sigma * eps[1]).astype(latents.mu.dtype)


def vae_loss(
    params: Params,
    config: Config,
    log_q: Complex[Array, "V S"],
    rgb: Float[Array, "V S 3"],
    mask: Bool[Array, "V S"],
    *,
    key: PRNGKey,
    corners: Int[Array, "V S 3"] | None = None,
    bary: Float[Array, "V S 3"] | None = None,
    vertex_mask: Bool[Array, " V"] | None = None,
    corner_logs: Complex[Array, "V S 3"] | None = None,
    kl_scale: Float[Array, ""] | float = 1.0,
) -> tuple[Float[Array, ""], dict]:
    """FL-VAE loss: L1 reconstruction of the one-ring samples + ``λ`` KL (paper eq. 26–28).

    With ``config.loss_normalization == "paper"`` (eq. 26–28 as printed; the presets):

    .. math:: \\mathcal L = \\frac{\\sum_{p,i} m_{pi} \\lVert D(z_p, \\log_p q_i) - c_i\\rVert_1}{\\sum m}
       + \\frac{\\lambda}{V} \\sum_p \\sum_{c=1}^{d} \\mathrm{KL}_{pc}, \\qquad z_p = \\mu_p + \\sigma_p \\epsilon

    (``‖·‖₁`` over RGB; ``KL_pc = σ² + ½|μ|² − 1 − 2 log σ``, the KL of ``N(μ, σ² I₂)`` to
    ``N(0, I₂)``; means over valid samples and real vertices). With ``"mean"`` (the shipped model's
    recipe) the L1 term is also divided by 3 and the KL averaged over channels (``λ`` effectively
    ``3/d`` as strong).

    Log decoder with ``config.experimental.log_objective == "blended"`` (the default): each sample ``x`` is
    decoded as at inference, ``Σ_k b_k D(z_{v_k}, log_{v_k} x)`` over its face's three corners
    (``corners``, ``bary``, ``corner_logs`` required); with ``"vertex"`` each vertex reconstructs
    its own one-ring from its own latent. Barycentric ablation: each sample is decoded from the
    interpolated invariants of its face's three corner latents (``corners``, ``bary`` required).

    KL options: ``config.experimental.free_bits = τ > 0`` replaces each channel's batch-mean KL by
    ``max(KL_c, τ)`` (a floor with no gradient below it); ``kl_scale`` multiplies ``λ`` (the
    warm-up of :func:`~jmeshtex.fl.train`).

    Args:
      params: :class:`Params`.
      config: :class:`~jmeshtex.fl.Config` (static).
      log_q, rgb, mask: one-ring samples of all ``V`` vertices (:func:`encode_samples`).
      key: PRNG key of the reparameterisation noise.
      corners: ``[V, S, 3]`` vertex ids of each sample's face (barycentric mode).
      bary: ``[V, S, 3]`` barycentric coordinates of each sample (barycentric mode).
      vertex_mask: ``[V]`` True for the vertices whose one-rings enter the loss (padding, and
        boundary vertices when they are dropped, excluded from the L1 and the KL).
      corner_logs: ``[V, S, 3]`` complex ``log_{v_k}(x) / r_{v_k}`` of each sample in each corner's
        frame (the blended log objective).
      kl_scale: factor on ``λ`` (a scalar, may be traced).

    Returns:
      ``(loss, {"l1": ..., "kl": ..., "kl_channels": [d]})``: ``kl`` the KL term before the floor
      (normalised as the loss), ``kl_channels`` each channel's mean KL in nats.

    Example:
      >>> import jax, jax.numpy as jnp
      >>> from jmeshtex.fl import init
      >>> c = Config(latent_dim=2, features=8, num_heads=2, num_blocks=1).replace(log_objective="vertex")
      >>> p = init(c, key=jax.random.key(0)).params
      >>> log = jnp.ones((1, 5), jnp.complex64)
      >>> loss, aux = vae_loss(p, c, log, jnp.full((1, 5, 3), 0.3), jnp.ones((1, 5), bool), key=jax.random.key(1))
      >>> bool(jnp.isfinite(loss)), sorted(aux)
      (True, ['kl', 'kl_channels', 'l1'])
    """
    _check_samples(log_q, rgb, mask)
    if config.decoder == "barycentric" and (corners is None or bary is None):
        raise InputError("vae_loss with decoder='barycentric' needs corners and bary [V, S, 3]")
    blended = config.decoder == "log" and config.experimental.log_objective == "blended"
    if blended and (corners is None or bary is None or corner_logs is None):
        raise InputError(
            "vae_loss with the blended log objective needs corners, bary and corner_logs "
            "[V, S, 3] (fl.core.mesh_batch builds them), or config.replace(log_objective='vertex')"
        )
    lat = encode_samples(params, config, log_q, rgb, mask)
    z = sample_latents(lat, key=key)
    rdt = lat.log_sigma.dtype
    v, s = log_q.shape

    def flat(a):  # [V, S, 3] per-sample corners -> [V·S, 3] rows of the face decoders
        return jnp.reshape(a, (v * s, 3))

    if config.decoder == "barycentric":
        pred = decode_barycentric_raw(params.decoder, config, z, flat(corners), flat(bary))
        pred = pred.reshape(v, s, 3)
    elif blended:
        pred = blend_log_predictions(
            params.decoder, config, z, flat(corners), flat(corner_logs), flat(bary)
        ).reshape(v, s, 3)
    else:
        pred = decode_points_raw(params.decoder, config, z, log_q)
    vm = (
        jnp.ones(log_q.shape[:1], rdt)
        if vertex_mask is None
        else jnp.asarray(vertex_mask).astype(rdt)
    )
    m = jnp.asarray(mask).astype(rdt) * vm[:, None]
    err = jnp.sum(jnp.abs(pred - jnp.asarray(rgb).astype(rdt)), axis=-1)
    paper = config.loss_normalization == "paper"
    l1 = jnp.sum(err * m) / ((1 if paper else 3) * jnp.maximum(jnp.sum(m), 1))
    channels = jnp.sum(kl_per_channel(lat) * vm[:, None], axis=0) / jnp.maximum(jnp.sum(vm), 1)
    reduce = jnp.sum if paper else jnp.mean  # "paper": summed over the d channels
    kl = reduce(channels)
    floored = kl
    if config.experimental.free_bits > 0:
        floored = reduce(jnp.maximum(channels, jnp.asarray(config.experimental.free_bits, rdt)))
    weight = jnp.asarray(config.kl_weight, rdt) * jnp.asarray(kl_scale, rdt)
    loss = l1 + weight * floored
    return loss, {"l1": l1, "kl": kl, "kl_channels": channels}

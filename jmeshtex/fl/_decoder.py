"""The FL-VAE decoder: a real MLP neural field on gauge-invariant features of a latent (eq. 5, 18).

For a latent ``z ∈ C^d`` at vertex p and a point q with (normalised) log coordinate ``log_p(q)``, the
decoder reads only quantities that do not change when p's frame turns (``z → z e^{-iα}``,
``log → log e^{-iα}``):

.. math:: \\phi(z, q) = \\big[\\,|z_c|^2,\\ \\mathrm{Re}, \\mathrm{Im}\\,(z_i \\bar z_j)_{i<j},\\
   \\mathrm{Re}, \\mathrm{Im}\\,(\\log_p(q)\\, \\bar z_c)\\,\\big], \\qquad \\mathrm{rgb}(q) = 0.5 + \\mathrm{MLP}(\\phi)

(the Hermitian invariants ``vec_{j≥i}(z z*)`` and the positional features ``log_p(q)·conj(z)``), with
``decoder_layers`` dense layers and SiLU between them. At inference a point in a triangle gets the
three vertex predictions blended barycentrically. The barycentric ablation ("FL-VAE (Bary.)",
paper Table 1) instead interpolates the invariants of the three corner latents across the triangle
and drops the log coordinates.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .._types import Array, Complex, Float, Int
from ._encoder import _dense_init, _dense_size, mlp


def num_features(config) -> int:
    """Width of the decoder input for ``config``: ``d²`` invariants (+ ``2d`` positional, log mode)."""
    d = config.latent_dim
    return d * d + (2 * d if config.decoder == "log" else 0)


def decoder_sizes(config) -> tuple[int, ...]:
    """Layer widths of the decoder MLP, input to output."""
    return (num_features(config), *([config.decoder_features] * (config.decoder_layers - 1)), 3)


def init_decoder(draw, config, *, dtype=jnp.float32) -> tuple:
    """Random real dense layers of the decoder MLP (``decoder_layers`` layers, output 3)."""
    return _dense_init(draw, decoder_sizes(config), dtype)


def decoder_size(config) -> int:
    """Number of standard normals :func:`init_decoder` draws."""
    return _dense_size(decoder_sizes(config))


def _invariants(mu: Complex[Array, "... d"]) -> Float[Array, "... D"]:
    """``[|z_c|², Re(z_i z̄_j), Im(z_i z̄_j) (i < j)]``: ``d²`` real invariants of a common rotation."""
    d = mu.shape[-1]
    rows, cols = np.triu_indices(d, k=1)
    outer = mu[..., rows] * jnp.conj(mu[..., cols])
    return jnp.concatenate([mu.real * mu.real + mu.imag * mu.imag, outer.real, outer.imag], axis=-1)


def decoder_features(
    config, mu: Complex[Array, "... d"], log_q: Complex[Array, "..."] | None
) -> Float[Array, "... D"]:
    """The decoder's gauge-invariant input ``φ(z, q)`` (module docstring).

    Args:
      config: :class:`~jmeshtex.fl.Config`.
      mu: ``[..., d]`` complex latents (broadcast against ``log_q``).
      log_q: ``[...]`` complex normalised log coordinates in the same frame as ``mu`` (log mode),
        or None (barycentric mode: invariants only).

    Returns:
      ``[..., D]`` real features, ``D = num_features(config)``.

    Example:
      >>> import jax.numpy as jnp
      >>> from jmeshtex.fl import Config
      >>> c = Config(latent_dim=2)
      >>> f = decoder_features(c, jnp.array([1j, 1.0]), jnp.array(1j))
      >>> f.tolist()  # |z|², Re/Im z0 z̄1, Re/Im log·z̄
      [1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0]
    """
    inv = _invariants(mu)
    if log_q is None:
        return inv
    pos = log_q[..., None] * jnp.conj(mu)
    inv = jnp.broadcast_to(inv, (*pos.shape[:-1], inv.shape[-1]))
    return jnp.concatenate([inv, pos.real, pos.imag], axis=-1)


def apply_decoder(layers, features: Float[Array, "... D"]) -> Float[Array, "... 3"]:
    """``0.5 + MLP(φ)``: colours around mid-grey (no squashing; clip when writing images)."""
    out = mlp(layers, features.astype(layers[0][0].dtype))
    return out + jnp.asarray(0.5, out.dtype)


def decode_points_raw(
    layers, config, mu: Complex[Array, "V d"], log_q: Complex[Array, "V S"]
) -> Float[Array, "V S 3"]:
    """Log-coordinate decoder: colour of each point from its vertex's latent and log coordinate."""
    cdt = mu.dtype
    return apply_decoder(
        layers, decoder_features(config, mu[:, None, :], jnp.asarray(log_q).astype(cdt))
    )


def decode_barycentric_raw(
    layers, config, mu: Complex[Array, "V d"], corners: Int[Array, "N 3"], bary: Float[Array, "N 3"]
) -> Float[Array, "N 3"]:
    """Barycentric-ablation decoder: corner invariants interpolated, then the MLP."""
    inv = _invariants(mu)[corners]  # [N, 3, D]
    feats = jnp.einsum("nk,nkd->nd", jnp.asarray(bary).astype(inv.dtype), inv)
    return apply_decoder(layers, feats)


def blend_log_predictions(
    layers,
    config,
    mu: Complex[Array, "V d"],
    corners: Int[Array, "N 3"],
    logs: Complex[Array, "N 3"],
    bary: Float[Array, "N 3"],
) -> Float[Array, "N 3"]:
    """Log decoder at points in triangles: ``Σ_k b_k D(z_{v_k}, log_{v_k}(x))`` (eq. 18 + blending)."""
    feats = decoder_features(config, mu[corners], jnp.asarray(logs).astype(mu.dtype))  # [N, 3, D]
    pred = apply_decoder(layers, feats)
    return jnp.einsum("nk,nkc->nc", jnp.asarray(bary).astype(pred.dtype), pred)

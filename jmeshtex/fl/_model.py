"""The FL-VAE model: its parameters, the :class:`Model` record, initialisation and the pure forward passes.

:func:`encode_samples` (one-ring samples → latents, paper eq. 21–25) and the decoders
:func:`decode_points`, :func:`decode_barycentric`, :func:`decode_vertex_colors_from_latents`
(eq. 5, 18) are pure functions of ``(params, config, arrays)``: jit/grad/vmap-safe, the config
static. The mesh-level functions of :mod:`jmeshtex.fl` take a :class:`Model` instead.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp

from .._errors import ConfigError, InputError
from .._jit import jit_once
from .._types import Array, Bool, Complex, Float, Int, PRNGKey
from ._config import Config
from ._decoder import (
    apply_decoder,
    blend_log_predictions,
    decode_barycentric_raw,
    decode_points_raw,
    decoder_features,
    decoder_size,
    init_decoder,
)
from ._encoder import EncoderParams, _Draw, encode_samples_raw, encoder_size, init_encoder


class Params(NamedTuple):
    """All FL-VAE parameters (a plain pytree).

    Attributes:
      encoder: ``EncoderParams`` (real MLPs, VN-Transformer blocks, complex heads).
      decoder: tuple of real dense layers ``(W, b)`` of the neural-field MLP.
    """

    encoder: EncoderParams
    decoder: tuple


@functools.partial(jax.tree_util.register_dataclass, data_fields=["params"], meta_fields=["config"])
@dataclasses.dataclass(frozen=True, eq=False)
class Model:
    """An FL-VAE: its parameters and the :class:`~jmeshtex.fl.Config` they belong to (a pytree).

    What :func:`~jmeshtex.fl.init`, :func:`~jmeshtex.fl.train` (``.model``),
    :func:`~jmeshtex.fl.load` and :func:`~jmeshtex.fl.load_pretrained` return, and what
    :func:`~jmeshtex.fl.save` and the mesh-level functions (:func:`~jmeshtex.fl.encode`,
    :func:`~jmeshtex.fl.decode_texture`, :func:`~jmeshtex.fl.reconstruct`, ...) take. The config is
    static pytree metadata: only the parameters are leaves, so a ``Model`` passes through
    ``jax.jit`` and ``jax.tree`` maps as it is.

    Attributes:
      params: :class:`~jmeshtex.fl.core.Params`.
      config: :class:`~jmeshtex.fl.Config`.

    Example:
      >>> import jax
      >>> m = init(Config(latent_dim=4), key=jax.random.key(0))
      >>> m.config.latent_dim, m.params.encoder.mean.shape, m.dtype
      (4, (32, 4), dtype('float32'))
    """

    params: Params
    config: Config

    def __post_init__(self) -> None:
        if not isinstance(self.config, Config):
            raise ConfigError(
                f"Model.config must be a jmeshtex.fl.Config, got {type(self.config).__name__}"
            )

    @property
    def dtype(self) -> jnp.dtype:
        """Real dtype of the parameters (complex ones use the matching complex dtype)."""
        return jnp.finfo(self.params.encoder.mean.dtype).dtype

    def __repr__(self) -> str:
        leaves = jax.tree.leaves(self.params)
        size = sum(int(x.size) * (2 if jnp.iscomplexobj(x) else 1) for x in leaves)
        return f"Model({size} real parameters, {self.dtype.name}, config={self.config!r})"


def init(config: Config, *, key: PRNGKey, dtype=jnp.float32) -> Model:
    """A randomly initialised FL-VAE for ``config``.

    Args:
      config: :class:`~jmeshtex.fl.Config`.
      key: PRNG key.
      dtype: real dtype of the parameters (complex ones use the matching complex dtype).

    Returns:
      :class:`Model`.

    Example:
      >>> import jax
      >>> m = init(Config(latent_dim=4), key=jax.random.key(0))
      >>> m.params.encoder.mean.shape, m.params.encoder.mean.dtype
      ((32, 4), dtype('complex64'))
    """
    if not isinstance(config, Config):
        raise ConfigError(f"config must be a jmeshtex.fl.Config, got {type(config).__name__}")
    return Model(_init_jit(key, config, jnp.dtype(dtype)), config)


@jit_once(static_argnums=(1, 2))
def _init_jit(key, config, dtype):
    # one compiled program (op-by-op, every random draw of a new shape compiles its own kernel), at
    # XLA's fastest compile: it runs once
    draw = _Draw(key, encoder_size(config) + decoder_size(config), dtype)
    return Params(init_encoder(draw, config, dtype=dtype), init_decoder(draw, config, dtype=dtype))


@functools.partial(
    jax.tree_util.register_dataclass, data_fields=["mu", "log_sigma"], meta_fields=[]
)
@dataclasses.dataclass(frozen=True)
class FieldLatents:
    """Tangent-vector latents at the vertices of a mesh (a pytree).

    Attributes:
      mu: ``[V, d]`` complex means, tangent vectors in the per-vertex frames of
        :func:`jmeshtex.geometry.one_ring_neighborhood` (x-axis = the edge to the first one-ring
        neighbour, slot 0). A gauge change turning p's frame by ``α_p`` maps ``μ_p → μ_p e^{-iα_p}``;
        field convolutions over these latents must use the same frames (``log``/``transport`` of that
        neighbourhood).
      log_sigma: ``[V, d]`` real ``log σ`` of the isotropic posterior ``N(μ, σ² I)`` per channel
        (σ² on the real and on the imaginary part): gauge-invariant.
    """

    mu: Complex[Array, "V d"]
    log_sigma: Float[Array, "V d"]


# ------------------------------------------------------------------------------------ pure parts


def _check_samples(log_q, rgb, mask):
    if jnp.ndim(log_q) != 2 or not jnp.issubdtype(jnp.result_type(log_q), jnp.complexfloating):
        raise InputError(
            f"log_q must be a complex [V, S] array, got {jnp.result_type(log_q)} {jnp.shape(log_q)}"
        )
    if jnp.shape(rgb) != (*jnp.shape(log_q), 3):
        raise InputError(
            f"rgb must have shape [V, S, 3] = {(*jnp.shape(log_q), 3)}, got {jnp.shape(rgb)}"
        )
    if jnp.shape(mask) != jnp.shape(log_q):
        raise InputError(f"mask must have shape [V, S] = {jnp.shape(log_q)}, got {jnp.shape(mask)}")


def encode_samples(
    params: Params,
    config: Config,
    log_q: Complex[Array, "V S"],
    rgb: Float[Array, "V S 3"],
    mask: Bool[Array, "V S"],
) -> FieldLatents:
    """Encode one-ring samples into latents (paper eq. 21–25; pure, jit/grad-safe).

    .. math:: x_i = f(c_i)\\,\\log_p(q_i), \\quad t = \\tfrac1n \\textstyle\\sum_i g(c_i, |\\log_p q_i|,
       \\bar c)\\, \\log_p(q_i), \\quad u = \\mathrm{VNT}(\\{x_i\\} \\cup \\{t\\})_t, \\quad
       \\mu = u W_\\mu, \\quad \\log\\sigma = \\tanh(\\mathrm{Re}(u \\overline{u W_s})) A + b

    Args:
      params: :class:`Params`.
      config: :class:`~jmeshtex.fl.Config` (static).
      log_q: ``[V, S]`` complex ``log_p(q_i) / r_p`` in p's frame (:func:`one_ring_samples`).
      rgb: ``[V, S, 3]`` colours in [0, 1] at the samples.
      mask: ``[V, S]`` True for real samples (others never change the output).

    Returns:
      :class:`~jmeshtex.fl.FieldLatents`: μ in p's frame (rotates with ``log_q``), ``log σ`` invariant.

    Example:
      >>> import jax, jax.numpy as jnp
      >>> c = Config(latent_dim=2, features=8, num_heads=2, num_blocks=1)
      >>> p = init(c, key=jax.random.key(0)).params
      >>> import numpy as np
      >>> log = jnp.asarray(np.exp(1j * np.linspace(0, 6, 5))[None], jnp.complex64)
      >>> rgb, mask = jnp.full((1, 5, 3), 0.3, jnp.float32), jnp.ones((1, 5), bool)
      >>> turn = complex(np.exp(-0.7j))
      >>> z, turned = encode_samples(p, c, log, rgb, mask), encode_samples(p, c, log * turn, rgb, mask)
      >>> bool(jnp.allclose(turned.mu, z.mu * turn, atol=1e-5))
      True
    """
    _check_samples(log_q, rgb, mask)
    mu, log_sigma = encode_samples_raw(params.encoder, config, log_q, rgb, mask)
    return FieldLatents(mu=mu, log_sigma=log_sigma)


def decode_points(
    params: Params, config: Config, mu: Complex[Array, "V d"], log_q: Complex[Array, "V S"]
) -> Float[Array, "V S 3"]:
    """Decode colours at points around each vertex from its latent alone (log decoder, eq. 5, 18).

    .. math:: \\mathrm{rgb}(q) = 0.5 + \\mathrm{MLP}\\big(|z_c|^2, z_i\\bar z_j, \\log_p(q)\\bar z_c\\big)

    Args:
      params: :class:`Params`.
      config: :class:`~jmeshtex.fl.Config`; with ``decoder="barycentric"`` the log coordinates
        are ignored (the ablation has none).
      mu: ``[V, d]`` complex latents in each vertex's frame.
      log_q: ``[V, S]`` complex normalised log coordinates in the same frames.

    Returns:
      ``[V, S, 3]`` colours (≈ [0, 1]; not clipped); invariant to gauge changes.

    Example:
      >>> import jax, jax.numpy as jnp
      >>> c = Config(latent_dim=2)
      >>> p = init(c, key=jax.random.key(0)).params
      >>> mu, log = jnp.array([[1 + 1j, 2j]], jnp.complex64), jnp.array([[0.5 + 0.1j]], jnp.complex64)
      >>> turn = jnp.exp(0.3j).astype(jnp.complex64)
      >>> bool(jnp.allclose(decode_points(p, c, mu * turn, log * turn), decode_points(p, c, mu, log), atol=1e-5))
      True
    """
    if jnp.ndim(mu) != 2 or jnp.ndim(log_q) != 2 or jnp.shape(mu)[0] != jnp.shape(log_q)[0]:
        raise InputError(
            f"mu must be [V, d] and log_q [V, S] with the same V, got {jnp.shape(mu)}, {jnp.shape(log_q)}"
        )
    mu = jnp.asarray(mu).astype(params.encoder.mean.dtype)
    if config.decoder == "barycentric":
        feats = decoder_features(config, mu, None)[:, None, :]
        return jnp.broadcast_to(apply_decoder(params.decoder, feats), (*jnp.shape(log_q), 3))
    return decode_points_raw(params.decoder, config, mu, log_q)


def decode_barycentric(
    params: Params,
    config: Config,
    mu: Complex[Array, "V d"],
    corners: Int[Array, "N 3"],
    bary: Float[Array, "N 3"],
    logs: Complex[Array, "N 3"] | None = None,
) -> Float[Array, "N 3"]:
    """Decode colours at points inside triangles from the latents of the three corners.

    ``decoder="log"``: ``Σ_k b_k D(z_{v_k}, log_{v_k}(x))`` (the paper's blending; needs ``logs``).
    ``decoder="barycentric"`` (ablation): ``D(Σ_k b_k φ(z_{v_k}))`` on interpolated invariants.

    Args:
      params: :class:`Params`.
      config: :class:`~jmeshtex.fl.Config`.
      mu: ``[V, d]`` complex latents.
      corners: ``[N, 3]`` vertex of each corner of the point's triangle.
      bary: ``[N, 3]`` barycentric coordinates of the points.
      logs: ``[N, 3]`` complex ``log_{v_k}(x) / r_{v_k}`` in each corner's frame (log mode).

    Returns:
      ``[N, 3]`` colours.

    Example:
      >>> import jax, jax.numpy as jnp
      >>> c = Config(latent_dim=2, decoder="barycentric")
      >>> p = init(c, key=jax.random.key(0)).params
      >>> mu = jnp.array([[1 + 1j, 2j], [1.0, 0.5j], [0.2, 1j]], jnp.complex64)
      >>> x = decode_barycentric(p, c, mu, jnp.array([[0, 1, 2]]), jnp.array([[1.0, 0.0, 0.0]]))
      >>> bool(jnp.allclose(x, decode_vertex_colors_from_latents(p, c, mu)[:1], atol=1e-6))
      True
    """
    mu = jnp.asarray(mu).astype(params.encoder.mean.dtype)
    if config.decoder == "barycentric":
        return decode_barycentric_raw(params.decoder, config, mu, corners, bary)
    if logs is None:
        raise InputError(
            "decode_barycentric with decoder='log' needs logs [N, 3] (each corner's log map of x)"
        )
    return blend_log_predictions(params.decoder, config, mu, corners, logs, bary)


def decode_vertex_colors_from_latents(
    params: Params, config: Config, mu: Complex[Array, "V d"]
) -> Float[Array, "V 3"]:
    """Colour at each vertex itself, ``D(z_p, log = 0)``, from its latent alone (pure; not clipped).

    Both decoders agree there: the log decoder at log coordinate 0, the barycentric ablation at a
    corner (weight 1 on the vertex).

    Args:
      params: :class:`Params`.
      config: :class:`~jmeshtex.fl.Config` (static).
      mu: ``[V, d]`` complex latents.

    Returns:
      ``[V, 3]`` colours (≈ [0, 1]); invariant to gauge changes.

    Example:
      >>> import jax, jax.numpy as jnp
      >>> c = Config(latent_dim=2)
      >>> p = init(c, key=jax.random.key(0)).params
      >>> mu = jnp.array([[1 + 1j, 2j]], jnp.complex64)
      >>> turn = jnp.exp(0.3j).astype(jnp.complex64)
      >>> bool(jnp.allclose(decode_vertex_colors_from_latents(p, c, mu * turn),
      ...                   decode_vertex_colors_from_latents(p, c, mu), atol=1e-5))
      True
    """
    mu = jnp.asarray(mu).astype(params.encoder.mean.dtype)
    log0 = None if config.decoder == "barycentric" else jnp.zeros(mu.shape[:1], mu.dtype)
    return apply_decoder(params.decoder, decoder_features(config, mu, log0))

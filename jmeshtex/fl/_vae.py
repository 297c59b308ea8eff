"""The FL-VAE: parameters, latents, loss, mesh-level encoding/decoding, saving and the shipped model.

Pure functions (jit/grad-safe): :func:`encode_samples`, :func:`decode_points`,
:func:`decode_barycentric`, :func:`kl_divergence`, :func:`vae_loss`. Host-level functions take a
:class:`~jmeshtex.Mesh`: :func:`encode_mesh` (one-ring sampling on the host, then a jitted encoder
over fixed-size vertex chunks), :func:`decode_vertex_colors`, :func:`decode_texture` (every used
texel of the UV atlas). Meshes with UV seams are handled on the merged geometry (``Mesh.faces``; the
per-corner ``Mesh.uv`` carries the seams), so latents live on merged vertices.
"""

from __future__ import annotations

import dataclasses
import functools
import io
import json
import os
import pathlib
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ConfigError, InputError, MeshIOError
from .._mesh import Mesh
from .._types import Array, Bool, Complex, Float, Int, PRNGKey
from ..geometry import rasterize_uv
from ..io import atomic_write
from ._colors import SurfaceColors, surface_colors
from ._config import FLVAEConfig
from ._decoder import (
    apply_decoder,
    blend_log_predictions,
    decode_barycentric_raw,
    decode_points_raw,
    decoder_features,
    decoder_size,
    init_decoder,
)
from ._encoder import (
    EncoderParams,
    _Draw,
    corner_logs,
    encode_samples_raw,
    encoder_size,
    init_encoder,
    one_ring_samples,
    ring_geometry,
)

WEIGHTS_DIR = pathlib.Path(__file__).parent / "weights"
PRETRAINED_FILE = WEIGHTS_DIR / "fl_vae.npz"


class FLVAEParams(NamedTuple):
    """All FL-VAE parameters (a plain pytree).

    Attributes:
      encoder: :class:`EncoderParams` (real MLPs, VN-Transformer blocks, complex heads).
      decoder: tuple of real dense layers ``(W, b)`` of the neural-field MLP.
    """

    encoder: EncoderParams
    decoder: tuple


@functools.partial(jax.tree_util.register_dataclass, data_fields=["mu", "log_sigma"], meta_fields=[])
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


def init_fl_vae(key: PRNGKey, config: FLVAEConfig, *, dtype=jnp.float32) -> FLVAEParams:
    """Random FL-VAE parameters for ``config``.

    Args:
      key: PRNG key.
      config: :class:`~jmeshtex.fl.FLVAEConfig`.
      dtype: real dtype of the parameters (complex ones use the matching complex dtype).

    Example:
      >>> import jax
      >>> p = init_fl_vae(jax.random.key(0), FLVAEConfig(latent_dim=4))
      >>> p.encoder.mean.shape, p.encoder.mean.dtype
      ((32, 4), dtype('complex64'))
    """
    if not isinstance(config, FLVAEConfig):
        raise ConfigError(f"config must be an FLVAEConfig, got {type(config).__name__}")
    return _init_jit(key, config, jnp.dtype(dtype))


@functools.partial(jax.jit, static_argnums=(1, 2))
def _init_jit(key, config, dtype):
    # one compiled program: op-by-op, every random draw of a new shape compiles its own kernel
    draw = _Draw(key, encoder_size(config) + decoder_size(config), dtype)
    return FLVAEParams(init_encoder(draw, config, dtype=dtype), init_decoder(draw, config, dtype=dtype))


# ------------------------------------------------------------------------------------ pure parts


def _check_samples(log_q, rgb, mask):
    if jnp.ndim(log_q) != 2 or not jnp.issubdtype(jnp.result_type(log_q), jnp.complexfloating):
        raise InputError(f"log_q must be a complex [V, S] array, got {jnp.result_type(log_q)} {jnp.shape(log_q)}")
    if jnp.shape(rgb) != (*jnp.shape(log_q), 3):
        raise InputError(f"rgb must have shape [V, S, 3] = {(*jnp.shape(log_q), 3)}, got {jnp.shape(rgb)}")
    if jnp.shape(mask) != jnp.shape(log_q):
        raise InputError(f"mask must have shape [V, S] = {jnp.shape(log_q)}, got {jnp.shape(mask)}")


def encode_samples(
    params: FLVAEParams,
    config: FLVAEConfig,
    log_q: Complex[Array, "V S"],
    rgb: Float[Array, "V S 3"],
    mask: Bool[Array, "V S"],
) -> FieldLatents:
    """Encode one-ring samples into latents (paper eq. 21–25; pure, jit/grad-safe).

    .. math:: x_i = f(c_i)\\,\\log_p(q_i), \\quad t = \\tfrac1n \\textstyle\\sum_i g(c_i, |\\log_p q_i|,
       \\bar c)\\, \\log_p(q_i), \\quad u = \\mathrm{VNT}(\\{x_i\\} \\cup \\{t\\})_t, \\quad
       \\mu = u W_\\mu, \\quad \\log\\sigma = \\tanh(\\mathrm{Re}(u \\overline{u W_s})) A + b

    Args:
      params: :class:`FLVAEParams`.
      config: :class:`~jmeshtex.fl.FLVAEConfig` (static).
      log_q: ``[V, S]`` complex ``log_p(q_i) / r_p`` in p's frame (:func:`one_ring_samples`).
      rgb: ``[V, S, 3]`` colours in [0, 1] at the samples.
      mask: ``[V, S]`` True for real samples (others never change the output).

    Returns:
      :class:`FieldLatents`: μ in p's frame (rotates with ``log_q``), ``log σ`` invariant.

    Example:
      >>> import jax, jax.numpy as jnp
      >>> c = FLVAEConfig(latent_dim=2, features=8, num_heads=2, num_blocks=1)
      >>> p = init_fl_vae(jax.random.key(0), c)
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
    params: FLVAEParams, config: FLVAEConfig, mu: Complex[Array, "V d"], log_q: Complex[Array, "V S"]
) -> Float[Array, "V S 3"]:
    """Decode colours at points around each vertex from its latent alone (log decoder, eq. 5, 18).

    .. math:: \\mathrm{rgb}(q) = 0.5 + \\mathrm{MLP}\\big(|z_c|^2, z_i\\bar z_j, \\log_p(q)\\bar z_c\\big)

    Args:
      params: :class:`FLVAEParams`.
      config: :class:`~jmeshtex.fl.FLVAEConfig`; with ``decoder="barycentric"`` the log coordinates
        are ignored (the ablation has none).
      mu: ``[V, d]`` complex latents in each vertex's frame.
      log_q: ``[V, S]`` complex normalised log coordinates in the same frames.

    Returns:
      ``[V, S, 3]`` colours (≈ [0, 1]; not clipped); invariant to gauge changes.

    Example:
      >>> import jax, jax.numpy as jnp
      >>> c = FLVAEConfig(latent_dim=2)
      >>> p = init_fl_vae(jax.random.key(0), c)
      >>> mu, log = jnp.array([[1 + 1j, 2j]], jnp.complex64), jnp.array([[0.5 + 0.1j]], jnp.complex64)
      >>> turn = jnp.exp(0.3j).astype(jnp.complex64)
      >>> bool(jnp.allclose(decode_points(p, c, mu * turn, log * turn), decode_points(p, c, mu, log), atol=1e-5))
      True
    """
    if jnp.ndim(mu) != 2 or jnp.ndim(log_q) != 2 or jnp.shape(mu)[0] != jnp.shape(log_q)[0]:
        raise InputError(f"mu must be [V, d] and log_q [V, S] with the same V, got {jnp.shape(mu)}, {jnp.shape(log_q)}")
    mu = jnp.asarray(mu).astype(params.encoder.mean.dtype)
    if config.decoder == "barycentric":
        feats = decoder_features(config, mu, None)[:, None, :]
        return jnp.broadcast_to(apply_decoder(params.decoder, feats), (*jnp.shape(log_q), 3))
    return decode_points_raw(params.decoder, config, mu, log_q)


def decode_barycentric(
    params: FLVAEParams, config: FLVAEConfig, mu: Complex[Array, "V d"], corners: Int[Array, "N 3"],
    bary: Float[Array, "N 3"], logs: Complex[Array, "N 3"] | None = None,
) -> Float[Array, "N 3"]:
    """Decode colours at points inside triangles from the latents of the three corners.

    ``decoder="log"``: ``Σ_k b_k D(z_{v_k}, log_{v_k}(x))`` (the paper's blending; needs ``logs``).
    ``decoder="barycentric"`` (ablation): ``D(Σ_k b_k φ(z_{v_k}))`` on interpolated invariants.

    Args:
      params: :class:`FLVAEParams`.
      config: :class:`~jmeshtex.fl.FLVAEConfig`.
      mu: ``[V, d]`` complex latents.
      corners: ``[N, 3]`` vertex of each corner of the point's triangle.
      bary: ``[N, 3]`` barycentric coordinates of the points.
      logs: ``[N, 3]`` complex ``log_{v_k}(x) / r_{v_k}`` in each corner's frame (log mode).

    Returns:
      ``[N, 3]`` colours.

    Example:
      >>> import jax, jax.numpy as jnp
      >>> c = FLVAEConfig(latent_dim=2, decoder="barycentric")
      >>> p = init_fl_vae(jax.random.key(0), c)
      >>> mu = jnp.array([[1 + 1j, 2j], [1.0, 0.5j], [0.2, 1j]], jnp.complex64)
      >>> x = decode_barycentric(p, c, mu, jnp.array([[0, 1, 2]]), jnp.array([[1.0, 0.0, 0.0]]))
      >>> bool(jnp.allclose(x, decode_vertex_colors_from_latents(p, c, mu)[:1], atol=1e-6))
      True
    """
    mu = jnp.asarray(mu).astype(params.encoder.mean.dtype)
    if config.decoder == "barycentric":
        return decode_barycentric_raw(params.decoder, config, mu, corners, bary)
    if logs is None:
        raise InputError("decode_barycentric with decoder='log' needs logs [N, 3] (each corner's log map of x)")
    return blend_log_predictions(params.decoder, config, mu, corners, logs, bary)


def decode_vertex_colors_from_latents(params: FLVAEParams, config: FLVAEConfig, mu: Complex[Array, "V d"]) -> Float[Array, "V 3"]:
    """Colour at each vertex itself: ``D(z_p, log = 0)`` (both decoders agree there)."""
    mu = jnp.asarray(mu).astype(params.encoder.mean.dtype)
    log0 = None if config.decoder == "barycentric" else jnp.zeros(mu.shape[:1], mu.dtype)
    return apply_decoder(params.decoder, decoder_features(config, mu, log0))


def kl_divergence(latents: FieldLatents) -> Float[Array, " V"]:
    """KL of the tangent-space posterior ``N(μ, σ² I₂)`` per channel to ``N(0, I₂)``, mean over channels.

    .. math:: \\mathrm{KL}_p = \\frac1d \\sum_c \\big(\\sigma_c^2 + \\tfrac12 |\\mu_c|^2 - 1 - 2 \\log\\sigma_c\\big)

    (paper eq. 26–28: a Gaussian in each tangent plane, isotropic so that it is gauge-invariant).

    Example:
      >>> import jax.numpy as jnp
      >>> kl_divergence(FieldLatents(jnp.zeros((2, 3), jnp.complex64), jnp.zeros((2, 3), jnp.float32))).tolist()
      [0.0, 0.0]
    """
    mu, ls = latents.mu, latents.log_sigma
    abs2 = mu.real * mu.real + mu.imag * mu.imag
    return jnp.mean(jnp.exp(2 * ls) + 0.5 * abs2 - 1 - 2 * ls, axis=-1)


def sample_latents(latents: FieldLatents, key: PRNGKey) -> Complex[Array, "V d"]:
    """Reparameterised draw ``z = μ + σ (ε_r + i ε_i)``, ``ε ~ N(0, 1)`` (rotation-invariant noise)."""
    rdt = latents.log_sigma.dtype
    eps = jax.random.normal(key, (2, *latents.mu.shape), rdt)
    sigma = jnp.exp(latents.log_sigma)
    return latents.mu + jax.lax.complex(sigma * eps[0], sigma * eps[1]).astype(latents.mu.dtype)


def vae_loss(
    params: FLVAEParams,
    config: FLVAEConfig,
    log_q: Complex[Array, "V S"],
    rgb: Float[Array, "V S 3"],
    mask: Bool[Array, "V S"],
    *,
    key: PRNGKey,
    corners: Int[Array, "V S 3"] | None = None,
    bary: Float[Array, "V S 3"] | None = None,
    vertex_mask: Bool[Array, " V"] | None = None,
) -> tuple[Float[Array, ""], dict]:
    """FL-VAE loss: L1 reconstruction of the one-ring samples + ``λ`` KL (paper eq. 26–28).

    .. math:: \\mathcal L = \\frac{\\sum_{p,i} m_{pi} \\lVert D(z_p, \\log_p q_i) - c_i\\rVert_1}{3\\sum m}
       + \\lambda\\, \\overline{\\mathrm{KL}_p}, \\qquad z_p = \\mu_p + \\sigma_p \\epsilon

    Log decoder: each vertex reconstructs its own one-ring from its own latent. Barycentric
    ablation: each sample is decoded from the interpolated invariants of its face's three corner
    latents (``corners``, ``bary`` required).

    Args:
      params: :class:`FLVAEParams`.
      config: :class:`~jmeshtex.fl.FLVAEConfig` (static).
      log_q, rgb, mask: one-ring samples of all ``V`` vertices (:func:`encode_samples`).
      key: PRNG key of the reparameterisation noise.
      corners: ``[V, S, 3]`` vertex ids of each sample's face (barycentric mode).
      bary: ``[V, S, 3]`` barycentric coordinates of each sample (barycentric mode).
      vertex_mask: ``[V]`` True for real vertices (padding excluded from the KL).

    Returns:
      ``(loss, {"l1": ..., "kl": ...})``.

    Example:
      >>> import jax, jax.numpy as jnp
      >>> c = FLVAEConfig(latent_dim=2, features=8, num_heads=2, num_blocks=1)
      >>> p = init_fl_vae(jax.random.key(0), c)
      >>> log = jnp.ones((1, 5), jnp.complex64)
      >>> loss, aux = vae_loss(p, c, log, jnp.full((1, 5, 3), 0.3), jnp.ones((1, 5), bool), key=jax.random.key(1))
      >>> bool(jnp.isfinite(loss)), sorted(aux)
      (True, ['kl', 'l1'])
    """
    _check_samples(log_q, rgb, mask)
    if config.decoder == "barycentric" and (corners is None or bary is None):
        raise InputError("vae_loss with decoder='barycentric' needs corners and bary [V, S, 3]")
    lat = encode_samples(params, config, log_q, rgb, mask)
    z = sample_latents(lat, key)
    rdt = lat.log_sigma.dtype
    if config.decoder == "barycentric":
        v, s = log_q.shape
        pred = decode_barycentric_raw(params.decoder, config, z, jnp.reshape(corners, (v * s, 3)),
                                      jnp.reshape(bary, (v * s, 3))).reshape(v, s, 3)
    else:
        pred = decode_points_raw(params.decoder, config, z, log_q)
    m = jnp.asarray(mask).astype(rdt)
    err = jnp.sum(jnp.abs(pred - jnp.asarray(rgb).astype(rdt)), axis=-1)
    l1 = jnp.sum(err * m) / (3 * jnp.maximum(jnp.sum(m), 1))
    vm = jnp.ones(log_q.shape[:1], rdt) if vertex_mask is None else jnp.asarray(vertex_mask).astype(rdt)
    kl = jnp.sum(kl_divergence(lat) * vm) / jnp.maximum(jnp.sum(vm), 1)
    loss = l1 + jnp.asarray(config.kl_weight, rdt) * kl
    return loss, {"l1": l1, "kl": kl}


# ---------------------------------------------------------------------------------- mesh level


def _numpy_rng(key: PRNGKey) -> np.random.Generator:
    data = jax.random.key_data(key) if jnp.issubdtype(jnp.asarray(key).dtype, jax.dtypes.prng_key) else key
    return np.random.default_rng(np.asarray(data, dtype=np.uint32).ravel().tolist())


@functools.partial(jax.jit, static_argnums=1)
def _encode_chunk(params, config, log_q, rgb, mask):
    return encode_samples_raw(params.encoder, config, log_q, rgb, mask)


def _check_mesh(mesh) -> Mesh:
    if not isinstance(mesh, Mesh):
        raise InputError(f"expected a jmeshtex.Mesh, got {type(mesh).__name__}")
    return mesh


def _param_complex(params: FLVAEParams):
    return params.encoder.mean.dtype


def encode_mesh(
    params: FLVAEParams,
    config: FLVAEConfig,
    mesh: Mesh,
    *,
    colors: SurfaceColors | None = None,
    key: PRNGKey,
) -> FieldLatents:
    """Encode a mesh's texture (or vertex colours) as tangent-vector latents at its vertices.

    Draws ``config.num_samples`` area-uniform points in every one-ring (host), reads their colours
    from ``colors`` (default :func:`~jmeshtex.fl.surface_colors` of the mesh) and runs the jitted
    encoder over chunks of ``config.encode_chunk`` vertices (the last chunk is padded, so a mesh of
    any size compiles once per chunk size).

    Args:
      params: :class:`FLVAEParams`.
      config: :class:`~jmeshtex.fl.FLVAEConfig`.
      mesh: a :class:`~jmeshtex.Mesh` (merged geometry; UV seams live in ``mesh.uv``).
      colors: where to read colours; pass ``surface_colors(original)`` to encode a re-triangulated
        copy of a textured mesh (:meth:`SurfaceColors.at_points`).
      key: PRNG key of the one-ring sampling.

    Returns:
      :class:`FieldLatents` ``[V, d]`` in the frames of ``one_ring_neighborhood(mesh)``.

    Raises:
      InputError: no colour source (neither texture + UVs nor vertex colours) or bad arguments.

    Example:
      >>> import jax, numpy as np
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> v, f = grid(4)
      >>> mesh = Mesh(v, f, vertex_colors=np.tile(v[:, :1], (1, 3)))
      >>> c = FLVAEConfig(features=8, num_heads=2, num_blocks=1, num_samples=8, encode_chunk=16)
      >>> lat = encode_mesh(init_fl_vae(jax.random.key(0), c), c, mesh, key=jax.random.key(1))
      >>> lat.mu.shape, lat.log_sigma.shape
      ((25, 8), (25, 8))
    """
    mesh = _check_mesh(mesh)
    if colors is None:
        colors = surface_colors(mesh)
    elif not isinstance(colors, SurfaceColors):
        raise InputError(f"colors must be a SurfaceColors (see jmeshtex.fl.surface_colors), got {type(colors).__name__}")
    samples = one_ring_samples(mesh.vertices, mesh.faces, config.num_samples, rng=_numpy_rng(key))
    if colors.vertices is mesh.vertices or (
        colors.faces.shape == mesh.faces.shape and np.array_equal(colors.faces, mesh.faces)
        and np.array_equal(colors.vertices, mesh.vertices)
    ):
        rgb = colors.at_barycentric(samples.face, samples.bary)
    else:  # another triangulation: look colours up at the sample positions
        points = np.einsum("vsk,vskd->vsd", samples.bary, np.asarray(mesh.vertices, np.float64)[mesh.faces[samples.face]])
        rgb = colors.at_points(points.reshape(-1, 3)).reshape(*samples.face.shape, 3)
    return _encode_arrays(params, config, samples.log, rgb, samples.mask)


def _encode_arrays(params, config, log, rgb, mask) -> FieldLatents:
    cdt = _param_complex(params)
    rdt = jnp.finfo(cdt).dtype
    V = log.shape[0]
    n = min(config.encode_chunk, V)
    mus, sigmas = [], []
    for start in range(0, V, n):
        stop = min(start + n, V)
        pad = n - (stop - start)
        def chunk(a, fill=0, start=start, stop=stop, pad=pad):
            a = a[start:stop]
            return np.concatenate([a, np.full((pad, *a.shape[1:]), fill, a.dtype)]) if pad else a

        mu, ls = _encode_chunk(params, config.model(), jnp.asarray(chunk(log), cdt), jnp.asarray(chunk(rgb), rdt),
                               jnp.asarray(chunk(mask, False)))
        mus.append(mu[: stop - start])
        sigmas.append(ls[: stop - start])
    return FieldLatents(mu=jnp.concatenate(mus), log_sigma=jnp.concatenate(sigmas))


def decode_vertex_colors(params: FLVAEParams, config: FLVAEConfig, mesh: Mesh, mu: Complex[Array, "V d"]) -> Float[Array, "V 3"]:
    """Decoded colour at every vertex, ``D(z_p, log_p(p) = 0)``, clipped to [0, 1].

    Args:
      params, config: the model.
      mesh: the mesh the latents belong to (its vertex count is checked).
      mu: ``[V, d]`` complex latents.

    Returns:
      ``[V, 3]`` colours in [0, 1] (gauge-invariant).

    Example:
      >>> import jax, jax.numpy as jnp, numpy as np
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import single_triangle
      >>> c = FLVAEConfig()
      >>> p = init_fl_vae(jax.random.key(0), c)
      >>> decode_vertex_colors(p, c, Mesh(*single_triangle()), jnp.zeros((3, 8), jnp.complex64)).shape
      (3, 3)
    """
    mesh = _check_mesh(mesh)
    if jnp.shape(mu) != (mesh.num_vertices, config.latent_dim):
        raise InputError(f"mu must have shape [V, d] = ({mesh.num_vertices}, {config.latent_dim}), got {jnp.shape(mu)}")
    return jnp.clip(decode_vertex_colors_from_latents(params, config, mu), 0.0, 1.0)


@functools.partial(jax.jit, static_argnums=1)
def _decode_texels_log(params, config, mu, corners, logs, bary):
    return blend_log_predictions(params.decoder, config, mu, corners, logs, bary)


@functools.partial(jax.jit, static_argnums=1)
def _decode_texels_bary(params, config, mu, corners, bary):
    return decode_barycentric_raw(params.decoder, config, mu, corners, bary)


def decode_points_in_faces(
    params: FLVAEParams, config: FLVAEConfig, mesh: Mesh, mu: Complex[Array, "V d"],
    face: Int[np.ndarray, " N"], bary: Float[np.ndarray, "N 3"], *, chunk: int = 65536,
) -> Float[np.ndarray, "N 3"]:
    """Decoded colours (unclipped, NumPy) at points ``(face, bary)`` of ``mesh`` from its latents.

    Log decoder: the three corner predictions at their own log coordinates blended barycentrically
    (eq. 18 + blending); barycentric ablation: interpolated invariants.
    """
    mesh = _check_mesh(mesh)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    mu = jnp.asarray(mu).astype(_param_complex(params))
    cdt, rdt = mu.dtype, jnp.finfo(mu.dtype).dtype
    geom = ring_geometry(mesh.vertices, faces) if config.decoder == "log" else None
    n = len(face)
    out = np.zeros((n, 3))
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        pad = chunk - (stop - start) if n > chunk else 0
        f = np.concatenate([face[start:stop], np.zeros(pad, np.int64)])
        b = np.concatenate([bary[start:stop], np.full((pad, 3), 1 / 3)])
        corners = jnp.asarray(faces[f], jnp.int32)
        if geom is not None:
            logs = np.stack([corner_logs(geom, f, np.full(len(f), k), b) for k in range(3)], axis=1)
            res = _decode_texels_log(params, config.model(), mu, corners, jnp.asarray(logs, cdt), jnp.asarray(b, rdt))
        else:
            res = _decode_texels_bary(params, config.model(), mu, corners, jnp.asarray(b, rdt))
        out[start:stop] = np.asarray(res)[: stop - start]
    return out


def decode_texture(
    params: FLVAEParams, config: FLVAEConfig, mesh: Mesh, mu: Complex[Array, "V d"], *, size: int
) -> tuple[Float[np.ndarray, "size size 3"], Bool[np.ndarray, "size size"]]:
    """Reconstruct the mesh's UV texture atlas from latents: every used texel (eq. 18 + blending).

    Each texel whose centre lies in a UV triangle gets ``Σ_k b_k D(z_{v_k}, log_{v_k}(x))`` (log
    decoder; ``log_{v_k}(x)`` is the intrinsic log map of the texel's surface point seen from corner
    vertex ``v_k``) or the barycentric ablation's prediction; colours are clipped to [0, 1].

    Args:
      params, config: the model.
      mesh: the mesh with ``uv`` ``[F, 3, 2]`` (merged geometry; seams in the per-corner UVs).
      mu: ``[V, d]`` complex latents on ``mesh``'s vertices.
      size: atlas side in texels.

    Returns:
      ``(texture [size, size, 3] float64 (0 where unused), valid [size, size] bool)``.

    Raises:
      InputError: no UVs, bad ``size`` or latent shape.

    Example:
      >>> import jax, jax.numpy as jnp, numpy as np
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> mesh = Mesh(v, f, uv=v[f][..., :2])
      >>> c = FLVAEConfig()
      >>> tex, valid = decode_texture(init_fl_vae(jax.random.key(0), c), c, mesh, jnp.zeros((9, 8), jnp.complex64), size=8)
      >>> tex.shape, int(valid.sum())
      ((8, 8, 3), 64)
    """
    mesh = _check_mesh(mesh)
    if mesh.uv is None:
        raise InputError("decode_texture needs a mesh with UV coordinates (mesh.uv [F, 3, 2]); use decode_vertex_colors otherwise")
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 1:
        raise InputError(f"size must be a positive int, got {size!r}")
    if jnp.shape(mu) != (mesh.num_vertices, config.latent_dim):
        raise InputError(f"mu must have shape [V, d] = ({mesh.num_vertices}, {config.latent_dim}), got {jnp.shape(mu)}")
    texels = rasterize_uv(mesh.uv, int(size))  # texel centres in UV triangles
    colors = decode_points_in_faces(params, config, mesh, mu, texels.face, texels.bary)
    tex = np.zeros((size, size, 3))
    valid = np.zeros((size, size), bool)
    tex[texels.row, texels.col] = np.clip(colors, 0.0, 1.0)  # a texel on a shared edge: last face wins
    valid[texels.row, texels.col] = True
    return tex, valid


# ------------------------------------------------------------------------------------- storage


def save_fl_vae(path: str | os.PathLike, params: FLVAEParams, config: FLVAEConfig, *, extra: dict | None = None) -> pathlib.Path:
    """Write parameters and config to one ``.npz`` file atomically (temporary file + rename).

    Args:
      path: target file (``.npz``); folders are created.
      params: :class:`FLVAEParams`.
      config: its :class:`~jmeshtex.fl.FLVAEConfig` (stored as JSON inside the file).
      extra: optional JSON-serialisable metadata (e.g. the training step) stored alongside.

    Example:
      >>> import jax, tempfile, pathlib
      >>> c = FLVAEConfig(features=8, num_heads=2)
      >>> p = init_fl_vae(jax.random.key(0), c)
      >>> path = save_fl_vae(pathlib.Path(tempfile.mkdtemp()) / "m.npz", p, c)
      >>> q, c2 = load_fl_vae(path)
      >>> c2 == c and all(bool((a == b).all()) for a, b in zip(jax.tree.leaves(p), jax.tree.leaves(q)))
      True
    """
    path = pathlib.Path(path)
    leaves = jax.tree.leaves(params)
    arrays = {f"leaf_{i:04d}": np.asarray(leaf) for i, leaf in enumerate(leaves)}
    meta = {"config": config.to_dict(), "num_leaves": len(leaves), "extra": extra or {}}
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write(path, buf.getvalue())
    return path


def load_fl_vae(path: str | os.PathLike, *, with_extra: bool = False):
    """Read a model written by :func:`save_fl_vae`: ``(params, config)`` (``+ extra`` if asked).

    Raises:
      MeshIOError: missing or unreadable file, or leaves that do not match the config.
    """
    path = pathlib.Path(path)
    if not path.is_file():
        raise MeshIOError(f"cannot read FL-VAE model {path}: no such file")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        meta = json.loads(arrays.pop("meta").tobytes().decode())
        config = FLVAEConfig.from_dict(meta["config"])
    except (OSError, ValueError, KeyError) as err:
        raise MeshIOError(f"cannot read FL-VAE model {path}: {err}") from err
    leaves = [arrays[f"leaf_{i:04d}"] for i in range(meta["num_leaves"])]
    real = jnp.float64 if leaves and leaves[0].dtype == np.float64 else jnp.float32
    shapes = jax.eval_shape(lambda k: init_fl_vae(k, config, dtype=real), jax.random.key(0))
    flat, treedef = jax.tree.flatten(shapes)
    if len(flat) != len(leaves) or any(a.shape != tuple(b.shape) for a, b in zip(flat, leaves, strict=True)):
        raise MeshIOError(f"FL-VAE model {path}: stored arrays do not match its config (corrupt or foreign file)")
    params = jax.tree.unflatten(treedef, [jnp.asarray(x) for x in leaves])
    return (params, config, meta.get("extra", {})) if with_extra else (params, config)


def load_pretrained(*, decoder: str = "log") -> tuple[FLVAEParams, FLVAEConfig]:
    """The small FL-VAE shipped in ``jmeshtex/fl/weights`` (see its README for how it was trained).

    Args:
      decoder: ``"log"`` (the FL-VAE, default) or ``"barycentric"`` (the paper's ablation, trained
        with the same data, steps and seed; used by ``benchmarks/fl_vae.py``).

    Raises:
      ConfigError: unknown ``decoder``.
      MeshIOError: the package was installed without the weights file.

    Example:
      >>> params, config = load_pretrained()
      >>> config.latent_dim, config.decoder
      (8, 'log')
    """
    files = {"log": PRETRAINED_FILE, "barycentric": WEIGHTS_DIR / "fl_vae_barycentric.npz"}
    if decoder not in files:
        raise ConfigError(f"decoder must be one of {sorted(files)}, got {decoder!r}")
    path = files[decoder]
    if not path.is_file():
        raise MeshIOError(
            f"no pre-trained FL-VAE shipped at {path}. Fix: train one with "
            "`jmeshtex fl pretrain --images builtin --out DIR` and load it with load_fl_vae(DIR/'fl_vae.npz')"
        )
    return load_fl_vae(path)

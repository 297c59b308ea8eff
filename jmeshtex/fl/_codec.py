"""Meshes in, latents out and back: FL-VAE encoding and decoding at the level of a whole mesh.

:func:`encode` samples every one-ring on the host and runs the jitted encoder over fixed-size
vertex chunks (:func:`encode_one_rings`); :func:`decode_vertex_colors`, :func:`decode_points_in_faces`
and :func:`decode_texture` (every used texel of the UV atlas) turn latents back into colours.
Meshes with UV seams are handled on the merged geometry (``Mesh.faces``; the per-corner
``Mesh.uv`` carries the seams), so latents live on merged vertices.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from .._config import is_int
from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._random import check_key
from .._types import Array, Bool, Complex, Float, Int, PRNGKey
from ..geometry import rasterize_uv
from ._colors import SurfaceColors, surface_colors
from ._decoder import blend_log_predictions, decode_barycentric_raw
from ._encoder import (
    OneRingSamples,
    _numpy_rng,
    corner_logs,
    encode_samples_raw,
    one_ring_samples,
    ring_geometry,
)
from ._model import FieldLatents, Model, decode_vertex_colors_from_latents


def _check_model(model) -> Model:
    if not isinstance(model, Model):
        raise InputError(
            f"expected a jmeshtex.fl.Model (from fl.init, fl.train(...).model, fl.load or "
            f"fl.load_pretrained), got {type(model).__name__}"
        )
    return model


def _latent_means(model: Model, mesh: Mesh, latents) -> jax.Array:
    """``latents`` (FieldLatents or a complex ``[V, d]`` array) as μ, checked against the mesh."""
    mu = latents.mu if isinstance(latents, FieldLatents) else latents
    if jnp.shape(mu) != (mesh.num_vertices, model.config.latent_dim):
        raise InputError(
            f"latents must have shape [V, d] = ({mesh.num_vertices}, {model.config.latent_dim}), "
            f"got {jnp.shape(mu)}"
        )
    return jnp.asarray(mu).astype(model.params.encoder.mean.dtype)


@functools.partial(jax.jit, static_argnums=1)
def _encode_chunk(params, config, log_q, rgb, mask):
    return encode_samples_raw(params.encoder, config, log_q, rgb, mask)


def encode(
    model: Model, mesh: Mesh | tuple, *, key: PRNGKey, colors: SurfaceColors | None = None
) -> FieldLatents:
    """Encode a mesh's texture (or vertex colours) as tangent-vector latents at its vertices.

    Draws ``config.num_samples`` area-uniform points in every one-ring (host, from ``key``), reads
    their colours from ``colors`` (default :func:`~jmeshtex.fl.core.surface_colors` of the mesh) and runs
    the jitted encoder (:func:`~jmeshtex.fl.core.encode_one_rings`).

    Args:
      model: the FL-VAE (:class:`~jmeshtex.fl.Model`).
      mesh: a :class:`~jmeshtex.Mesh` (merged geometry; UV seams live in ``mesh.uv``).
      key: PRNG key of the one-ring sampling.
      colors: where to read colours; pass ``surface_colors(original)`` to encode a re-triangulated
        copy of a textured mesh (:meth:`~jmeshtex.fl.core.SurfaceColors.at_points`).

    Returns:
      :class:`FieldLatents` ``[V, d]`` in the frames of ``one_ring_neighborhood(mesh)``.

    Raises:
      InputError: no colour source (neither texture + UVs nor vertex colours) or bad arguments.

    Example:
      >>> import jax, numpy as np
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.fl import Config, init
      >>> v, f = grid(4)
      >>> mesh = Mesh(v, f, vertex_colors=np.tile(v[:, :1], (1, 3)))
      >>> model = init(Config(features=8, num_heads=2, num_blocks=1, num_samples=8, encode_chunk=16),
      ...              key=jax.random.key(0))
      >>> lat = encode(model, mesh, key=jax.random.key(1))
      >>> lat.mu.shape, lat.log_sigma.shape
      ((25, 8), (25, 8))
    """
    model = _check_model(model)
    check_key(key, "encode: key")
    mesh = as_mesh(mesh, what="mesh")
    if colors is None:
        colors = surface_colors(mesh)
    elif not isinstance(colors, SurfaceColors):
        raise InputError(
            f"colors must be a SurfaceColors (see jmeshtex.fl.surface_colors), got {type(colors).__name__}"
        )
    samples = one_ring_samples(
        mesh.vertices,
        mesh.faces,
        model.config.num_samples,
        rng=_numpy_rng(key),
        center=model.config.experimental.token == "centre",
    )
    if colors.vertices is mesh.vertices or (
        colors.faces.shape == mesh.faces.shape
        and np.array_equal(colors.faces, mesh.faces)
        and np.array_equal(colors.vertices, mesh.vertices)
    ):
        rgb = colors.at_barycentric(samples.face, samples.bary)
    else:  # another triangulation: look colours up at the sample positions
        points = np.einsum(
            "vsk,vskd->vsd",
            samples.bary,
            np.asarray(mesh.vertices, np.float64)[mesh.faces[samples.face]],
        )
        rgb = colors.at_points(points.reshape(-1, 3)).reshape(*samples.face.shape, 3)
    return encode_one_rings(model, samples, rgb)


def encode_one_rings(
    model: Model, samples: OneRingSamples, rgb: Float[np.ndarray, "V S 3"]
) -> FieldLatents:
    """Encode precomputed one-ring samples of a whole mesh with the jitted encoder, chunk by chunk.

    The vertices go through the encoder in chunks of ``config.encode_chunk`` (the last one padded),
    so a mesh of any size compiles once per chunk size and memory stays bounded. :func:`~jmeshtex.fl.encode` is
    this after :func:`~jmeshtex.fl.core.one_ring_samples` and the colour lookup; call it directly to
    time the encoder apart from the host-side sampling, or to encode samples drawn another way.

    Args:
      model: the FL-VAE (:class:`~jmeshtex.fl.Model`).
      samples: :class:`~jmeshtex.fl.core.OneRingSamples` ``[V, S]`` (log coordinates and mask are used;
        drawn with ``center=True`` exactly when the model's ``token`` is ``"centre"``).
      rgb: ``[V, S, 3]`` colours in [0, 1] at the samples.

    Returns:
      :class:`~jmeshtex.fl.FieldLatents` ``[V, d]`` in the dtype of the model's parameters.

    Example:
      >>> import jax, numpy as np
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.fl import Config, init
      >>> from jmeshtex.fl.core import one_ring_samples
      >>> model = init(Config(features=8, num_heads=2, num_blocks=1, encode_chunk=10), key=jax.random.key(0))
      >>> s = one_ring_samples(*grid(3), 8, rng=np.random.default_rng(0), center=True)
      >>> lat = encode_one_rings(model, s, np.full((*s.log.shape, 3), 0.5))
      >>> lat.mu.shape  # 16 vertices in two chunks of 10
      (16, 8)
    """
    model = _check_model(model)
    if not isinstance(samples, OneRingSamples):
        raise InputError(
            f"samples must be OneRingSamples (see jmeshtex.fl.one_ring_samples), got {type(samples).__name__}"
        )
    if (model.config.experimental.token == "centre") != bool(samples.centered):
        raise InputError(
            f"the model's token is {model.config.experimental.token!r}, so its samples must "
            f"{'' if model.config.experimental.token == 'centre' else 'not '}have the ring's centre in column 0: "
            f"draw them with one_ring_samples(..., center={model.config.experimental.token == 'centre'})"
        )
    log, mask, rgb = np.asarray(samples.log), np.asarray(samples.mask), np.asarray(rgb)
    if rgb.shape != (*log.shape, 3):
        raise InputError(f"rgb must have shape [V, S, 3] = {(*log.shape, 3)}, got {rgb.shape}")
    cdt = model.params.encoder.mean.dtype
    rdt = jnp.finfo(cdt).dtype
    config = model.config.architecture()
    V = log.shape[0]
    n = min(model.config.encode_chunk, V)
    mus, sigmas = [], []
    for start in range(0, V, n):
        stop = min(start + n, V)
        pad = n - (stop - start)

        def chunk(a, fill=0, start=start, stop=stop, pad=pad):
            a = a[start:stop]
            return np.concatenate([a, np.full((pad, *a.shape[1:]), fill, a.dtype)]) if pad else a

        mu, ls = _encode_chunk(
            model.params,
            config,
            jnp.asarray(chunk(log), cdt),
            jnp.asarray(chunk(rgb), rdt),
            jnp.asarray(chunk(mask, False)),
        )
        mus.append(mu[: stop - start])
        sigmas.append(ls[: stop - start])
    return FieldLatents(mu=jnp.concatenate(mus), log_sigma=jnp.concatenate(sigmas))


def decode_vertex_colors(
    model: Model, mesh: Mesh | tuple, latents: FieldLatents | Complex[Array, "V d"]
) -> Float[Array, "V 3"]:
    """Decoded colour at every vertex, ``D(z_p, log_p(p) = 0)``, clipped to [0, 1].

    Args:
      model: the FL-VAE (:class:`~jmeshtex.fl.Model`).
      mesh: the mesh the latents belong to (its vertex count is checked).
      latents: :class:`FieldLatents` (its means are decoded) or ``[V, d]`` complex latents.

    Returns:
      ``[V, 3]`` colours in [0, 1] (gauge-invariant).

    Example:
      >>> import jax, jax.numpy as jnp
      >>> from jmeshtex.data import single_triangle
      >>> from jmeshtex.fl import Config, init
      >>> model = init(Config(), key=jax.random.key(0))
      >>> decode_vertex_colors(model, single_triangle(), jnp.zeros((3, 8), jnp.complex64)).shape
      (3, 3)
    """
    model = _check_model(model)
    mesh = as_mesh(mesh, what="mesh")
    mu = _latent_means(model, mesh, latents)
    return jnp.clip(decode_vertex_colors_from_latents(model.params, model.config, mu), 0.0, 1.0)


@functools.partial(jax.jit, static_argnums=1)
def _decode_texels_log(params, config, mu, corners, logs, bary):
    return blend_log_predictions(params.decoder, config, mu, corners, logs, bary)


@functools.partial(jax.jit, static_argnums=1)
def _decode_texels_bary(params, config, mu, corners, bary):
    return decode_barycentric_raw(params.decoder, config, mu, corners, bary)


def decode_points_in_faces(
    model: Model,
    mesh: Mesh | tuple,
    latents: FieldLatents | Complex[Array, "V d"],
    face: Int[np.ndarray, " N"],
    bary: Float[np.ndarray, "N 3"],
    *,
    chunk: int = 65536,
) -> Float[np.ndarray, "N 3"]:
    """Decoded colours (unclipped, NumPy) at points ``(face, bary)`` of ``mesh`` from its latents.

    Log decoder: the three corner predictions at their own log coordinates, blended
    barycentrically, ``Σ_k b_k D(z_{v_k}, log_{v_k}(x))`` (eq. 18 + blending); barycentric
    ablation: the decoder on interpolated invariants. Points go through one jitted call per
    ``chunk`` (the last one padded when there is more than one).

    Args:
      model: the FL-VAE (:class:`~jmeshtex.fl.Model`).
      mesh: the mesh the latents belong to.
      latents: :class:`FieldLatents` (its means are decoded) or ``[V, d]`` complex latents.
      face: ``[N]`` face of each point.
      bary: ``[N, 3]`` barycentric coordinates in that face (corner order of ``mesh.faces``).
      chunk: points per jitted call.

    Returns:
      ``[N, 3]`` float64 colours (≈ [0, 1], not clipped).

    Example:
      >>> import jax, jax.numpy as jnp, numpy as np
      >>> from jmeshtex.data import single_triangle
      >>> from jmeshtex.fl import Config, init
      >>> model = init(Config(latent_dim=2), key=jax.random.key(0))
      >>> mu = jnp.ones((3, 2), jnp.complex64)
      >>> at_corner = decode_points_in_faces(model, single_triangle(), mu, np.array([0]), np.array([[1.0, 0, 0]]))
      >>> bool(np.allclose(at_corner, decode_vertex_colors(model, single_triangle(), mu)[:1], atol=1e-6))
      True
    """
    model = _check_model(model)
    mesh = as_mesh(mesh, what="mesh")
    params, config = model.params, model.config.architecture()
    mu = _latent_means(model, mesh, latents)
    face = np.asarray(face, dtype=np.int64)
    bary = np.asarray(bary, dtype=np.float64)
    if face.ndim != 1 or bary.shape != (len(face), 3):
        raise InputError(f"face must be [N] and bary [N, 3], got {face.shape} and {bary.shape}")
    faces = np.asarray(mesh.faces, dtype=np.int64)
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
            res = _decode_texels_log(
                params, config, mu, corners, jnp.asarray(logs, cdt), jnp.asarray(b, rdt)
            )
        else:
            res = _decode_texels_bary(params, config, mu, corners, jnp.asarray(b, rdt))
        out[start:stop] = np.asarray(res)[: stop - start]
    return out


def decode_texture(
    model: Model, mesh: Mesh | tuple, latents: FieldLatents | Complex[Array, "V d"], *, size: int
) -> tuple[Float[np.ndarray, "size size 3"], Bool[np.ndarray, "size size"]]:
    """Reconstruct the mesh's UV texture atlas from latents: every used texel (eq. 18 + blending).

    Each texel whose centre lies in a UV triangle gets ``Σ_k b_k D(z_{v_k}, log_{v_k}(x))`` (log
    decoder; ``log_{v_k}(x)`` is the intrinsic log map of the texel's surface point seen from corner
    vertex ``v_k``) or the barycentric ablation's prediction; colours are clipped to [0, 1].

    Args:
      model: the FL-VAE (:class:`~jmeshtex.fl.Model`).
      mesh: the mesh with ``uv`` ``[F, 3, 2]`` (merged geometry; seams in the per-corner UVs).
      latents: :class:`FieldLatents` (its means are decoded) or ``[V, d]`` complex latents on
        ``mesh``'s vertices.
      size: atlas side in texels.

    Returns:
      ``(texture [size, size, 3] float64 (0 where unused), valid [size, size] bool)``.

    Raises:
      InputError: no UVs, bad ``size`` or latent shape.

    Example:
      >>> import jax, jax.numpy as jnp
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.fl import Config, init
      >>> v, f = grid(2)
      >>> mesh = Mesh(v, f, uv=v[f][..., :2])
      >>> model = init(Config(), key=jax.random.key(0))
      >>> tex, valid = decode_texture(model, mesh, jnp.zeros((9, 8), jnp.complex64), size=8)
      >>> tex.shape, int(valid.sum())
      ((8, 8, 3), 64)
    """
    model = _check_model(model)
    mesh = as_mesh(mesh, what="mesh")
    if mesh.uv is None:
        raise InputError(
            "decode_texture needs a mesh with UV coordinates (mesh.uv [F, 3, 2]); use decode_vertex_colors otherwise"
        )
    if not is_int(size, 1):
        raise InputError(f"size must be a positive int, got {size!r}")
    mu = _latent_means(model, mesh, latents)
    texels = rasterize_uv(mesh.uv, int(size))  # texel centres in UV triangles
    colors = decode_points_in_faces(model, mesh, mu, texels.face, texels.bary)
    tex = np.zeros((size, size, 3))
    valid = np.zeros((size, size), bool)
    tex[texels.row, texels.col] = np.clip(
        colors, 0.0, 1.0
    )  # a texel on a shared edge: last face wins
    valid[texels.row, texels.col] = True
    return tex, valid

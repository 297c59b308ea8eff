"""Transfer a learned DGTS texture to any mesh, and interpolate between noises (Hertz et al. 2020, §3.4, §4).

The target is scaled about its centroid so its mean edge is 1 (the frame the generators were trained
in), the generators ``start_level … L−1`` run on it with fresh Gaussian vertex noise, subdividing 1 → 4
and rescaling ×2 between levels, and the result is mapped back to the target's coordinates. No
re-meshing: the target's own triangles are subdivided, so open meshes, several components and any
genus work (boundary edges are handled by the face neighbourhood's substitute opposite vertex).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse

from .._errors import InputError
from .._types import Float, Int, PRNGKey
from ..geometry import mean_edge_length, validate_mesh
from ._model import generate, hierarchy_geometry, upsample
from ._train import DGTSModel


class TransferResult(NamedTuple):
    """Meshes produced by :func:`transfer` (all in the target's input coordinates).

    Attributes:
      vertices: ``[S, V_n, 3]`` one textured mesh per sample.
      faces: ``[F_n, 3]`` their triangles (the target subdivided ``n − 1`` times).
      base: ``[V_n, 3]`` the subdivided target without displacement (the reference for heights).
      heights: ``[S, V_n]`` displacement along the base's vertex normals, in mean edges of the
        output (for colouring).
      noise: per sample, the list of per-level noises used (replay or interpolate with them).
    """

    vertices: np.ndarray
    faces: np.ndarray
    base: np.ndarray
    heights: np.ndarray
    noise: list


def vertex_normals(vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"]) -> Float[np.ndarray, "V 3"]:
    """Area-weighted unit vertex normals (0 for isolated vertices).

    Example:
      >>> from jmeshtex.data import single_triangle
      >>> vertex_normals(*single_triangle()).tolist()[0]
      [0.0, 0.0, 1.0]
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    np.add.at(n, f.ravel(), np.repeat(fn, 3, axis=0))
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)


def normal_heights(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    *,
    smoothing: int = 10,
    lam: float = 0.5,
    mu: float = -0.53,
) -> Float[np.ndarray, " V"]:
    """Per-vertex height along the normal of a smoothed copy of the mesh, in mean edges.

    .. math:: h_i = \\frac{(v_i - \\bar v_i)\\cdot \\bar n_i}{\\bar\\ell},\\qquad
       \\bar v = \\big((I + \\mu \\Delta)(I + \\lambda \\Delta)\\big)^{k} v

    Taubin's shrink-free smoothing with the uniform graph Laplacian ``Δ = D^{-1}A − I``
    (``k = smoothing`` pairs of steps), ``n̄`` the smoothed mesh's vertex normals and ``ℓ̄`` the mean
    edge length. Bumps point
    outwards as positive heights; the distribution of ``h`` summarises a geometric texture.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(6)
      >>> float(np.abs(normal_heights(v, f)).max())  # a flat sheet has no texture
      0.0
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    V = len(v)
    pairs = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    pairs = np.unique(np.sort(pairs, axis=1), axis=0)
    a = scipy.sparse.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(V, V)).tocsr()
    a = a + a.T
    deg = np.asarray(a.sum(axis=1)).ravel()
    avg = scipy.sparse.diags(1.0 / np.maximum(deg, 1)) @ a
    smooth = v.copy()
    for _ in range(int(smoothing)):  # iterations over the whole mesh, not per vertex
        smooth = smooth + lam * (avg @ smooth - smooth)
        smooth = smooth + mu * (avg @ smooth - smooth)
    n = vertex_normals(smooth, f)
    ell = np.linalg.norm(v[pairs[:, 0]] - v[pairs[:, 1]], axis=1).mean()
    return np.einsum("vd,vd->v", v - smooth, n) / ell


def _prepare_target(model: DGTSModel, vertices, faces, start_level: int):
    v = np.asarray(vertices)
    f = np.asarray(faces)
    validate_mesh(v, f)
    L = model.num_levels
    if L == 0:
        raise InputError("the model has no trained level: train it first")
    if isinstance(start_level, bool) or not isinstance(start_level, (int, np.integer)) or not 0 <= start_level < L:
        raise InputError(f"start_level must be an int in [0, {L - 1}] (the model has {L} levels), got {start_level!r}")
    v = v.astype(np.float64)
    f = f.astype(np.int64)
    center = v.mean(axis=0)
    scale = 1.0 / mean_edge_length(v, f)
    n = L - int(start_level)
    geos, faces_all = hierarchy_geometry(f, len(v), n)
    sizes = [len(v)]
    for g in geos[:-1]:
        sizes.append(sizes[-1] + int(g.edge_vertices.shape[0]))
    return (v - center) * scale, f, center, scale, n, geos, faces_all, sizes


@jax.jit(static_argnums=(0, 1, 2))
def _generate_jit(scale, negative_slope, eps, v0, geos, params, zs):
    return generate(params, v0, geos, zs, scale=scale, negative_slope=negative_slope, eps=eps)


def _run_jit(model: DGTSModel, v0, geos, params, zs):
    c = model.config
    return _generate_jit(c.scale_factor, c.negative_slope, c.eps, v0, geos, params, zs)


def _noises(key: PRNGKey, sizes: Sequence[int], amplitude: float) -> list[jax.Array]:
    keys = jax.random.split(key, len(sizes))
    return [amplitude * jax.random.normal(k, (s, 3), jnp.float32) for k, s in zip(keys, sizes, strict=True)]


def _finish(model, out, v0, geos, faces_all, center, scale, n):
    c = model.config
    base = jnp.asarray(v0, jnp.float32)
    for g in geos[:-1]:
        base = upsample(base, g.edge_vertices, scale=c.scale_factor)
    factor = scale * c.scale_factor ** (n - 1)
    base = np.asarray(base, np.float64)
    nrm = vertex_normals(base, faces_all[-1])
    outs = [np.asarray(o, np.float64) for o in out]
    heights = np.stack([np.einsum("vd,vd->v", o - base, nrm) for o in outs])
    return [o / factor + center for o in outs], base / factor + center, heights


def _synthesise(model: DGTSModel, vertices, faces, start_level: int, noises) -> TransferResult:
    """Run the generators from ``start_level`` on the target once per noise list ``noises(sizes)``
    returns (one ``[V_l, 3]`` array per level run), and map the results back to the target's frame."""
    v0, _, center, scale, n, geos, faces_all, sizes = _prepare_target(model, vertices, faces, start_level)
    params = tuple(model.generators[start_level:])
    x = jnp.asarray(v0, jnp.float32)
    draws = noises(sizes)
    outs = [_run_jit(model, x, geos, params, zs) for zs in draws]
    verts, base, heights = _finish(model, outs, v0, geos, faces_all, center, scale, n)
    return TransferResult(np.stack(verts), faces_all[-1], base, heights, [[np.asarray(z) for z in zs] for zs in draws])


def transfer(
    model: DGTSModel,
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    *,
    start_level: int = 0,
    num_samples: int = 1,
    key: PRNGKey,
) -> TransferResult:
    """Synthesise the learned texture on a target mesh, ``num_samples`` times with different noise.

    .. math:: v_{l+1} = 2\\,U_l\\big(v_l + G_l(v_l, z_l)\\big),\\quad l = \\text{start\\_level} \\ldots L-1,
       \\quad v_{\\text{start}} = \\text{target} / \\bar\\ell

    Args:
      model: a trained :class:`DGTSModel`.
      vertices: ``[V, 3]`` target positions (any scale and placement).
      faces: ``[F, 3]`` target triangles (open or closed, any genus).
      start_level: first generator to run (0: coarsest); the target is treated as a level-``start``
        mesh, so ``L − start_level − 1`` subdivisions follow.
      num_samples: independent noise draws.
      key: PRNG key of the noise.

    Returns:
      :class:`TransferResult` in the target's coordinates.

    Raises:
      InputError: a bad ``start_level`` or an untrained model; MeshError subclasses: an invalid target.

    Example:
      >>> from jmeshtex.data import icosahedron, torus
      >>> from jmeshtex.dgts import TrainConfig, training_meshes, train, PrepareConfig
      >>> tm = training_meshes(icosahedron(), icosahedron(), config=PrepareConfig(num_levels=2, iterations=0))
      >>> cfg = TrainConfig(num_layers=3, start_features=4, min_features=4, max_features=4, iterations=2, seed=3,
      ...     shared_levels=2)
      >>> model, _ = train(tm, cfg, progress=False)
      >>> res = transfer(model, *torus(8, 6), num_samples=2, key=jax.random.key(0))
      >>> res.vertices.shape, res.faces.shape
      ((2, 192, 3), (384, 3))
    """
    if isinstance(num_samples, bool) or not isinstance(num_samples, (int, np.integer)) or num_samples < 1:
        raise InputError(f"num_samples must be a positive int, got {num_samples!r}")

    def noises(sizes):
        return [_noises(jax.random.fold_in(key, s), sizes, model.config.noise_amplitude) for s in range(int(num_samples))]

    return _synthesise(model, vertices, faces, start_level, noises)


def interpolate(
    model: DGTSModel,
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    *,
    start_level: int = 0,
    num_frames: int = 8,
    key: PRNGKey,
) -> TransferResult:
    """Frames of a latent interpolation between two noise draws (the reference code's animation).

    .. math:: z(t) = (1 - t)\\, z_a + t\\, z_b,\\qquad t = 0, \\tfrac{1}{N-1}, \\ldots, 1

    Args:
      model, vertices, faces, start_level: as :func:`transfer`.
      num_frames: frames including both ends (≥ 2).
      key: PRNG key of ``z_a`` and ``z_b``.

    Returns:
      :class:`TransferResult` with one "sample" per frame; ``noise[0]`` is ``z_a`` and
      ``noise[-1]`` is ``z_b``.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.dgts import TrainConfig, training_meshes, train, PrepareConfig
      >>> tm = training_meshes(icosahedron(), icosahedron(), config=PrepareConfig(num_levels=2, iterations=0))
      >>> cfg = TrainConfig(num_layers=3, start_features=4, min_features=4, max_features=4, iterations=2, seed=3,
      ...     shared_levels=2)
      >>> model, _ = train(tm, cfg, progress=False)
      >>> interpolate(model, *icosahedron(), start_level=1, num_frames=3, key=jax.random.key(0)).vertices.shape
      (3, 12, 3)
    """
    if isinstance(num_frames, bool) or not isinstance(num_frames, (int, np.integer)) or num_frames < 2:
        raise InputError(f"num_frames must be an int >= 2, got {num_frames!r}")

    def noises(sizes):
        ka, kb = jax.random.split(key)
        za = _noises(ka, sizes, model.config.noise_amplitude)
        zb = _noises(kb, sizes, model.config.noise_amplitude)
        weights = [np.float32(t) for t in np.linspace(0.0, 1.0, int(num_frames))]
        return [[(1 - w) * a + w * b for a, b in zip(za, zb, strict=True)] for w in weights]

    return _synthesise(model, vertices, faces, start_level, noises)

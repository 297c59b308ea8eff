"""Transfer a learned DGTS texture to any mesh, and interpolate between noises (Hertz et al. 2020, §3.4, §4).

The target is scaled about its centroid so its mean edge is 1 (the frame the generators were trained
in), the generators ``start_level … L−1`` run on it with fresh Gaussian vertex noise, subdividing 1 → 4
and rescaling ×2 between levels, and the result is mapped back to the target's coordinates. No
re-meshing: the target's own triangles are subdivided, so open meshes, several components and any
genus work (boundary edges are handled by the face neighbourhood's substitute opposite vertex).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._types import Array, Float, Int, PRNGKey
from ..geometry import mean_edge_length, unique_edges, validate_mesh, vertex_normals
from ._model import Model
from ._networks import LevelGeometry, generate, hierarchy_geometry, upsample


class DGTSTransfer(NamedTuple):
    """Meshes produced by :func:`transfer` and :func:`interpolate` (all in the target's coordinates).

    Attributes:
      vertices: ``[S, V_n, 3]`` float64, one textured mesh per sample (or frame).
      faces: ``[F_n, 3]`` int64, their triangles (the target subdivided ``n − 1`` times).
      base: ``[V_n, 3]`` float64, the subdivided target without displacement (the reference for heights).
      heights: ``[S, V_n]`` float64, displacement along the base's vertex normals, in mean edges of
        the output's level frame (for colouring).
      noise: per sample, the list of per-level noises used (``[V_l, 3]`` float32 arrays; replay or
        interpolate with them through :func:`run_plan`).
    """

    vertices: np.ndarray
    faces: np.ndarray
    base: np.ndarray
    heights: np.ndarray
    noise: list

    def mesh(self, sample: int = 0) -> Mesh:
        """Sample (or frame) ``sample`` as a :class:`~jmeshtex.Mesh`."""
        return Mesh(self.vertices[sample], self.faces)


class TransferPlan(NamedTuple):
    """A target prepared for the generators (:func:`plan_transfer`): frames and connectivity.

    Attributes:
      vertices: ``[V, 3]`` float32, the target in the model's frame (centred on its centroid, mean
        edge 1).
      geometry: one :class:`~jmeshtex.dgts.LevelGeometry` per level run.
      faces: ``[F_l, 3]`` int64 triangles per level run (the target's, then its subdivisions).
      sizes: vertices per level run (the shapes of the noise, ``[V_l, 3]``).
      center: ``[3]`` the target's centroid (input coordinates).
      factor: input-to-output scale: the output's frame is ``(x − center) · factor``.
      start_level: the first generator run.
    """

    vertices: Float[Array, "V 3"]
    geometry: tuple[LevelGeometry, ...]
    faces: tuple[np.ndarray, ...]
    sizes: tuple[int, ...]
    center: Float[np.ndarray, " 3"]
    factor: float
    start_level: int

    def to_target(self, vertices: Float[Array, "Vn 3"]) -> Float[np.ndarray, "Vn 3"]:
        """Output positions of :func:`run_plan` back in the target's coordinates (float64)."""
        return np.asarray(vertices, np.float64) / self.factor + self.center


def plan_transfer(model: Model, target: Mesh | tuple, *, start_level: int = 0) -> TransferPlan:
    """Prepare a target mesh for the generators ``start_level … L−1`` (host side, once per target).

    The target is scaled about its centroid so its mean edge is 1 (the frame the generators were
    trained in), and the connectivity of ``L − start_level`` levels of midpoint subdivision is built.

    Args:
      model: a trained :class:`~jmeshtex.dgts.Model`.
      target: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])`` (open or closed, any
        genus, any scale and placement).
      start_level: first generator to run (0: coarsest).

    Returns:
      :class:`TransferPlan`, the input of :func:`run_plan`.

    Raises:
      InputError: a bad ``start_level``, an untrained model, or a target that is not a mesh;
      MeshError: (a subclass) an invalid target.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.dgts import Config, init_level
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(2))
      >>> model = Model(c, gs, gs, np.zeros((12, 3), np.float32))
      >>> plan = plan_transfer(model, icosahedron())
      >>> plan.sizes, plan.faces[-1].shape
      ((12, 42), (80, 3))
    """
    v, f = as_mesh(target, what="target")
    validate_mesh(v, f)
    L = model.num_levels
    if L == 0:
        raise InputError("the model has no trained level: train it first")
    if isinstance(start_level, bool) or not isinstance(start_level, (int, np.integer)) or not 0 <= start_level < L:
        raise InputError(f"start_level must be an int in [0, {L - 1}] (the model has {L} levels), got {start_level!r}")
    v = np.asarray(v, np.float64)
    f = np.asarray(f, np.int64)
    center = v.mean(axis=0)
    scale = 1.0 / mean_edge_length(v, f)
    n = L - int(start_level)
    geos, faces_all = hierarchy_geometry(f, len(v), n)
    sizes = [len(v)]
    for g in geos[:-1]:
        sizes.append(sizes[-1] + int(g.edge_vertices.shape[0]))
    factor = scale * model.config.scale_factor ** (n - 1)
    return TransferPlan(jnp.asarray((v - center) * scale, jnp.float32), geos, faces_all, tuple(sizes), center,
                        float(factor), int(start_level))


@jax.jit(static_argnums=(0, 1, 2))
def _generate_jit(scale, negative_slope, eps, v0, geos, params, zs):
    return generate(params, v0, geos, zs, scale=scale, negative_slope=negative_slope, eps=eps)


def run_plan(model: Model, plan: TransferPlan, noise: Sequence[Float[Array, "Vl 3"] | float]) -> Float[Array, "Vn 3"]:
    """Run the generators on a prepared target with the given noise (jit-compiled, pure JAX).

    .. math:: v_{l+1} = s\\,U_l\\big(v_l + G_l(v_l, z_l)\\big),\\quad l = \\text{start} \\ldots L-1

    Args:
      model: the :class:`~jmeshtex.dgts.Model` the plan was made for.
      plan: from :func:`plan_transfer`.
      noise: one ``[V_l, 3]`` array (``plan.sizes[l]``) or scalar 0 per level run.

    Returns:
      ``[V_n, 3]`` float32 output in the last level's frame (:meth:`TransferPlan.to_target` maps it
      back); a second call with the same shapes does not recompile.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.dgts import Config, init_level
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(2))
      >>> model = Model(c, gs, gs, np.zeros((12, 3), np.float32))
      >>> plan = plan_transfer(model, icosahedron())
      >>> plan.to_target(run_plan(model, plan, [0.0, 0.0])).shape
      (42, 3)
    """
    if len(noise) != len(plan.sizes):
        raise InputError(f"run_plan: got {len(noise)} noises for {len(plan.sizes)} levels")
    c = model.config
    params = tuple(model.generators[plan.start_level:])
    return _generate_jit(c.scale_factor, c.negative_slope, c.eps, plan.vertices, plan.geometry, params, tuple(noise))


def _noises(key: PRNGKey, sizes: Sequence[int], amplitude: float) -> list[jax.Array]:
    keys = jax.random.split(key, len(sizes))
    return [amplitude * jax.random.normal(k, (s, 3), jnp.float32) for k, s in zip(keys, sizes, strict=True)]


def _synthesise(model: Model, target, start_level: int, noises: Callable) -> DGTSTransfer:
    """Run the generators from ``start_level`` on the target once per noise list ``noises(sizes)``
    returns (one ``[V_l, 3]`` array per level run), and map the results back to the target's frame."""
    plan = plan_transfer(model, target, start_level=start_level)
    draws = noises(plan.sizes)
    outs = [run_plan(model, plan, zs) for zs in draws]
    base = plan.vertices
    for g in plan.geometry[:-1]:
        base = upsample(base, g.edge_vertices, scale=model.config.scale_factor)
    base = np.asarray(base, np.float64)
    nrm = vertex_normals(base, plan.faces[-1])
    outs = [np.asarray(o, np.float64) for o in outs]
    heights = np.stack([np.einsum("vd,vd->v", o - base, nrm) for o in outs])
    vertices = np.stack([plan.to_target(o) for o in outs])
    return DGTSTransfer(vertices, plan.faces[-1], plan.to_target(base), heights,
                        [[np.asarray(z) for z in zs] for zs in draws])


def transfer(
    model: Model,
    target: Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]],
    *,
    key: PRNGKey,
    start_level: int = 0,
    num_samples: int = 1,
) -> DGTSTransfer:
    """Synthesise the learned texture on a target mesh, ``num_samples`` times with different noise.

    .. math:: v_{l+1} = 2\\,U_l\\big(v_l + G_l(v_l, z_l)\\big),\\quad l = \\text{start\\_level} \\ldots L-1,
       \\quad v_{\\text{start}} = \\text{target} / \\bar\\ell

    Args:
      model: a trained :class:`~jmeshtex.dgts.Model`.
      target: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])`` (any scale and
        placement; open or closed, any genus).
      key: PRNG key of the noise.
      start_level: first generator to run (0: coarsest); the target is treated as a level-``start``
        mesh, so ``L − start_level − 1`` subdivisions follow.
      num_samples: independent noise draws.

    Returns:
      :class:`DGTSTransfer` in the target's coordinates.

    Raises:
      InputError: a bad ``start_level`` or ``num_samples``, an untrained model, a target that is
        not a mesh.
      MeshError: (a subclass) an invalid target.

    Example:
      >>> from jmeshtex.data import icosahedron, torus
      >>> from jmeshtex.dgts import Config, PrepareConfig, train, training_meshes
      >>> tm = training_meshes(icosahedron(), icosahedron(), config=PrepareConfig(levels=2, steps=0),
      ...                      key=jax.random.key(0))
      >>> cfg = Config(num_layers=3, start_features=4, min_features=4, max_features=4, steps=2, shared_levels=2)
      >>> model = train(tm, cfg, key=jax.random.key(3), progress=False).model
      >>> res = transfer(model, torus(8, 6), num_samples=2, key=jax.random.key(0))
      >>> res.vertices.shape, res.faces.shape
      ((2, 192, 3), (384, 3))
    """
    if isinstance(num_samples, bool) or not isinstance(num_samples, (int, np.integer)) or num_samples < 1:
        raise InputError(f"num_samples must be a positive int, got {num_samples!r}")

    def noises(sizes):
        return [_noises(jax.random.fold_in(key, s), sizes, model.config.noise_amplitude) for s in range(int(num_samples))]

    return _synthesise(model, target, start_level, noises)


def interpolate(
    model: Model,
    target: Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]],
    *,
    key: PRNGKey,
    start_level: int = 0,
    num_frames: int = 8,
) -> DGTSTransfer:
    """Frames of a latent interpolation between two noise draws (the reference code's animation).

    .. math:: z(t) = (1 - t)\\, z_a + t\\, z_b,\\qquad t = 0, \\tfrac{1}{N-1}, \\ldots, 1

    Args:
      model, target, start_level: as :func:`transfer`.
      key: PRNG key of ``z_a`` and ``z_b``.
      num_frames: frames including both ends (≥ 2).

    Returns:
      :class:`DGTSTransfer` with one "sample" per frame; ``noise[0]`` is ``z_a`` and
      ``noise[-1]`` is ``z_b``.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.dgts import Config, PrepareConfig, train, training_meshes
      >>> tm = training_meshes(icosahedron(), icosahedron(), config=PrepareConfig(levels=2, steps=0),
      ...                      key=jax.random.key(0))
      >>> cfg = Config(num_layers=3, start_features=4, min_features=4, max_features=4, steps=2, shared_levels=2)
      >>> model = train(tm, cfg, key=jax.random.key(3), progress=False).model
      >>> interpolate(model, icosahedron(), start_level=1, num_frames=3, key=jax.random.key(0)).vertices.shape
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

    return _synthesise(model, target, start_level, noises)


def normal_heights(
    mesh: Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]],
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
    edge length. Bumps point outwards as positive heights; the distribution of ``h`` summarises a
    geometric texture.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or a ``(vertices [V, 3], faces [F, 3])`` pair.
      smoothing: pairs of Taubin steps.
      lam, mu: the shrink and inflate factors of a pair.

    Returns:
      ``[V]`` float64 heights in mean edges.

    Example:
      >>> from jmeshtex.data import grid
      >>> float(np.abs(normal_heights(grid(6))).max())  # a flat sheet has no texture
      0.0
    """
    v, f = as_mesh(mesh, what="normal_heights: mesh")
    v = np.asarray(v, np.float64)
    f = np.asarray(f, np.int64)
    V = len(v)
    pairs = unique_edges(f, V)
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

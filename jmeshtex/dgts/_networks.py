"""DGTS generator and discriminator of one level, and the generator hierarchy (Hertz et al. 2020, §3.2–3.4).

Pure functions over plain parameter pytrees (:class:`~jmeshtex.ops.FaceConvStackParams`), plus thin
flax modules (:class:`Generator`, :class:`Discriminator`) that only create those parameters.

One generator level (paper §3.4, "noise before" variant of the reference code):

.. math:: \\tilde v = v + z,\\qquad d = G_\\theta\\big(\\phi(\\tilde v)\\big) \\in \\mathbb R^{F\\times 3},
   \\qquad v' = v + \\Pi_v(d)

with ``z`` Gaussian vertex noise, ``φ`` the rigid-invariant face features of the *noisy* mesh
(:func:`~jmeshtex.ops.face_features`), ``G`` a face-convolution stack and ``Π_v`` the average over a
vertex's faces of the per-face coefficients expressed in the *clean* mesh's edge frames
(:func:`~jmeshtex.ops.face_to_vertex_displacement`). Between levels the mesh is subdivided at edge
midpoints and scaled by ``scale_factor`` (2), which keeps the mean edge ≈ 1 at every level.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import flax.linen as nn
import jax  # noqa: F401  (the doctests use it)
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._neighborhoods import FaceNeighborhood
from .._types import Array, Float, Int, PRNGKey
from ..geometry import face_neighborhood, subdivide_midpoint, to_jax
from ..ops import (
    FaceConvStackParams,
    face_conv_stack,
    face_features,
    face_to_vertex_displacement,
    init_face_conv_stack,
)
from ._config import Config


class LevelGeometry(NamedTuple):
    """Static connectivity of one level of a hierarchy (a pytree of JAX arrays).

    Attributes:
      nbhd: the level's :class:`~jmeshtex.FaceNeighborhood`.
      edge_vertices: ``[E, 2]`` coarse edges whose midpoints become the next level's new vertices
        (``[0, 2]`` at the last level).
    """

    nbhd: FaceNeighborhood
    edge_vertices: Int[Array, "E 2"]


def hierarchy_geometry(
    faces: Int[np.ndarray, "F 3"], num_vertices: int, levels: int
) -> tuple[tuple[LevelGeometry, ...], tuple[np.ndarray, ...]]:
    """Connectivity of ``levels`` levels obtained by repeated midpoint subdivision of ``faces``.

    Only the connectivity matters (no positions), so this takes the faces of a mesh, not the mesh.

    Args:
      faces: ``[F, 3]`` triangles of the coarsest level.
      num_vertices: V of the coarsest level.
      levels: number of levels, ≥ 1.

    Returns:
      ``(geometries, faces_per_level)``; geometry ``l`` holds the face neighbourhood of level ``l`` and
      the subdivision edges from level ``l`` to ``l + 1``.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> geos, faces = hierarchy_geometry(icosahedron().faces, 12, 3)
      >>> [f.shape[0] for f in faces], [g.edge_vertices.shape[0] for g in geos]
      ([20, 80, 320], [30, 120, 0])
    """
    f = np.asarray(faces, dtype=np.int64)
    V = int(num_vertices)
    dummy = np.zeros((V, 3))
    geos, all_faces = [], []
    for level in range(levels):
        nb = face_neighborhood(f, V)
        if level + 1 < levels:
            sub = subdivide_midpoint(dummy, f)
            edges, nf = sub.edge_vertices, sub.faces
        else:
            edges, nf = np.zeros((0, 2), np.int64), None
        geos.append(LevelGeometry(to_jax(nb), jnp.asarray(edges, jnp.int32)))
        all_faces.append(f)
        if nf is not None:
            V += len(edges)
            dummy = np.zeros((V, 3))
            f = nf
    return tuple(geos), tuple(all_faces)


def upsample(
    vertices: Float[Array, "V 3"], edge_vertices: Int[Array, "E 2"], *, scale: float = 2.0
) -> Float[Array, "V+E 3"]:
    """Midpoint subdivision of the positions followed by a uniform rescale (between DGTS levels).

    .. math:: v' = s\\,[\\,v;\\ \\tfrac12(v_{e_0} + v_{e_1})\\,]

    Args:
      vertices: ``[V, 3]`` positions of the coarse level.
      edge_vertices: ``[E, 2]`` the edges whose midpoints become new vertices ``V … V+E−1``
        (:attr:`LevelGeometry.edge_vertices`).
      scale: the uniform rescale (``Config.scale_factor``).

    Returns:
      ``[V + E, 3]`` positions of the fine level, ``vertices``' dtype.

    Example:
      >>> upsample(jnp.array([[0.0, 0, 0], [1.0, 0, 0]]), jnp.array([[0, 1]])).tolist()
      [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    """
    mids = 0.5 * (vertices[edge_vertices[:, 0]] + vertices[edge_vertices[:, 1]])
    return jnp.concatenate([vertices, mids], axis=0) * jnp.asarray(scale, vertices.dtype)


def generator_level(
    params: FaceConvStackParams,
    vertices: Float[Array, "V 3"],
    nbhd: FaceNeighborhood,
    noise: Float[Array, "V 3"] | float = 0.0,
    *,
    negative_slope: float = 0.2,
    eps: float = 1e-5,
    y_sign: float = 1.0,
) -> Float[Array, "V 3"]:
    """Per-vertex displacement produced by one DGTS generator level (module docstring formula).

    Args:
      params: the level's face-convolution stack (last width 3).
      vertices: ``[V, 3]`` clean positions (level frame, mean edge ≈ 1).
      nbhd: the level's face neighbourhood.
      noise: ``[V, 3]`` vertex noise added before the features are computed (0: none).
      negative_slope, eps: leaky-ReLU slope and instance-norm regulariser.
      y_sign: sign of the in-plane coefficient ``d_y`` (static): 1 for jmeshtex's axis ``y = n × x``,
        −1 for the official code's ``y = x × n`` (:attr:`~jmeshtex.dgts.Config.y_sign`; the sign cannot be folded
        into the last layer's weights because a max over neighbours follows them).

    Returns:
      ``[V, 3]`` world-frame displacement ``Π_v(d)``; rotates with rigid motions of ``vertices``
      (and ``noise``), independent of vertex and face labelling.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.geometry import face_neighborhood
      >>> v, f = icosahedron()
      >>> p = init_face_conv_stack(jax.random.key(0), (8, 8, 3))
      >>> generator_level(p, jnp.asarray(v, jnp.float32), face_neighborhood(f)).shape
      (12, 3)
    """
    if params.convs and params.convs[-1].weight.shape[-1] != 3:
        raise InputError(
            "generator_level: the last layer must have 3 outputs (displacement coefficients)"
        )
    noisy = vertices + jnp.asarray(noise, vertices.dtype)
    d = face_conv_stack(
        face_features(noisy, nbhd), nbhd, params, negative_slope=negative_slope, eps=eps
    )
    if float(y_sign) != 1.0:
        d = d * jnp.asarray([1.0, float(y_sign), 1.0], d.dtype)
    return face_to_vertex_displacement(d, vertices, nbhd)


def discriminator_features(
    params: FaceConvStackParams,
    features: Float[Array, "F 3 4"],
    nbhd: FaceNeighborhood,
    *,
    negative_slope: float = 0.2,
    eps: float = 1e-5,
) -> Float[Array, " F"]:
    """Per-face critic scores of a patch discriminator, from face features (used by the penalty).

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.geometry import face_neighborhood
      >>> v, f = icosahedron()
      >>> nb = face_neighborhood(f)
      >>> p = init_face_conv_stack(jax.random.key(0), (8, 8, 1))
      >>> discriminator_features(p, face_features(jnp.asarray(v), nb), nb).shape
      (20,)
    """
    return face_conv_stack(features, nbhd, params, negative_slope=negative_slope, eps=eps)[:, 0]


def discriminator(
    params: FaceConvStackParams,
    vertices: Float[Array, "V 3"],
    nbhd: FaceNeighborhood,
    *,
    negative_slope: float = 0.2,
    eps: float = 1e-5,
) -> Float[Array, " F"]:
    """Per-face critic scores of a mesh (DGTS's patch discriminator: each face sees its receptive field).

    .. math:: D(v)_f = \\mathrm{stack}_\\psi\\big(\\phi(v)\\big)_f

    Args:
      params: the critic's face-convolution stack (last width 1).
      vertices: ``[V, 3]`` positions.
      nbhd: the mesh's face neighbourhood.
      negative_slope, eps: leaky-ReLU slope and instance-norm regulariser.

    Returns:
      ``[F]`` scores, invariant to rigid motions and to relabelling.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.geometry import face_neighborhood
      >>> v, f = icosahedron()
      >>> p = init_face_conv_stack(jax.random.key(0), (8, 8, 1))
      >>> discriminator(p, jnp.asarray(v), face_neighborhood(f)).shape
      (20,)
    """
    return discriminator_features(
        params, face_features(vertices, nbhd), nbhd, negative_slope=negative_slope, eps=eps
    )


def generate(
    params: Sequence[FaceConvStackParams],
    vertices: Float[Array, "V 3"],
    geometry: Sequence[LevelGeometry],
    noise: Sequence[Float[Array, "Vl 3"] | float],
    *,
    scale: float = 2.0,
    negative_slope: float = 0.2,
    eps: float = 1e-5,
    y_sign: float = 1.0,
    per_level: bool = False,
) -> Float[Array, "Vn 3"] | tuple[Float[Array, "Vl 3"], ...]:
    """Run generator levels one after another, subdividing in between (DGTS inference, §3.4).

    .. math:: v_{l+1} = s\\, U_l\\big(v_l + G_l(v_l, z_l)\\big)

    Args:
      params: one parameter set per level to run (``len(params) = n``).
      vertices: ``[V, 3]`` input of the first level run, in its frame.
      geometry: the matching :class:`LevelGeometry` per level run.
      noise: per level, ``[V_l, 3]`` noise or a scalar 0.
      scale: rescaling after each subdivision.
      negative_slope, eps, y_sign: as :func:`generator_level`.
      per_level: also return every level's output (the growing output of the paper's Fig. 6).

    Returns:
      ``[V_n, 3]`` output of the last level (not subdivided after it), in its frame; with
      ``per_level`` the tuple of every level's output ``v_l + G_l(v_l, z_l)`` (in level ``l``'s
      frame, before subdivision), the last one being that output.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> v, f = icosahedron()
      >>> geos, _ = hierarchy_geometry(f, 12, 2)
      >>> ps = [init_face_conv_stack(jax.random.key(i), (8, 3)) for i in range(2)]
      >>> generate(ps, jnp.asarray(v, jnp.float32), geos, [0.0, 0.0]).shape
      (42, 3)
    """
    if not (len(params) == len(geometry) == len(noise)):
        raise InputError(
            f"generate: got {len(params)} parameter sets, {len(geometry)} geometries and {len(noise)} noises; "
            "pass one of each per level"
        )
    v = vertices
    outputs = []
    for i, (p, g, z) in enumerate(zip(params, geometry, noise, strict=True)):
        v = v + generator_level(
            p, v, g.nbhd, z, negative_slope=negative_slope, eps=eps, y_sign=y_sign
        )
        outputs.append(v)
        if i + 1 < len(params):
            v = upsample(v, g.edge_vertices, scale=scale)
    return tuple(outputs) if per_level else v


def init_level(
    config: Config, level: int, *, generator: bool, key: PRNGKey, dtype=jnp.float32
) -> FaceConvStackParams:
    """Fresh parameters of one level's generator or discriminator (widths from the config).

    Args:
      config: the widths (:meth:`~jmeshtex.dgts.Config.level_features`).
      level: the level, 0 the coarsest.
      generator: the generator (last width 3) or the discriminator (last width 1).
      key: PRNG key of the initialisation.
      dtype: parameter dtype.

    Returns:
      A :class:`~jmeshtex.ops.FaceConvStackParams`.

    Example:
      >>> p = init_level(Config(), 1, generator=True, key=jax.random.key(0))
      >>> p.embed.weight.shape, p.convs[-1].weight.shape
      ((4, 64), (64, 3))
    """
    return init_face_conv_stack(key, config.level_features(level, generator=generator), dtype=dtype)


class _FaceStackModule(nn.Module):
    """Fields shared by the flax wrappers: widths, activation and norm settings, parameter dtype."""

    features: Sequence[int]
    negative_slope: float = 0.2
    eps: float = 1e-5
    param_dtype: jnp.dtype = jnp.float32

    def stack(self) -> FaceConvStackParams:
        """Create (or fetch) the ``"stack"`` parameter: a :class:`~jmeshtex.ops.FaceConvStackParams`."""
        return self.param(
            "stack", lambda key: init_face_conv_stack(key, self.features, dtype=self.param_dtype)
        )


class Generator(_FaceStackModule):
    """Thin flax wrapper of one generator level: creates ``"stack"`` and calls :func:`generator_level`.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.geometry import face_neighborhood
      >>> v, f = icosahedron()
      >>> nb, x = face_neighborhood(f), jnp.asarray(v, jnp.float32)
      >>> m = Generator((8, 8, 3))
      >>> variables = m.init(jax.random.key(0), x, nb)
      >>> m.apply(variables, x, nb).shape
      (12, 3)
    """

    @nn.compact
    def __call__(self, vertices, nbhd, noise=0.0):
        return generator_level(
            self.stack(), vertices, nbhd, noise, negative_slope=self.negative_slope, eps=self.eps
        )


class Discriminator(_FaceStackModule):
    """Thin flax wrapper of one discriminator level: creates ``"stack"`` and calls :func:`discriminator`.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.geometry import face_neighborhood
      >>> v, f = icosahedron()
      >>> nb, x = face_neighborhood(f), jnp.asarray(v, jnp.float32)
      >>> m = Discriminator((8, 8, 1))
      >>> m.apply(m.init(jax.random.key(0), x, nb), x, nb).shape
      (20,)
    """

    @nn.compact
    def __call__(self, vertices, nbhd):
        return discriminator(
            self.stack(), vertices, nbhd, negative_slope=self.negative_slope, eps=self.eps
        )

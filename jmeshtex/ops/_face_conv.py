"""DGTS face convolutions (Hertz et al. 2020, "Deep Geometric Texture Synthesis", §3.1–3.2).

A DGTS generator sees a mesh as a set of faces. Each face gets rotation- and translation-invariant
input features measured in three *edge frames*, is convolved with its (up to) three edge neighbours
by a symmetric operator (a shared linear map followed by a max over neighbours, so the result does
not depend on the order of a face's edges), and finally emits one 3-vector per face that is expressed
in the edge frames again and averaged onto the vertices as a displacement. Because input features
and output displacements both live in frames that move with the mesh, the whole generator is
invariant (features) / equivariant (displacements) under rigid motions.

Edge frame ``k`` of face ``f = (v_0, v_1, v_2)`` (counter-clockwise seen from outside):

- origin: the midpoint ``(v_k + v_{k+1}) / 2`` of edge ``k``;
- ``x = (v_{k+1} - v_k) / |v_{k+1} - v_k|`` along the edge;
- ``z = n_f``, the unit face normal ``(v_1 - v_0) × (v_2 - v_0)`` normalised;
- ``y = z × x`` (a right-handed frame; the reference code uses ``x × z``, i.e. ``-y``).

Degenerate faces (collinear or coincident corners) get zero axes wherever the axis is undefined, so
features, displacements and their gradients stay finite (:mod:`._util` safe norms). Padded faces
(``face_mask`` False) give zero features and zero outputs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import jax
import jax.numpy as jnp

from .._errors import InputError
from .._neighborhoods import FaceNeighborhood
from .._types import Array, ArrayLike, Bool, Float, PRNGKey
from ._numerics import (
    check_key,
    check_size,
    elementwise_max,
    masked_mean,
    safe_norm,
    safe_normalize,
)


class EdgeFrames(NamedTuple):
    """Per-face, per-edge orthonormal frames (see the module docstring for the definition).

    Attributes:
      origin: ``[F, 3, 3]`` midpoint of edge k of face f (world coordinates).
      x: ``[F, 3, 3]`` unit vector along edge k, ``v_k → v_{k+1}``.
      y: ``[F, 3, 3]`` ``z × x``, in the face plane, pointing into the face.
      z: ``[F, 3, 3]`` the unit face normal (the same for the three edges).
    """

    origin: Float[ArrayLike, "F 3 3"]
    x: Float[ArrayLike, "F 3 3"]
    y: Float[ArrayLike, "F 3 3"]
    z: Float[ArrayLike, "F 3 3"]


class FaceEmbedParams(NamedTuple):
    """Parameters of :func:`face_edge_embed`: a linear map shared by the three edges.

    Attributes:
      weight: ``[E, C]`` (``E = 4`` edge features in, ``C`` channels out).
      bias: ``[C]``.
    """

    weight: Float[ArrayLike, "E C"]
    bias: Float[ArrayLike, " C"]


class FaceConvParams(NamedTuple):
    """Parameters of :func:`face_conv`.

    Attributes:
      weight: ``[2C, D]``; rows ``0..C-1`` act on the neighbour's features ``x_j``, rows
        ``C..2C-1`` on the face's own features ``x_self`` (the input ``[x_j ; x_self]``).
      bias: ``[D]``.
    """

    weight: Float[ArrayLike, "C2 D"]
    bias: Float[ArrayLike, " D"]


class FaceConvStackParams(NamedTuple):
    """Parameters of :func:`face_conv_stack`: the embedding layer, then the face convolutions.

    Attributes:
      embed: the first layer, :class:`FaceEmbedParams`.
      convs: one :class:`FaceConvParams` per following layer (may be empty).
    """

    embed: FaceEmbedParams
    convs: tuple[FaceConvParams, ...]


def _check_vertices(vertices, nbhd: FaceNeighborhood, name: str) -> None:
    if vertices.ndim != 2 or vertices.shape[-1] != 3:
        raise InputError(f"{name}: vertices must have shape [V, 3], got {tuple(vertices.shape)}")
    if not jnp.issubdtype(vertices.dtype, jnp.floating):
        raise InputError(f"{name}: vertices must be floating point, got {vertices.dtype}")
    V = nbhd.vertex_mask.shape[0]
    if vertices.shape[0] != V:
        raise InputError(
            f"{name}: {vertices.shape[0]} vertices but the FaceNeighborhood has V = {V}; pad the "
            "vertices with zeros to the neighbourhood's V (or pad_to the neighbourhood)"
        )


def edge_frames(vertices: Float[ArrayLike, "V 3"], nbhd: FaceNeighborhood) -> EdgeFrames:
    """The three edge frames of every face used by DGTS features and displacements.

    .. math:: o_k = \\tfrac12 (v_k + v_{k+1}),\\quad x_k = \\frac{v_{k+1} - v_k}{|v_{k+1} - v_k|},
       \\quad z = \\frac{(v_1 - v_0) \\times (v_2 - v_0)}{|\\cdot|},\\quad y_k = z \\times x_k

    Args:
      vertices: ``[V, 3]`` world positions.
      nbhd: from :func:`jmeshtex.geometry.face_neighborhood` (only ``faces`` is read).

    Returns:
      :class:`EdgeFrames`, each field ``[F, 3 (edge k), 3 (xyz)]``. Axes that are undefined on a
      degenerate face are zero.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import single_triangle
      >>> from jmeshtex.geometry import face_neighborhood
      >>> v, f = single_triangle()
      >>> fr = edge_frames(jnp.asarray(v), face_neighborhood(f))
      >>> fr.x[0, 0].tolist(), fr.y[0, 0].tolist(), fr.z[0, 0].tolist()
      ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0])
    """
    _check_vertices(vertices, nbhd, "edge_frames")
    tri = vertices[nbhd.faces]  # [F, 3 corners, 3]
    nxt = jnp.roll(tri, -1, axis=1)  # v_{k+1}
    x = safe_normalize(nxt - tri)
    normal = safe_normalize(jnp.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    z = jnp.broadcast_to(normal[:, None, :], x.shape)
    y = jnp.cross(z, x)
    return EdgeFrames(origin=0.5 * (tri + nxt), x=x, y=y, z=z)


def face_features(
    vertices: Float[ArrayLike, "V 3"], nbhd: FaceNeighborhood
) -> Float[Array, "F 3 4"]:
    """Rigid-motion-invariant input features of every face, one row of 4 per edge (DGTS §3.1).

    For edge ``k`` of face ``f`` with frame :func:`edge_frames` ``(o_k, x_k, y_k, z)`` and ``p`` the
    vertex of the neighbouring face across edge ``k`` that is opposite the edge (``nbhd.opposite``):

    .. math:: \\phi_{f,k} = \\big(|v_{k+1} - v_k|,\\ (p - o_k)\\cdot x_k,\\ (p - o_k)\\cdot y_k,
       \\ (p - o_k)\\cdot z\\big)

    On a boundary edge there is no neighbouring face; the neighbourhood pytree already substitutes
    the face's *own* opposite vertex ``v_{k+2}`` (:class:`~jmeshtex.FaceNeighborhood`), so
    the feature describes the face itself (its ``z`` coordinate is 0). The reference code uses the
    edge midpoint there instead (all three coordinates 0).

    Args:
      vertices: ``[V, 3]`` world positions (float32 or float64; the output follows).
      nbhd: from :func:`jmeshtex.geometry.face_neighborhood`, possibly padded.

    Returns:
      ``[F, 3 (edge k), 4]`` features ``(length, x, y, z)``; zero on padded faces. Unchanged by
      rotations and translations of ``vertices``; cyclically rotating a face's vertex order
      cyclically permutes its three rows.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.geometry import face_neighborhood
      >>> v = jnp.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 1]])
      >>> nb = face_neighborhood(np.array([[0, 1, 2], [2, 1, 3]]))
      >>> face_features(v, nb)[0, 1].round(4).tolist()  # edge 1→2, across it vertex 3
      [1.4142, 0.0, -0.7071, 1.0]
    """
    frames = edge_frames(vertices, nbhd)
    tri = vertices[nbhd.faces]
    length = safe_norm(jnp.roll(tri, -1, axis=1) - tri)  # [F, 3]
    rel = vertices[nbhd.opposite] - frames.origin  # [F, 3, 3]
    coords = jnp.stack(
        [jnp.sum(rel * frames.x, -1), jnp.sum(rel * frames.y, -1), jnp.sum(rel * frames.z, -1)], -1
    )
    feats = jnp.concatenate([length[..., None], coords], axis=-1)
    return feats * nbhd.face_mask.astype(feats.dtype)[:, None, None]


def face_edge_embed(
    features: Float[ArrayLike, "F 3 E"], params: FaceEmbedParams
) -> Float[Array, "F C"]:
    """First DGTS layer: a linear map shared by the three edges, then the max over edges (§3.2).

    .. math:: h_f = \\max_{k \\in \\{0,1,2\\}} \\big(W^\\top \\phi_{f,k} + b\\big)

    The max makes the result independent of which vertex a face's vertex list starts with.

    Args:
      features: ``[F, 3, E]`` per-edge features, e.g. :func:`face_features` (``E = 4``).
      params: :class:`FaceEmbedParams` (cast to the features' dtype).

    Returns:
      ``[F, C]`` face features. Padded faces (zero features) get ``max_k b = b``; the next
      :func:`face_conv` / :func:`instance_norm` ignores and zeroes them.

    Example:
      >>> p = FaceEmbedParams(jnp.eye(4)[:, :2], jnp.zeros(2))
      >>> face_edge_embed(jnp.arange(12.0).reshape(1, 3, 4), p).tolist()
      [[8.0, 9.0]]
    """
    if features.ndim != 3 or features.shape[1] != 3:
        raise InputError(
            f"face_edge_embed: features must be [F, 3, E], got {tuple(features.shape)}"
        )
    E = features.shape[-1]
    if params.weight.shape[0] != E or params.bias.shape != params.weight.shape[1:]:
        raise InputError(
            f"face_edge_embed: weight {tuple(params.weight.shape)} / bias {tuple(params.bias.shape)} "
            f"do not fit {E} edge features; expected weight [{E}, C] and bias [C]"
        )
    w = params.weight.astype(features.dtype)
    b = params.bias.astype(features.dtype)
    F = features.shape[0]
    h = (features.reshape(3 * F, E) @ w).reshape(F, 3, -1)  # one GEMM over all edges
    # an elementwise max of the three slices: on CPU its backward is ~10x cheaper than a reduce-max
    return elementwise_max((h[:, 0], h[:, 1], h[:, 2])) + b


def face_conv(
    x: Float[ArrayLike, "F C"], nbhd: FaceNeighborhood, params: FaceConvParams
) -> Float[Array, "F D"]:
    """Symmetric DGTS face convolution: a shared linear map per neighbour, max over neighbours (§3.2).

    .. math:: y_f = \\max_{j \\in \\mathcal N(f)} \\big(W^\\top [x_j ; x_f] + b\\big)
       = \\max_{j \\in \\mathcal N(f)} W_n^\\top x_j + W_s^\\top x_f + b

    where ``N(f)`` holds the faces across the edges of ``f`` that have one (``nbhd.mask``), so a
    boundary face takes the max over its one or two neighbours. Because the weights are shared by the
    neighbours, the GEMMs run first (``[F, C] @ [C, D]`` twice, a third of the FLOPs of
    gathering ``[x_j ; x_f]`` first) and only ``W_n^T x_j`` is gathered, one ``[F, D]`` slice per
    edge; the mask enters as an additive ``-big`` before an elementwise max (no ``where``).

    Conventions: a face with no neighbour at all (an isolated triangle) gets ``W_s^T x_f + b``, the
    neighbour term being 0; padded faces (``face_mask`` False) give 0.

    Args:
      x: ``[F, C]`` face features.
      nbhd: from :func:`jmeshtex.geometry.face_neighborhood`, possibly padded.
      params: :class:`FaceConvParams` with ``weight [2C, D]`` (cast to ``x``'s dtype).

    Returns:
      ``[F, D]`` face features.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.geometry import face_neighborhood
      >>> nb = face_neighborhood(np.array([[0, 1, 2], [2, 1, 3]]))
      >>> p = FaceConvParams(jnp.array([[1.0], [10.0]]), jnp.zeros(1))  # x_j + 10 x_f
      >>> face_conv(jnp.array([[1.0], [2.0]]), nb, p).tolist()
      [[12.0], [21.0]]
    """
    if x.ndim != 2 or x.shape[0] != nbhd.faces.shape[0]:
        raise InputError(
            f"face_conv: x must be [F, C] with F = {nbhd.faces.shape[0]} faces of the neighbourhood, "
            f"got {tuple(x.shape)}"
        )
    C = x.shape[1]
    if (
        params.weight.ndim != 2
        or params.weight.shape[0] != 2 * C
        or params.bias.shape != params.weight.shape[1:]
    ):
        raise InputError(
            f"face_conv: weight {tuple(params.weight.shape)} / bias {tuple(params.bias.shape)} do not fit "
            f"C = {C} input channels; expected weight [2C, D] = [{2 * C}, D] and bias [D]"
        )
    dtype = x.dtype
    w = params.weight.astype(dtype)
    z_nbr = x @ w[:C]  # W_n^T x for every face, gathered below
    z_self = x @ w[C:]
    mask = nbhd.mask.astype(dtype)
    big = jnp.asarray(jnp.finfo(dtype).max / 4, dtype)
    penalty = (mask - 1) * big  # 0 for real neighbours, -big for missing ones
    nbr_max = elementwise_max(
        tuple(z_nbr[nbhd.neighbors[:, k]] + penalty[:, k, None] for k in range(3))
    )
    has_nbr = jnp.max(mask, axis=1, keepdims=True)  # 0 for isolated faces
    y = nbr_max * has_nbr + z_self + params.bias.astype(dtype)
    return y * nbhd.face_mask.astype(dtype)[:, None]


def instance_norm(
    x: Float[ArrayLike, "F C"], mask: Bool[ArrayLike, " F"], *, eps: float | Float[Array, ""] = 1e-5
) -> Float[Array, "F C"]:
    """Mask-aware instance normalisation over faces, per channel, without affine parameters.

    .. math:: \\hat x_{fc} = m_f\\,\\frac{x_{fc} - \\mu_c}{\\sqrt{\\sigma_c^2 + \\epsilon}},\\quad
       \\mu_c = \\frac{\\sum_f m_f x_{fc}}{\\sum_f m_f},\\quad
       \\sigma_c^2 = \\frac{\\sum_f m_f (x_{fc} - \\mu_c)^2}{\\sum_f m_f}

    (PyTorch's ``InstanceNorm1d`` defaults, as DGTS uses them: biased variance, ``eps = 1e-5``.)

    Args:
      x: ``[F, C]`` features.
      mask: ``[F]`` True for real faces (``nbhd.face_mask``); padded rows are ignored and set to 0.
      eps: variance regulariser (keeps values and gradients finite for constant channels).

    Returns:
      ``[F, C]`` normalised features, same dtype.

    Example:
      >>> y = instance_norm(jnp.array([[1.0], [3.0], [7.0]]), jnp.array([True, True, False]), eps=0.0)
      >>> y.tolist()
      [[-1.0], [1.0], [0.0]]
    """
    if x.ndim != 2 or mask.shape != x.shape[:1]:
        raise InputError(
            f"instance_norm: x must be [F, C] and mask [F], got {tuple(x.shape)}, {tuple(mask.shape)}"
        )
    m = mask.astype(x.dtype)[:, None]
    mean = masked_mean(x, mask)
    centred = (x - mean) * m
    var = masked_mean(centred * centred, mask)
    return centred * jax.lax.rsqrt(var + jnp.asarray(eps, x.dtype))


def face_conv_stack(
    features: Float[ArrayLike, "F 3 E"],
    nbhd: FaceNeighborhood,
    params: FaceConvStackParams,
    *,
    negative_slope: float = 0.2,
    eps: float = 1e-5,
) -> Float[Array, "F D"]:
    """The DGTS face-convolution network: embedding, then face convolutions (§3.2).

    .. math:: h^{(0)} = \\mathrm{embed}(\\phi),\\quad
       h^{(l+1)} = \\mathrm{conv}_l\\big(\\mathrm{LReLU}(\\mathrm{IN}(h^{(l)}))\\big)

    Every layer but the last is followed by :func:`instance_norm` (mask-aware, over faces) and a leaky
    ReLU with slope ``negative_slope``, as in the reference ``MultiMeshConv``.

    Args:
      features: ``[F, 3, E]`` edge features from :func:`face_features`.
      nbhd: the face neighbourhood.
      params: :class:`FaceConvStackParams` (e.g. from :func:`init_face_conv_stack`).
      negative_slope: leaky-ReLU slope (DGTS: 0.2).
      eps: instance-norm regulariser.

    Returns:
      ``[F, D]`` outputs of the last layer (0 on padded faces when there is at least one
      convolution).

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.geometry import face_neighborhood
      >>> v, f = icosahedron()
      >>> nb = face_neighborhood(f)
      >>> p = init_face_conv_stack(jax.random.key(0), (8, 8, 3))
      >>> jax.jit(face_conv_stack)(face_features(jnp.asarray(v), nb), nb, p).shape
      (20, 3)
    """
    h = face_edge_embed(features, params.embed)
    for conv in params.convs:
        h = jax.nn.leaky_relu(instance_norm(h, nbhd.face_mask, eps=eps), negative_slope)
        h = face_conv(h, nbhd, conv)
    return h


def init_face_conv_stack(
    key: PRNGKey, features: Sequence[int], *, in_features: int = 4, dtype=jnp.float32
) -> FaceConvStackParams:
    """Random parameters for :func:`face_conv_stack` (PyTorch ``Conv1d`` default initialisation).

    Weights and biases are drawn from ``U(-1/√fan_in, 1/√fan_in)`` with ``fan_in = in_features`` for
    the embedding and ``2C`` for a face convolution on ``C`` channels.

    Args:
      key: PRNG key (split inside).
      features: output channels of each layer; ``features[0]`` is the embedding width, each further
        entry one :func:`face_conv` layer.
      in_features: edge features in (4 for :func:`face_features`).
      dtype: parameter dtype.

    Returns:
      :class:`FaceConvStackParams`.

    Example:
      >>> p = init_face_conv_stack(jax.random.key(0), (16, 32, 3))
      >>> p.embed.weight.shape, [c.weight.shape for c in p.convs]
      ((4, 16), [(32, 32), (64, 3)])
    """
    check_key(key, "init_face_conv_stack")
    features = tuple(int(c) for c in features)
    if not features or min(features) < 1:
        raise InputError(
            f"init_face_conv_stack: features must be a non-empty list of positive widths, got {features}"
        )
    keys = jax.random.split(key, 2 * len(features))
    fan_ins = [in_features] + [2 * c for c in features[:-1]]
    layers = []
    for i, (fan_in, out) in enumerate(zip(fan_ins, features, strict=True)):
        bound = 1.0 / math.sqrt(fan_in)
        w = jax.random.uniform(keys[2 * i], (fan_in, out), dtype, -bound, bound)
        b = jax.random.uniform(keys[2 * i + 1], (out,), dtype, -bound, bound)
        layers.append((w, b))
    return FaceConvStackParams(
        embed=FaceEmbedParams(*layers[0]), convs=tuple(FaceConvParams(w, b) for w, b in layers[1:])
    )


def init_face_conv(
    key: PRNGKey, in_features: int, out_features: int, *, dtype=jnp.float32
) -> FaceConvParams:
    """Random parameters of one :func:`face_conv` layer (PyTorch ``Conv1d`` default, as the stack's).

    Weights and bias from ``U(-1/√(2C), 1/√(2C))`` for ``C = in_features`` (the layer sees
    ``[x_j ; x_f]``).

    Example:
      >>> p = init_face_conv(jax.random.key(0), 8, 3)
      >>> p.weight.shape, p.bias.shape
      ((16, 3), (3,))
    """
    for name, value in (("in_features", in_features), ("out_features", out_features)):
        check_size(value, name, "init_face_conv")
    check_key(key, "init_face_conv")
    bound = 1.0 / math.sqrt(2 * in_features)
    k_w, k_b = jax.random.split(key)
    return FaceConvParams(
        jax.random.uniform(k_w, (2 * in_features, out_features), dtype, -bound, bound),
        jax.random.uniform(k_b, (out_features,), dtype, -bound, bound),
    )


def face_to_vertex_displacement(
    d: Float[ArrayLike, "F 3"], vertices: Float[ArrayLike, "V 3"], nbhd: FaceNeighborhood
) -> Float[Array, "V 3"]:
    """Per-face displacement coefficients in edge frames, averaged onto the vertices (DGTS §3.2).

    Corner ``k`` of face ``f`` reads the face's coefficients in the frame of the edge that *starts*
    at it (edge ``k``, ``v_k → v_{k+1}``, :func:`edge_frames`), and every vertex averages over its
    incident faces:

    .. math:: \\Delta v = \\frac{1}{|\\mathcal F(v)|} \\sum_{(f, k) \\in \\mathcal F(v)}
       d_{f,x}\\, x_{f,k} + d_{f,y}\\, y_{f,k} + d_{f,z}\\, z_f

    Because the frames move with the mesh, rotating ``vertices`` rotates the output.

    Args:
      d: ``[F, 3]`` per-face coefficients ``(d_x, d_y, d_z)``.
      vertices: ``[V, 3]`` positions that define the frames.
      nbhd: the face neighbourhood (``vertex_faces``, ``vertex_corners``, ``vertex_faces_mask``).

    Returns:
      ``[V, 3]`` world-space displacements; 0 on vertices without faces and on padded vertices.

    Example:
      >>> from jmeshtex.data import single_triangle
      >>> from jmeshtex.geometry import face_neighborhood
      >>> v, f = single_triangle()
      >>> out = face_to_vertex_displacement(jnp.array([[1.0, 0, 0]]), jnp.asarray(v), face_neighborhood(f))
      >>> out.round(4).tolist()  # each corner moves along its outgoing edge
      [[1.0, 0.0, 0.0], [-0.7071, 0.7071, 0.0], [0.0, -1.0, 0.0]]
    """
    _check_vertices(vertices, nbhd, "face_to_vertex_displacement")
    F = nbhd.faces.shape[0]
    if d.shape != (F, 3):
        raise InputError(
            f"face_to_vertex_displacement: d must be [F, 3] = [{F}, 3], got {tuple(d.shape)}"
        )
    fr = edge_frames(vertices, nbhd)
    d = d.astype(vertices.dtype)
    per_corner = (
        d[:, None, 0:1] * fr.x + d[:, None, 1:2] * fr.y + d[:, None, 2:3] * fr.z
    )  # [F, 3, 3]
    flat = per_corner.reshape(3 * F, 3)
    slot = nbhd.vertex_faces * 3 + nbhd.vertex_corners  # [V, M]
    w = nbhd.vertex_faces_mask.astype(vertices.dtype)
    w = w / jnp.maximum(jnp.sum(w, axis=1, keepdims=True), 1)
    return jnp.sum(flat[slot] * w[..., None], axis=1)

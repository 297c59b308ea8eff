"""The FL-VAE encoder: one-ring samples → a tangent-vector latent per vertex (paper §4, eq. 21–25).

Host side (NumPy): :func:`one_ring_samples` draws points area-uniformly in each vertex's one-ring and
gives their intrinsic log map ``log_p(q)`` in p's frame — the frame of
:func:`jmeshtex.geometry.one_ring_neighborhood` (x-axis = the edge to the first one-ring neighbour) —
divided by ``r_p``, the mean length of the edges at p, so the encoder sees the same coordinates at
every mesh resolution. Inside the wedge (p, q_j, q_{j+1}) with corner angle α and angle scale
``s_p`` (2π / angle sum at interior vertices), a point ``z = b_j ℓ_j + b_{j+1} ℓ_{j+1} e^{iα}`` laid
out in the flattened face has

.. math:: \\log_p(q) = |z|\\, e^{i(\\theta_{pj} + s_p \\arg z)} / r_p,

which equals the one-ring log map at the ring vertices and depends on edge lengths only.

JAX side (pure): :func:`encode_samples`. Each sample's colour goes through a real MLP and multiplies
its log coordinate (eq. 21: a feature that turns with the frame); a token starts as a filtered gather
of the samples (eq. 22); VN-Transformer blocks (:func:`jmeshtex.ops.vn_transformer_block`) mix
{samples, token}; the mean is a complex linear map of the token (eq. 24), ``log σ`` a real map of the
rotation invariants ``Re(u·conj(u W))`` of the token (eq. 25). A gauge change ``x → x e^{-iα}`` of
all log coordinates therefore rotates μ by ``e^{-iα}`` and leaves ``log σ`` unchanged, and the
samples form a set (any order).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._config import is_int
from .._errors import InputError
from .._random import key_ints
from .._types import Array, Bool, Complex, Float, Int
from ..geometry import corner_angles, edge_lengths, one_ring_angles
from ..ops import VNTransformerParams, complex_linear, real_dtype, vn_transformer_block

# ------------------------------------------------------------------------------------ host side


def _numpy_rng(key) -> np.random.Generator:
    """A NumPy generator seeded with a JAX key's data (host-side sampling driven by ``key=``)."""
    return np.random.default_rng(key_ints(key))


class RingGeometry(NamedTuple):
    """Per-vertex frames and per-corner wedge data for intrinsic log maps of points in faces.

    Attributes:
      theta: ``[V, K]`` angle of one-ring slot j in p's frame (``one_ring_angles``).
      scale: ``[V]`` angle scale ``s_p``.
      radius: ``[V]`` ``r_p``, mean length of the edges at p (each counted once per incident face).
      lengths: ``[F, 3]`` edge lengths, column k = edge ``faces[:, k] → faces[:, k+1]``.
      angles: ``[F, 3]`` corner angles.
      corner_slot: ``[F, 3]`` one-ring slot j of ``faces[f, (k+1) % 3]`` in the ring of ``faces[f, k]``
        (the wedge of face f at corner k starts at that slot).
      faces: ``[F, 3]`` int64.
      wedge_faces: ``[V, K]`` face of wedge j at p; ``wedge_mask`` ``[V, K]`` True for real wedges.
    """

    theta: np.ndarray
    scale: np.ndarray
    radius: np.ndarray
    lengths: np.ndarray
    angles: np.ndarray
    corner_slot: np.ndarray
    faces: np.ndarray
    wedge_faces: np.ndarray
    wedge_mask: np.ndarray


def ring_geometry(
    vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"]
) -> RingGeometry:
    """Build :class:`RingGeometry` (edge lengths only; the gauge of ``one_ring_neighborhood``)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    rings, theta, scale = one_ring_angles(vertices, faces)
    lengths = edge_lengths(vertices, faces)
    angles = corner_angles(lengths)
    num_v = len(vertices)
    wf, wm = rings.wedge_faces, rings.wedge_mask
    p, j = np.nonzero(wm)
    f = wf[p, j]
    corner = np.argmax(faces[f] == p[:, None], axis=1)
    corner_slot = np.zeros(faces.shape, np.int64)
    corner_slot[f, corner] = j
    # r_p: mean of the two edges at each incident corner
    total = np.bincount(
        faces.ravel(), weights=(lengths + np.roll(lengths, 1, axis=1)).ravel(), minlength=num_v
    )
    count = np.bincount(faces.ravel(), minlength=num_v) * 2.0
    radius = np.where(count > 0, total / np.maximum(count, 1.0), 1.0)
    return RingGeometry(theta, scale, radius, lengths, angles, corner_slot, faces, wf, wm)


def corner_logs(
    geom: RingGeometry,
    face: Int[np.ndarray, "*N"],
    corner: Int[np.ndarray, "*N"],
    bary: Float[np.ndarray, "*N 3"],
) -> Complex[np.ndarray, "*N"]:
    """Normalised intrinsic ``log_p(x) / r_p`` of points ``x`` = (face, bary) seen from ``p = faces[face, corner]``.

    Args:
      geom: :class:`RingGeometry` of the mesh.
      face: ``[...N]`` face of each point.
      corner: ``[...N]`` which corner (0, 1, 2) of that face is the base vertex p.
      bary: ``[...N, 3]`` barycentric coordinates in the face's corner order.

    Returns:
      ``[...N]`` complex128 in p's frame (module docstring).
    """
    c1 = (corner + 1) % 3
    c2 = (corner + 2) % 3
    b1 = np.take_along_axis(bary, c1[..., None], axis=-1)[..., 0]
    b2 = np.take_along_axis(bary, c2[..., None], axis=-1)[..., 0]
    l1 = geom.lengths[face, corner]
    l2 = geom.lengths[face, c2]
    alpha = geom.angles[face, corner]
    z = b1 * l1 + b2 * l2 * np.exp(1j * alpha)
    p = geom.faces[face, corner]
    phase = geom.theta[p, geom.corner_slot[face, corner]] + geom.scale[p] * np.angle(z)
    return np.abs(z) * np.exp(1j * phase) / geom.radius[p]


class OneRingSamples(NamedTuple):
    """Points in every vertex's one-ring, with their log coordinates (host arrays).

    Attributes:
      log: ``[V, S]`` complex128 ``log_p(q) / r_p`` in p's frame (gauge of
        ``one_ring_neighborhood``); 0 where ``mask`` is False.
      face: ``[V, S]`` int64 face containing each sample (0 on padding).
      bary: ``[V, S, 3]`` float64 barycentric coordinates in that face (corner order of ``faces``).
      mask: ``[V, S]`` True for real samples (False at vertices without faces).
      centered: True when column 0 is the ring's centre, the vertex itself (log 0): what an
        encoder with ``token="centre"`` reads as the token's reference colour.
    """

    log: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    mask: np.ndarray
    centered: bool = False


#: fixed per-wedge rule (barycentrics on (p, q_j, q_{j+1})) of the deterministic "quadrature" sampler
_QUADRATURE = np.array(
    [
        [2 / 3, 1 / 6, 1 / 6],
        [1 / 3, 1 / 3, 1 / 3],
        [1 / 3, 1 / 2, 1 / 6],
        [1 / 3, 1 / 6, 1 / 2],
        [0.0, 0.5, 0.5],
        [0.5, 0.5, 0.0],
    ]
)


def one_ring_samples(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    num_samples: int,
    *,
    rng: np.random.Generator | None = None,
    geometry: RingGeometry | None = None,
    chunk: int = 8192,
    center: bool = False,
) -> OneRingSamples:
    """Sample every one-ring: area-uniform random points (or a fixed per-wedge rule) with log maps.

    Random (``rng`` given): a wedge with probability ∝ its area, then a uniform point in it by the
    square-root trick. Deterministic (``rng=None``): the same 6 barycentric points in every wedge
    (``S = 6 K``, ignoring ``num_samples``), for exact equivariance checks.

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` consistently oriented manifold triangles.
      num_samples: ``S`` samples per vertex (random mode).
      rng: a ``numpy.random.Generator``, or None for the deterministic rule.
      geometry: a precomputed ``ring_geometry`` (else built here).
      chunk: vertices per vectorised batch (bounds memory).
      center: put the ring's centre (the vertex itself: log 0, in the first wedge's face) in
        column 0, before the ``S`` samples (what ``Config(token="centre")`` encoders read).

    Returns:
      :class:`OneRingSamples` (``S + 1`` columns with ``center``).

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import grid
      >>> s = one_ring_samples(*grid(3), 16, rng=np.random.default_rng(0))
      >>> s.log.shape, bool(s.mask.all()), bool((np.abs(s.log) <= np.sqrt(2) / 0.5 + 1e-9).all())
      ((16, 16), True, True)
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    geom = ring_geometry(vertices, faces) if geometry is None else geometry
    wf, wm = geom.wedge_faces, geom.wedge_mask
    V, K = wf.shape
    p_all = np.arange(V)
    corner_of = np.argmax(faces[wf] == p_all[:, None, None], axis=-1)  # [V, K]
    if rng is None:
        q = len(_QUADRATURE)
        wedge = np.repeat(np.arange(K), q)[None, :].repeat(V, 0)  # [V, K q]
        local = np.tile(_QUADRATURE, (K, 1))[None].repeat(V, 0)
        mask = np.take_along_axis(wm, wedge, axis=1)
        out = _assemble(geom, wedge, local, mask, corner_of)
        return _with_center(geom, out, corner_of) if center else out
    if not is_int(num_samples, 1):
        raise InputError(f"num_samples must be a positive int, got {num_samples!r}")
    area = np.where(
        wm,
        0.5
        * geom.lengths[wf, corner_of]
        * geom.lengths[wf, (corner_of + 2) % 3]
        * np.sin(geom.angles[wf, corner_of]),
        0.0,
    )
    cum = np.cumsum(area, axis=1)
    total = cum[:, -1]
    out = []
    for start in range(0, V, chunk):
        sl = slice(start, min(start + chunk, V))
        u = rng.random((sl.stop - sl.start, num_samples)) * total[sl, None]
        wedge = np.minimum((cum[sl, None, :] <= u[..., None]).sum(-1), K - 1)
        s = np.sqrt(rng.random(u.shape))
        t = rng.random(u.shape)
        local = np.stack([1.0 - s, s * (1.0 - t), s * t], axis=-1)
        mask = np.take_along_axis(wm[sl], wedge, axis=1) & (total[sl, None] > 0)
        out.append(_assemble(geom, wedge, local, mask, corner_of[sl], offset=sl.start))
    joined = OneRingSamples(
        *(np.concatenate(parts, axis=0) for parts in zip(*(o[:4] for o in out), strict=True))
    )
    return _with_center(geom, joined, corner_of) if center else joined


def _with_center(geom: RingGeometry, s: OneRingSamples, corner_of: np.ndarray) -> OneRingSamples:
    """``s`` with the ring's centre (the vertex, in the face of its first wedge) as column 0."""
    face = np.where(geom.wedge_mask[:, 0], geom.wedge_faces[:, 0], 0)
    corner = np.where(geom.wedge_mask[:, 0], corner_of[:, 0], 0)
    bary = np.zeros((len(face), 3))
    bary[np.arange(len(face)), corner] = 1.0
    bary = np.where(geom.wedge_mask[:, :1], bary, 0.0)
    return OneRingSamples(
        log=np.concatenate([np.zeros((len(face), 1), s.log.dtype), s.log], axis=1),
        face=np.concatenate([face[:, None], s.face], axis=1),
        bary=np.concatenate([bary[:, None], s.bary], axis=1),
        mask=np.concatenate([geom.wedge_mask[:, :1], s.mask], axis=1),
        centered=True,
    )


def _assemble(geom, wedge, local, mask, corner_of, offset=0) -> OneRingSamples:
    """Turn (wedge slot, barycentrics on (p, q_j, q_{j+1})) into face-order samples with logs."""
    rows = np.arange(wedge.shape[0])[:, None] + offset
    face = np.where(mask, geom.wedge_faces[rows, wedge], 0)
    corner = np.where(mask, np.take_along_axis(corner_of, wedge, axis=1), 0)
    bary = np.zeros(local.shape)
    for k in range(3):  # local coordinate k belongs to face corner (corner + k) % 3
        np.put_along_axis(bary, ((corner + k) % 3)[..., None], local[..., k : k + 1], axis=-1)
    log = np.where(mask, corner_logs(geom, face, corner, bary), 0.0)
    bary = np.where(mask[..., None], bary, 0.0)
    return OneRingSamples(log=log, face=face, bary=bary, mask=mask)


# -------------------------------------------------------------------------------------- JAX side


class EncoderParams(NamedTuple):
    """Parameters of :func:`encode_samples` (plain pytree).

    Attributes:
      sample_mlp: real dense layers ``((W [3, C], b [C]), ...)`` on each sample's colour (eq. 21).
      token_mlp: real dense layers on ``[colour, |log|, ring mean colour]`` (eq. 22 filter).
      blocks: VN-Transformer blocks over {samples, token}.
      mean: ``[C, d]`` complex map token → μ (eq. 24).
      sigma_dir: ``[C, C]`` complex map for the invariants ``Re(u conj(u W))`` (eq. 25).
      sigma: ``(W [C, d], b [d])`` real map invariants → ``log σ``.
    """

    sample_mlp: tuple
    token_mlp: tuple
    blocks: tuple[VNTransformerParams, ...]
    mean: Array
    sigma_dir: Array
    sigma: tuple


class _Draw:
    """Slices of one standard-normal draw (each extra ``jax.random`` call costs ~1 s of compile time)."""

    def __init__(self, key, total: int, dtype):
        self.flat = jax.random.normal(key, (total,), dtype)
        self.pos = 0

    def take(self, shape) -> Array:
        n = int(np.prod(shape))
        out = self.flat[self.pos : self.pos + n].reshape(shape)
        self.pos += n
        return out


def _dense_size(sizes) -> int:
    return sum(a * b for a, b in zip(sizes[:-1], sizes[1:], strict=True))


def _dense_init(draw: _Draw, sizes, dtype):
    """LeCun-normal real dense layers ``((W, b), ...)`` for widths ``sizes`` (biases 0)."""
    return tuple(
        (draw.take((a, b)) * jnp.asarray(1.0 / np.sqrt(a), dtype), jnp.zeros((b,), dtype))
        for a, b in zip(sizes[:-1], sizes[1:], strict=True)
    )


def _complex_init(draw: _Draw, shape, fan_in: int, cdt):
    re, im = draw.take(shape), draw.take(shape)
    scale = jnp.asarray(1.0 / np.sqrt(2.0 * fan_in), re.dtype)
    return jax.lax.complex(re * scale, im * scale).astype(cdt)


def mlp(layers, x):
    """Real MLP: SiLU between dense layers, none after the last."""
    for i, (w, b) in enumerate(layers):
        x = x @ w + b
        if i < len(layers) - 1:
            x = jax.nn.silu(x)
    return x


def _vnt_block(
    draw: _Draw, c: int, heads: int, cdt, rdt, linear: bool = False
) -> VNTransformerParams:
    from ..ops import ComplexAttentionParams, VNParams

    e = c // heads
    attention = ComplexAttentionParams(
        query=_complex_init(draw, (c, heads, e), c, cdt),
        key=_complex_init(draw, (c, heads, e), c, cdt),
        value=_complex_init(draw, (c, heads, e), c, cdt),
        out=_complex_init(draw, (heads, e, c), heads * e, cdt),
        linear=_complex_init(draw, (c, c), c, cdt) if linear else None,
    )
    mlp_in = VNParams(_complex_init(draw, (c, c), c, cdt), _complex_init(draw, (c, c), c, cdt))
    mlp_out = VNParams(_complex_init(draw, (c, c), c, cdt), _complex_init(draw, (c, c), c, cdt))
    ones = jnp.ones((c,), rdt)
    return VNTransformerParams(ones, attention, ones, mlp_in, mlp_out)


def encoder_size(config) -> int:
    """Number of standard normals :func:`init_encoder` draws."""
    c, d = config.features, config.latent_dim
    block = 2 * (4 * c * c + 4 * c * c) + (2 * c * c if config.experimental.attention_linear else 0)
    return (
        _dense_size((3, c, c, c))
        + _dense_size((7, c, c))
        + config.num_blocks * block
        + 2 * (c * d + c * c)
        + c * d
    )


def init_encoder(draw: _Draw, config, *, dtype=jnp.float32) -> EncoderParams:
    """Random ``EncoderParams`` for ``config`` (an :class:`~jmeshtex.fl.Config`)."""
    c, d = config.features, config.latent_dim
    cdt = jnp.complex128 if jnp.dtype(dtype) == jnp.float64 else jnp.complex64
    sample_mlp = _dense_init(draw, (3, c, c, c), dtype)
    token_mlp = _dense_init(draw, (7, c, c), dtype)
    blocks = tuple(
        _vnt_block(draw, c, config.num_heads, cdt, dtype, config.experimental.attention_linear)
        for _ in range(config.num_blocks)
    )
    mean = _complex_init(draw, (c, d), c, cdt)
    sigma_dir = _complex_init(draw, (c, c), c, cdt)
    w, b = _dense_init(draw, (c, d), dtype)[0]
    # start at log σ ≈ config.experimental.log_sigma_init (-2: small σ, the KL pulls it up as training allows)
    sigma = (
        w * jnp.asarray(0.1, dtype),
        b + jnp.asarray(config.experimental.log_sigma_init, dtype),
    )
    return EncoderParams(sample_mlp, token_mlp, blocks, mean, sigma_dir, sigma)


def encode_samples_raw(
    params: EncoderParams,
    config,
    log_q: Complex[Array, "V S"],
    rgb: Float[Array, "V S 3"],
    mask: Bool[Array, "V S"],
) -> tuple[Complex[Array, "V d"], Float[Array, "V d"]]:
    """``(μ, log σ)`` from one-ring samples (see :func:`~jmeshtex.fl.core.encode_samples`)."""
    rdt = real_dtype(params.mean.dtype)
    cdt = params.mean.dtype
    log_q = jnp.asarray(log_q).astype(cdt)
    rgb = jnp.asarray(rgb).astype(rdt) - jnp.asarray(0.5, rdt)
    mask = jnp.asarray(mask, bool)
    center = config.experimental.token == "centre"
    if center:  # column 0 is the ring's centre: the token's reference colour, not a set element
        center_rgb = rgb[:, :1, :]
        log_q, rgb, mask = log_q[:, 1:], rgb[:, 1:], mask[:, 1:]
    m = mask.astype(rdt)
    count = jnp.maximum(jnp.sum(m, axis=1, keepdims=True), jnp.asarray(1.0, rdt))  # [V, 1]
    # eq. 21: a real feature of the colour times the sample's log coordinate
    h = mlp(params.sample_mlp, rgb) * m[..., None]  # [V, S, C]
    x = h.astype(cdt) * log_q[..., None]
    # eq. 22: token = filtered gather Σ f(colour, |log|, reference colour) log / n
    if center:
        ref_rgb = center_rgb
    else:
        ref_rgb = jnp.sum(rgb * m[..., None], axis=1, keepdims=True) / count[..., None]
    feats = jnp.concatenate(
        [rgb, jnp.abs(log_q)[..., None], jnp.broadcast_to(ref_rgb, rgb.shape)], axis=-1
    )
    g = mlp(params.token_mlp, feats) * m[..., None]
    token = jnp.sum(g.astype(cdt) * log_q[..., None], axis=1) / count.astype(cdt)  # [V, C]
    seq = jnp.concatenate([x, token[:, None, :]], axis=1)
    # the token is always valid; for the per-channel norm's batch statistic, padded vertices (no
    # valid sample) are left out
    token_valid = (
        jnp.any(mask, axis=1, keepdims=True)
        if config.experimental.vn_norm == "channel"
        else jnp.ones((mask.shape[0], 1), bool)
    )
    seq_mask = jnp.concatenate([mask, token_valid], axis=1)
    for block in params.blocks:
        seq = vn_transformer_block(
            seq, block, mask=seq_mask, delta=config.delta, norm=config.experimental.vn_norm
        )
    u = seq[:, -1, :]
    mu = complex_linear(u, params.mean)
    v = complex_linear(u, params.sigma_dir)
    inv = jnp.tanh(u.real * v.real + u.imag * v.imag)
    log_sigma = jnp.minimum(
        inv @ params.sigma[0] + params.sigma[1], jnp.asarray(config.log_sigma_max, rdt)
    )
    return mu, log_sigma

"""The FLDM denoiser: a two-level U-Net of FCResNet blocks over tangent-vector latents (2024 §5, supp. §8.2).

.. code-block:: text

    z_t [V, d] ─ lift ─ FCRes×down (C₀, fine k-NN) ─┬─ pool (transported mean) ─ FCRes×mid (C₁, coarse k-NN)
                                                    │                                   │
                                                    └── concat ◄── unpool (nearest) ────┘
                                ─ merge (linear) ─ FCRes×up (C₀, fine) ─ linear ─► ε̂ [V, d]

Every block (``FCResBlock`` in ``jmeshtex/fldm/_blocks.py``, the reference's ``FCEResBlock``) is a linear
(complex dense) residual plus (norm → vector neuron) × ``mlp_layers`` → field convolution →
(norm → VN) × ``mlp_layers`` → field convolution whose filters see, per channel, the processed
timestep (⊕ one-hot label) embedding (eq. 35; the reference's ``FieldConvEmb``). Filters are one- or
two-hidden-layer MLPs of the gauge-invariant argument. The output layer is linear, with no norm or
nonlinearity after the last block: with the linear residuals, the output follows the scale of
``z_t`` (at high noise ε̂ ≈ z_t must be reachable), as in the reference's ``fc_unet_2``.
With ``Config.mask_conditioning`` (inpainting conditioned on the mask, §6.4) the inpainting mask
joins the timestep (and label) embedding as a per-vertex filter input, and the known latents,
masked, enter the lift as ``d`` more tangent channels (``z_t ⊕ m·z_known``). Complex
linear layers have no bias. Every piece is gauge-equivariant, so the denoiser is: rotating every
frame of the input rotates the output by the same angles.

Geometry (:class:`DenoiserGeometry`, built on the host by :func:`denoiser_geometry`): k-NN
neighbourhoods of the input mesh and of one coarser level of :func:`jmeshtex.geometry.mesh_hierarchy`,
and the pooling map between them. Fine frames are those of
:func:`jmeshtex.geometry.one_ring_neighborhood` — the FL-VAE's latent gauge — so latents from
:func:`jmeshtex.fl.encode` go in unchanged. Log maps are divided by the fine level's mean edge
length: the filters see distances in units of the mesh resolution, so sampling a trained model on a
finer mesh gives a smaller texture (textural scale follows resolution, §6.6).
"""

from __future__ import annotations

import functools
import math
from typing import Any, NamedTuple

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._jit import jit_once
from .._mesh import Mesh, as_mesh
from .._neighborhoods import scale_log_maps
from .._types import Array, Bool, Complex, Float, Int, PRNGKey
from ..geometry import (
    PoolingMap,
    VertexNeighborhood,
    knn_from_one_ring,
    mean_edge_length,
    mesh_hierarchy,
    pad_to,
)
from ..nn import ComplexDense
from ..ops import real_dtype, tangent_pool, tangent_unpool
from ._blocks import FCResBlock
from ._config import Config


class DenoiserGeometry(NamedTuple):
    """Frozen geometry of one mesh for the denoiser (a pytree; pad with :func:`pad_geometry`).

    Attributes:
      fine: ``[V₀, k]`` k-NN neighbourhoods of the mesh (frames of ``one_ring_neighborhood``).
      coarse: ``[V₁, k]`` k-NN neighbourhoods of the coarse level.
      pool: :class:`~jmeshtex.PoolingMap` fine → coarse.
    """

    fine: VertexNeighborhood
    coarse: VertexNeighborhood
    pool: PoolingMap

    @property
    def num_vertices(self) -> int:
        return int(np.shape(self.fine.index)[0])


def denoiser_geometry(
    mesh: Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]],
    *,
    knn: int = 9,
    pool_ratio: float = 0.25,
) -> DenoiserGeometry:
    """Host-side k-NN neighbourhoods of the mesh and of one coarse level, and the pooling map.

    Log maps (both levels) are divided by the mean edge length ``h`` of the mesh (unique edges):
    ``log ← log / h`` (module docstring).

    Args:
      mesh: a :class:`~jmeshtex.Mesh` (or a ``(vertices [V, 3], faces [F, 3])`` pair) of manifold
        triangles, open or closed, any genus.
      knn: slots per neighbourhood including the vertex itself.
      pool_ratio: coarse / fine vertex ratio.

    Returns:
      :class:`DenoiserGeometry` of NumPy arrays.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> g = denoiser_geometry(icosphere(2), knn=7, pool_ratio=0.25)
      >>> g.fine.index.shape, g.coarse.index.shape[1], g.pool.parent.shape
      ((162, 7), 7, (162,))
    """
    mesh = as_mesh(mesh)
    vertices, faces = mesh.vertices, mesh.faces
    h = mesh_hierarchy(vertices, faces, levels=2, ratio=pool_ratio)
    scale = mean_edge_length(vertices, faces)
    fine = knn_from_one_ring(h.neighborhoods[0], knn)
    coarse = knn_from_one_ring(h.neighborhoods[1], knn)
    fine = scale_log_maps(fine, scale)  # log maps in mean edges, the unit recorded
    coarse = scale_log_maps(coarse, scale)
    return DenoiserGeometry(fine=fine, coarse=coarse, pool=h.pooling[0])


def geometry_sizes(geo: DenoiserGeometry) -> dict[str, int]:
    """The sizes of a geometry, for bucketing and FLOP counts.

    Returns:
      ``{"V0": fine vertices, "V1": coarse vertices, "M": most fine children of a coarse vertex}``.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> s = geometry_sizes(denoiser_geometry(icosphere(1), knn=5, pool_ratio=0.5))
      >>> s["V0"], 0 < s["V1"] < 42
      (42, True)
    """
    return {
        "V0": int(np.shape(geo.fine.index)[0]),
        "V1": int(np.shape(geo.coarse.index)[0]),
        "M": int(np.shape(geo.pool.children)[1]),
    }


def _round_up(n: int, multiple: int) -> int:
    return -(-int(n) // int(multiple)) * int(multiple)


def _bucketed_vertices(V0: int, V1: int, bucket: int) -> tuple[int, int]:
    """Fine and coarse vertex counts padded for bucketing: ``V0`` up to a multiple of ``bucket``,
    ``V1`` of ``bucket // 4`` (at least 1), so nearby sizes share one compiled program."""
    return _round_up(V0, bucket), _round_up(V1, max(bucket // 4, 1))


def pad_geometry(geo: DenoiserGeometry, *, V0: int, V1: int, M: int) -> DenoiserGeometry:
    """Pad a geometry to static sizes (padding contract: masked slots, vertices, children).

    Example:
      >>> from jmeshtex.data import icosphere
      >>> g = pad_geometry(denoiser_geometry(icosphere(1), knn=5), V0=50, V1=20, M=12)
      >>> g.fine.index.shape, g.coarse.index.shape, g.pool.children.shape
      ((50, 5), (20, 5), (20, 12))
    """
    return DenoiserGeometry(
        fine=pad_to(geo.fine, {"V": V0}),
        coarse=pad_to(geo.coarse, {"V": V1}),
        pool=pad_to(geo.pool, {"Vf": V0, "Vc": V1, "M": M}),
    )


def timestep_embedding(
    t: Int[Array, ""], features: int, *, dtype=jnp.float32
) -> Float[Array, " E"]:
    """Sinusoidal timestep embedding (Vaswani et al. 2017; Ho et al. 2020).

    .. math:: e_{2j} = \\sin(t\\, \\omega_j),\\ e_{2j+1} = \\cos(t\\, \\omega_j),\\
       \\omega_j = 10000^{-j/(E/2)}

    Example:
      >>> timestep_embedding(jnp.array(0), 4).tolist()
      [0.0, 1.0, 0.0, 1.0]
    """
    half = features // 2
    freqs = jnp.exp(-math.log(10000.0) * jnp.arange(half, dtype=dtype) / half)
    arg = jnp.asarray(t).astype(dtype) * freqs
    return jnp.stack([jnp.sin(arg), jnp.cos(arg)], axis=-1).reshape(-1)


class Denoiser(nn.Module):
    """The U-Net as a flax module; use :func:`init_denoiser` / :func:`denoise` (pure functions).

    Attributes:
      config: :class:`Config` (widths, blocks, hdim, mlp_layers, filter_layers, activation,
        time_features, num_labels; ``remat``: every block under :func:`flax.linen.remat`).
      param_dtype: complex dtype of the complex weights.
      argument: filter argument of every field convolution (``"untransported"``: the reference's
        form, for the equivariance harness's negative control only).
    """

    config: Config
    param_dtype: Any = jnp.complex64
    argument: str = "transported"

    @nn.compact
    def __call__(self, z, t, geo: DenoiserGeometry, labels=None, mask=None, known=None):
        cfg = self.config
        c0, c1 = cfg.widths
        rdt = real_dtype(z.dtype)
        width = 4 * c0  # the reference's embedding width (fc_unet_2: 4 x the fine features)
        temb = timestep_embedding(t, cfg.time_features, dtype=rdt)
        per_vertex = []  # per-vertex scalars appended to the filters' embedding input
        if cfg.num_labels:
            per_vertex.append(jax.nn.one_hot(labels, cfg.num_labels, dtype=rdt))
        if cfg.mask_conditioning:
            m = jnp.asarray(mask).astype(rdt)[:, None]
            per_vertex.append(m)
            # the known latents, masked, as d more tangent input channels (equivariant: same frames)
            z = jnp.concatenate([z, jnp.asarray(known).astype(z.dtype) * m.astype(z.dtype)], axis=1)
        if per_vertex:
            v0, v1 = z.shape[0], geo.coarse.index.shape[0]
            cond = jnp.concatenate(per_vertex, axis=1)
            own = jnp.asarray(geo.pool.children)[:, 0]  # each coarse vertex's own fine copy
            emb0 = jnp.concatenate([jnp.broadcast_to(temb, (v0, temb.shape[0])), cond], axis=1)
            emb1 = jnp.concatenate([jnp.broadcast_to(temb, (v1, temb.shape[0])), cond[own]], axis=1)
            emb0, emb1 = (
                _embedding_mlp(e, width, rdt, f"embed_{lvl}") for lvl, e in ((0, emb0), (1, emb1))
            )
        else:
            emb0 = emb1 = _embedding_mlp(temb, width, rdt, "embed")
        block = dict(
            hdim=cfg.hdim,
            mlp_layers=cfg.mlp_layers,
            filter_layers=cfg.filter_layers,
            activation=cfg.activation,
            argument=self.argument,
            invariants=cfg.experimental.invariants,
            param_dtype=self.param_dtype,
        )
        Block = (
            nn.remat(FCResBlock) if cfg.experimental.remat else FCResBlock
        )  # same parameters, recomputed in the backward pass
        h = ComplexDense(c0, self.param_dtype, name="lift")(z)
        for i in range(cfg.blocks[0]):
            h = Block(c0, name=f"down_{i}", **block)(h, geo.fine, emb0)
        skip = h
        h = tangent_pool(h, geo.pool)
        for i in range(cfg.blocks[1]):
            h = Block(c1, name=f"mid_{i}", **block)(h, geo.coarse, emb1)
        h = jnp.concatenate([tangent_unpool(h, geo.pool), skip], axis=1)
        h = ComplexDense(c0, self.param_dtype, name="merge")(h)
        for i in range(cfg.blocks[2]):
            h = Block(c0, name=f"up_{i}", **block)(h, geo.fine, emb0)
        out = ComplexDense(cfg.latent_channels, self.param_dtype, name="out")(
            h
        )  # linear output (no norm, no VN)
        return out * jnp.asarray(geo.fine.vertex_mask).astype(out.dtype)[:, None]


def _embedding_mlp(e, width: int, rdt, prefix: str):
    """``SiLU(SiLU(e W₁ + b₁) W₂ + b₂)``, the reference's shared embedding MLP (per level with labels)."""
    e = jax.nn.silu(nn.Dense(width, dtype=rdt, param_dtype=rdt, name=f"{prefix}_0")(e))
    return jax.nn.silu(nn.Dense(width, dtype=rdt, param_dtype=rdt, name=f"{prefix}_1")(e))


def _check_mask(config: Config, z, mask, known) -> None:
    if config.mask_conditioning and (mask is None or known is None):
        raise InputError(
            "denoiser: the config has mask_conditioning=True; pass mask [V] bool and known [V, d] latents"
        )
    if not config.mask_conditioning and (mask is not None or known is not None):
        raise InputError(
            "denoiser: mask/known given but the config is not mask-conditioned (mask_conditioning=False)"
        )
    if mask is not None and np.shape(mask) != (z.shape[0],):
        raise InputError(f"denoiser: mask must be [V] = ({z.shape[0]},), got {np.shape(mask)}")
    if known is not None and np.shape(known) != z.shape:
        raise InputError(f"denoiser: known must be [V, d] = {z.shape}, got {np.shape(known)}")


def _check_inputs(config: Config, z, geo: DenoiserGeometry, labels) -> None:
    if z.ndim != 2 or not jnp.issubdtype(z.dtype, jnp.complexfloating):
        raise InputError(
            f"denoiser: z must be complex [V, d] (vmap for batches), got {z.dtype} {z.shape}"
        )
    if z.shape[1] != config.latent_channels:
        raise InputError(
            f"denoiser: z has {z.shape[1]} channels, the config says latent_channels={config.latent_channels}"
        )
    if z.shape[0] != np.shape(geo.fine.index)[0]:
        raise InputError(
            f"denoiser: z has {z.shape[0]} vertices, the geometry {np.shape(geo.fine.index)[0]}"
        )
    if config.num_labels and labels is None:
        raise InputError(
            f"denoiser: the config has num_labels={config.num_labels}; pass labels [V] int"
        )
    if not config.num_labels and labels is not None:
        raise InputError("denoiser: labels given but the config is unconditional (num_labels=0)")
    if labels is not None and np.shape(labels) != (z.shape[0],):
        raise InputError(f"denoiser: labels must be [V] = ({z.shape[0]},), got {np.shape(labels)}")


def init_denoiser(
    key: PRNGKey, config: Config, geo: DenoiserGeometry | None = None, *, dtype=jnp.complex64
) -> dict:
    """Random denoiser parameters (a flax ``params`` dict) for ``config``; they fit every geometry.

    ``geo`` is accepted for symmetry with :func:`denoise` but not needed: parameter shapes depend on
    the configuration only, and initialisation runs (jitted once per config and dtype) on a fixed
    small mesh.

    Args:
      key: PRNG key of the initialisation.
      config: the :class:`~jmeshtex.fldm.Config` (architecture fields).
      geo: unused (any geometry, or None).
      dtype: complex dtype of the complex weights.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> cfg = Config.tiny(latent_channels=2)
      >>> params = init_denoiser(jax.random.key(0), cfg)
      >>> sorted(params)
      ['down_0', 'embed_0', 'embed_1', 'lift', 'merge', 'mid_0', 'out', 'up_0']
    """
    del geo  # parameter shapes depend on the config only: initialise on one fixed small mesh
    return _init(key, config.network(), jnp.dtype(dtype))


def _init_geometry(knn: int) -> DenoiserGeometry:
    """The small fixed mesh parameters are initialised on (built when ``_init`` is traced)."""
    from ..data import icosphere

    return denoiser_geometry(icosphere(1), knn=knn, pool_ratio=0.5)


@jit_once(static_argnames=("config", "dtype"))
def _init(key, config: Config, dtype):
    # jitted (eager initialisation dispatches and compiles every small op of every block separately);
    # it runs once
    geo = _as_jax(_init_geometry(config.knn), dtype)
    v = np.shape(geo.fine.index)[0]
    z = jnp.zeros((v, config.latent_channels), dtype)
    labels = jnp.zeros((v,), jnp.int32) if config.num_labels else None
    mask, known = (jnp.zeros((v,), bool), z) if config.mask_conditioning else (None, None)
    return Denoiser(config, param_dtype=dtype).init(
        key, z, jnp.zeros((), jnp.int32), geo, labels, mask, known
    )["params"]


def _as_jax(geo: DenoiserGeometry, cdtype) -> DenoiserGeometry:
    from ..geometry import to_jax

    rdt = real_dtype(jnp.dtype(cdtype))
    return to_jax(geo, rdt)


def denoise(
    params: dict,
    config: Config,
    z_t: Complex[Array, "V d"],
    t: Int[Array, ""],
    geo: DenoiserGeometry,
    *,
    labels: Int[Array, " V"] | None = None,
    mask: Bool[Array, " V"] | None = None,
    known: Complex[Array, "V d"] | None = None,
    filter_argument: str = "transported",
) -> Complex[Array, "V d"]:
    """Predict the noise ``ε̂_θ(z_t, t)`` of tangent latents on one (possibly padded) mesh.

    .. math:: \\hat\\varepsilon = \\mathrm{UNet}_\\theta(z_t;\\ e(t) \\oplus \\mathrm{onehot}(\\ell))

    Equivariant to gauge changes (``z → z e^{-iα}`` gives ``ε̂ → ε̂ e^{-iα}`` with the matching
    geometry), to isometries and relabelling (registered in the harness). Padded vertices output 0
    and never influence real ones.

    Args:
      params: from :func:`init_denoiser` (or training).
      config: the :class:`~jmeshtex.fldm.Config`.
      z_t: ``[V, d]`` noisy latents in the fine frames of ``geo``.
      t: scalar int timestep.
      geo: :class:`DenoiserGeometry` (NumPy or JAX).
      labels: ``[V]`` int labels in ``[0, num_labels)`` when the config is label-guided.
      mask: ``[V]`` bool inpainting mask (True: known) when the config is mask-conditioned
        (``mask_conditioning``): a per-vertex input of every embedding-conditioned filter.
      known: ``[V, d]`` the known (scaled, clean) latents of a mask-conditioned config, in the
        frames of ``z_t``; the denoiser reads ``known · mask`` as ``d`` extra input channels.
      filter_argument: ``"transported"`` (default, gauge-equivariant) or ``"untransported"``: the
        reference code's filter argument (``get_rel_pos``: the log map paired with the neighbour's
        feature direction in the neighbour's own frame), which is **not** gauge-equivariant with
        these log maps; it exists for the equivariance harness's negative control
        (``fldm.denoiser_reference_argument``).

    Returns:
      ``[V, d]`` predicted noise (or ``v̂`` for a v-prediction config), dtype of ``z_t``.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> cfg = Config.tiny(latent_channels=2)
      >>> geo = denoiser_geometry(icosphere(1), knn=cfg.knn)
      >>> params = init_denoiser(jax.random.key(0), cfg, geo)
      >>> z = jnp.ones((42, 2), jnp.complex64)
      >>> denoise(params, cfg, z, jnp.array(10), geo).shape
      (42, 2)
    """
    _check_inputs(config, z_t, geo, labels)
    _check_mask(config, z_t, mask, known)
    geo = _as_jax(geo, z_t.dtype)
    return _apply(
        params,
        config.network(),
        z_t,
        jnp.asarray(t, jnp.int32),
        geo,
        labels,
        mask,
        known,
        filter_argument,
    )


@functools.partial(jax.jit, static_argnames=("config", "argument"))
def _apply(params, config, z_t, t, geo, labels, mask=None, known=None, argument="transported"):
    # jitted once per config and shapes (eager use would dispatch every small op separately)
    return Denoiser(config, param_dtype=z_t.dtype, argument=argument).apply(
        {"params": params}, z_t, t, geo, labels, mask, known
    )


def denoiser_flops(config: Config, v0: int, v1: int) -> float:
    """Approximate real FLOPs of one denoiser evaluation (multiply-adds × 2; complex × 4).

    Counts the field convolutions' filter responses (first layer ``V·k·C·H``, second hidden layer
    ``V·k·C·H²``), slot sums (``V·k·C·H``) and complex mixes (``V·C·H·D``), the vector neurons'
    two complex dense layers per ``mlp_layers``, the residual, lift, merge and output layers; norms
    and pooling are lower order.

    Args:
      config: the :class:`~jmeshtex.fldm.Config` (widths, blocks, knn, hdim, mlp_layers, filter_layers, latent_channels).
      v0: fine vertices (``geometry_sizes(geo)["V0"]``).
      v1: coarse vertices (``geometry_sizes(geo)["V1"]``).

    Example:
      >>> f = denoiser_flops(Config.paper(), 30000, 7500)
      >>> 1e10 < f < 1e13
      True
    """
    c0, c1 = config.widths
    k, h = config.knn, config.hdim

    def conv(v, c, d):
        filt = v * k * c * h * 2 * 2  # filter pre-activation (2 inputs) per slot/channel/response
        if config.filter_layers == 2:
            filt += v * k * c * h * h * 2  # the second hidden layer
        sums = (
            v * k * c * h * 2 * 2
        )  # complex feature × real response, accumulated: 2 multiply-adds
        mix = v * c * h * d * 8  # complex matmul
        return filt + sums + mix

    def mlp(
        v, c, d
    ):  # (norm → VN) × mlp_layers; the first maps c → d, each VN has two dense layers
        return 2 * 8 * v * (c * d + (config.mlp_layers - 1) * d * d)

    def block(v, c, d):
        return v * c * d * 8 + mlp(v, c, d) + conv(v, d, d) + mlp(v, d, d) + conv(v, d, d)

    total = (
        8 * v0 * config.latent_channels * (2 if config.mask_conditioning else 1) * c0
    )  # lift (+ known)
    total += sum(block(v0, c0, c0) for _ in range(config.blocks[0]))
    total += block(v1, c0, c1) + sum(block(v1, c1, c1) for _ in range(config.blocks[1] - 1))
    total += 8 * v0 * (c1 + c0) * c0  # merge
    total += sum(block(v0, c0, c0) for _ in range(config.blocks[2]))
    total += 8 * v0 * c0 * config.latent_channels
    return float(total)


def denoiser_activations(config: Config, v0: int, v1: int) -> float:
    """Filter activations evaluated by one denoiser evaluation: ``Σ_conv V·k·C_in·H·filter_layers``.

    Every field convolution evaluates its filter nonlinearity once per vertex, slot, input channel,
    response and hidden layer; :func:`denoiser_flops` counts the multiply-adds around it but not the
    activation itself (a SiLU is an exponential and a division).

    Args:
      config: the :class:`~jmeshtex.fldm.Config`.
      v0: fine vertices.
      v1: coarse vertices.

    Example:
      >>> n = denoiser_activations(Config.paper(), 30000, 7500)
      >>> round(n / 1e9, 2)  # G evaluations
      11.8
    """
    c0, c1 = config.widths
    per = config.knn * config.hdim * config.filter_layers
    fine = (
        (config.blocks[0] + config.blocks[2]) * 2 * c0
    )  # every convolution acts on the block's width
    coarse = config.blocks[1] * 2 * c1
    return float(per * (v0 * fine + v1 * coarse))

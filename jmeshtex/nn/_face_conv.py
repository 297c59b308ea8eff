"""Flax wrapper of the DGTS face-convolution network (Hertz et al. 2020, §3.2)."""

from __future__ import annotations

from collections.abc import Sequence

import flax.linen as nn
import jax.numpy as jnp

from .._neighborhoods import FaceNeighborhood
from .._types import Array, Float
from ..ops import FaceConvStackParams, face_conv_stack, init_face_conv_stack


class FaceConvStack(nn.Module):
    """Embedding layer, then face convolutions with instance norm and leaky ReLU in between.

    A thin module: it only creates one parameter, ``"stack"``, a
    :class:`~jmeshtex.ops.FaceConvStackParams` NamedTuple (initialised by
    :func:`~jmeshtex.ops.init_face_conv_stack`), and calls :func:`~jmeshtex.ops.face_conv_stack`.
    ``variables["params"]["stack"]`` can be passed to the op directly, without flax.

    Attributes:
      features: output width of each layer; ``features[0]`` is the embedding, every further entry
        one face convolution (DGTS's generator ends with 3, the displacement coefficients).
      negative_slope: leaky-ReLU slope (0.2 in DGTS).
      eps: instance-norm regulariser.
      param_dtype: dtype of the created parameters (the op casts them to the input's dtype).

    Example:
      >>> import jax, numpy as np
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.geometry import face_neighborhood
      >>> from jmeshtex.ops import face_features
      >>> v, f = icosahedron()
      >>> nb = face_neighborhood(f)
      >>> x = face_features(jnp.asarray(v, jnp.float32), nb)
      >>> model = FaceConvStack((16, 16, 3))
      >>> variables = jax.jit(model.init)(jax.random.key(0), x, nb)
      >>> jax.jit(model.apply)(variables, x, nb).shape
      (20, 3)
    """

    features: Sequence[int]
    negative_slope: float = 0.2
    eps: float = 1e-5
    param_dtype: jnp.dtype = jnp.float32

    @nn.compact
    def __call__(self, x: Float[Array, "F 3 E"], nbhd: FaceNeighborhood) -> Float[Array, "F D"]:
        params: FaceConvStackParams = self.param(
            "stack",
            lambda key: init_face_conv_stack(
                key, self.features, in_features=x.shape[-1], dtype=self.param_dtype
            ),
        )
        return face_conv_stack(x, nbhd, params, negative_slope=self.negative_slope, eps=self.eps)

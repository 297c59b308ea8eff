"""Complex linear layer without bias (Mitchel, Esteves, Makadia, CVPR 2024, supplement §9).

A tangent feature is one complex number per vertex and channel, in that vertex's frame (docs/concepts.md); a
gauge change rotates all channels of a vertex together, ``x → x e^{-iα}``, and a complex-linear map
without bias commutes with it.
"""

import jax.numpy as jnp

from .._errors import InputError
from .._types import Array, ArrayLike, Complex, PRNGKey
from ._complex_init import complex_lecun_blocks
from ._numerics import check_complex, check_size, complex_matmul


def init_complex_linear(
    key: PRNGKey, in_features: int, out_features: int, *, dtype=jnp.complex64
) -> Complex[Array, "C D"]:
    """Weights ``[in_features, out_features]`` for :func:`complex_linear` (:func:`complex_lecun_normal`).

    Example:
      >>> import jax
      >>> jax.eval_shape(lambda key: init_complex_linear(key, 3, 5), jax.random.key(0)).shape
      (3, 5)
    """
    for name, value in (("in_features", in_features), ("out_features", out_features)):
        check_size(value, name, "init_complex_linear")
    return complex_lecun_blocks(
        key,
        [((in_features, out_features), in_features)],
        dtype=dtype,
        where="init_complex_linear",
    )[0]


# --------------------------------------------------------------------------------- linear layer


def complex_linear(
    x: Complex[ArrayLike, "... C"], w: Complex[ArrayLike, "C D"]
) -> Complex[Array, "... D"]:
    """Complex linear layer without bias: ``y = x W``.

    .. math:: y_d = \\sum_c x_c\\, W_{cd}

    There is deliberately no bias: ``(x e^{-iα}) W = (x W) e^{-iα}``, whereas a bias ``b`` would stay
    put when the frame rotates and break gauge equivariance.

    Args:
      x: ``[..., C]`` complex tangent features (any leading axes), each in its vertex's frame.
      w: ``[C, D]`` complex weights (cast to ``x``'s dtype).

    Returns:
      ``[..., D]`` complex, same frames and dtype as ``x``.

    Example:
      >>> x = jnp.array([[1j, 1.0]], jnp.complex64)
      >>> complex_linear(x, jnp.array([[1.0], [1j]], jnp.complex64)).tolist()
      [[2j]]
    """
    check_complex(x, "complex_linear")
    if jnp.ndim(w) != 2 or w.shape[0] != x.shape[-1]:
        raise InputError(
            f"complex_linear: x has {x.shape[-1]} channels but w has shape {jnp.shape(w)}; "
            "w must be [C, D] with C = x.shape[-1]"
        )
    return complex_matmul(x, w)

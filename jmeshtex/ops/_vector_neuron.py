"""Vector-neuron nonlinearity for complex tangent features (CVPR 2024 supplement eq. 19).

It looks only at rotation invariants (``Re(q k̄)``, ``|k|²``) to decide how much of a learned
direction to remove, so it commutes with a common rotation of the channels.
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp

from .._errors import InputError
from .._types import Array, ArrayLike, Complex, PRNGKey
from ._complex_init import complex_lecun_blocks
from ._complex_linear import complex_linear
from ._numerics import abs2, check_complex, check_delta, check_size


class VNParams(NamedTuple):
    """Parameters of :func:`vn_nonlinearity`.

    Attributes:
      weight: ``[C, D]`` complex map to the features ``q = x W``; ``None`` means ``q = x`` (then
        ``D = C``).
      direction: ``[C, D]`` complex map to the learned directions ``k = x U``.
    """

    weight: Complex[ArrayLike, "C D"] | None
    direction: Complex[ArrayLike, "C D"]


def init_vn(
    key: PRNGKey, in_features: int, out_features: int | None = None, *, dtype=jnp.complex64
) -> VNParams:
    """Random :class:`VNParams` (complex LeCun normal).

    Training: the weights are complex; put :func:`jmeshtex.optim.complex_steepest` first in the
    optax chain (``optax.chain(complex_steepest(), optax.adam(lr))``), or plain optax moves the
    imaginary parts uphill.

    Args:
      key: PRNG key.
      in_features: ``C``.
      out_features: ``D``; ``None`` gives the residual form ``q = x`` (``weight=None``, ``D = C``).
      dtype: complex dtype of the weights.

    Example:
      >>> p = jax.eval_shape(lambda key: init_vn(key, 4, 6), jax.random.key(0))
      >>> p.weight.shape, p.direction.shape, init_vn(jax.random.key(0), 4).weight is None
      ((4, 6), (4, 6), True)
    """
    check_size(in_features, "in_features", "init_vn")
    if out_features is not None:
        check_size(out_features, "out_features", "init_vn")
    out = in_features if out_features is None else out_features
    spec = ((in_features, out), in_features)
    if out_features is None:
        return VNParams(
            weight=None,
            direction=complex_lecun_blocks(key, [spec], dtype=dtype, where="init_vn")[0],
        )
    weight, direction = complex_lecun_blocks(key, [spec, spec], dtype=dtype, where="init_vn")
    return VNParams(weight=weight, direction=direction)


def vn_nonlinearity(
    x: Complex[ArrayLike, "... C"], params: VNParams, *, delta: float = 1e-6
) -> Complex[Array, "... D"]:
    """Vector-neuron nonlinearity for tangent features (2024 supplement eq. 19; Deng et al. 2021).

    With ``q = x W`` (or ``q = x``) and ``k = x U``, per output channel:

    .. math:: y = q + \\frac{\\mathrm{SiLU}\\big(-\\langle q, k\\rangle\\big)}{|k|^2 + \\delta}\\, k,
       \\qquad \\langle q, k\\rangle = \\mathrm{Re}(q\\,\\bar k)

    For ``⟨q, k⟩ ≫ 0`` this is ``y ≈ q``; for ``⟨q, k⟩ ≪ 0`` it is ``y ≈ q − ⟨q,k⟩ k/|k|²``, the
    projection of ``q`` onto the half-plane ``⟨y, k⟩ ≥ 0`` (the vector-neuron ReLU), with SiLU as a
    smooth switch between the two. ``⟨q, k⟩`` and ``|k|²`` are invariant to a common rotation of the
    channels, so ``x → x e^{iα}`` gives ``y → y e^{iα}``. ``δ > 0`` keeps the value and gradient finite
    at ``k = 0`` (where ``y = q``), in particular at ``x = 0`` (where ``y = 0``).

    Args:
      x: ``[..., C]`` complex tangent features.
      params: :class:`VNParams` (cast to ``x``'s dtype).
      delta: ``δ > 0`` in the denominator.

    Returns:
      ``[..., D]`` complex, in the same frames as ``x``.

    Example:
      >>> p = VNParams(weight=None, direction=jnp.eye(1, dtype=jnp.complex64))  # k = q = x
      >>> y = vn_nonlinearity(jnp.array([[2 + 0j], [-2 + 0j]], jnp.complex64), p)
      >>> y.real.round(4).tolist()  # coefficient SiLU(-4)/4 = -sigmoid(-4): x shrinks by 1.8 %
      [[1.964], [-1.964]]
    """
    check_complex(x, "vn_nonlinearity")
    delta = check_delta(delta, "vn_nonlinearity")
    c = x.shape[-1]
    if params.weight is None:
        q = x
        if params.direction.shape[-1] != c:
            raise InputError(
                f"vn_nonlinearity: with weight=None the output has C = {c} channels, but direction has "
                f"shape {params.direction.shape}; pass a weight [C, D] or a direction [C, C]"
            )
    else:
        if params.weight.shape[-1] != params.direction.shape[-1]:
            raise InputError(
                f"vn_nonlinearity: weight {params.weight.shape} and direction {params.direction.shape} "
                "must have the same output width D"
            )
        q = complex_linear(x, params.weight)
    k = complex_linear(x, params.direction)
    dot = q.real * k.real + q.imag * k.imag
    coef = jax.nn.silu(-dot) / (abs2(k) + jnp.asarray(delta, dot.dtype))
    return jax.lax.complex(q.real + coef * k.real, q.imag + coef * k.imag)

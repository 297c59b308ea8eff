"""Gaussian noise in the tangent bundle (Mitchel, Esteves, Makadia, CVPR 2024, eq. 1).

The forward diffusion process of a field-latent diffusion model adds noise to tangent-vector latents.
For the process to be intrinsic the noise distribution must not depend on the (arbitrary) frame at
each vertex: a circularly-symmetric complex Gaussian has exactly this property, because rotating
``a + ib`` with ``a, b`` i.i.d. centred Gaussians gives again i.i.d. centred Gaussians.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp

from .._errors import InputError
from .._types import Array, Complex, PRNGKey
from ._numerics import check_key


def tangent_noise(
    key: PRNGKey, shape: Sequence[int], *, dtype=jnp.complex64
) -> Complex[Array, "..."]:
    """Standard circular complex Gaussian noise: one tangent vector per vertex and channel (eq. 1).

    .. math:: \\varepsilon = \\frac{a + i b}{\\sqrt 2}, \\qquad a, b \\sim \\mathcal N(0, 1)
       \\text{ i.i.d. per vertex and channel}

    Variance convention: ``E|ε|² = 1`` (each of the real and imaginary parts has variance ½) and
    ``E[ε²] = 0``; as a 2D tangent vector, ``ε`` has covariance ``½ I``. The density depends on
    ``|ε|`` only, so ``ε e^{iα}`` has the same distribution for every (vertex-dependent) frame
    rotation ``α``: the noise is the same in every gauge. Use it as ``x_t = √ᾱ_t x_0 + √(1-ᾱ_t) ε``
    with the latents scaled to ``E|x_0|² = 1``.

    Args:
      key: PRNG key.
      shape: output shape, typically ``(V, C)``.
      dtype: ``complex64`` (default) or ``complex128`` (needs ``jax_enable_x64``).

    Returns:
      Complex array of ``shape`` and ``dtype``; deterministic given ``key``.

    Example:
      >>> eps = tangent_noise(jax.random.key(0), (20000, 4))
      >>> eps.dtype, round(float(jnp.mean(jnp.abs(eps) ** 2)), 1), round(abs(complex(jnp.mean(eps**2))), 1)
      (dtype('complex64'), 1.0, 0.0)
    """
    check_key(key, "tangent_noise")
    dtype = jnp.dtype(dtype)
    if not jnp.issubdtype(dtype, jnp.complexfloating):
        raise InputError(
            f"tangent_noise: dtype must be complex64 or complex128 (a tangent vector is a complex "
            f"number), got {dtype}"
        )
    shape = tuple(int(s) for s in shape)
    if any(s < 0 for s in shape):
        raise InputError(f"tangent_noise: shape must be non-negative, got {shape}")
    # jax.random.normal for a complex dtype draws real and imaginary parts with variance 1/2 each,
    # which is exactly (a + ib)/√2 with a, b ~ N(0, 1).
    return jax.random.normal(key, shape, dtype)

"""Complex LeCun-normal initialisation for the tangent-feature layers (circular Gaussian weights).

Every ``init_*`` function of :mod:`jmeshtex.ops` draws its numbers through :func:`complex_lecun_blocks`:
one ``jax.random`` draw cut into blocks, since each generator call costs compile time.
"""

import math

import jax
import jax.numpy as jnp

from .._config import is_int
from .._errors import InputError
from .._types import Array, PRNGKey
from ._numerics import check_key, check_size, complex_dtype, real_dtype


def complex_lecun_normal(
    key: PRNGKey, shape: tuple[int, ...], *, fan_in: int, dtype=jnp.complex64
) -> Array:
    """Circular complex Gaussian weights with ``E|w|² = 1/fan_in`` (complex LeCun normal).

    .. math:: w = \\frac{a + i b}{\\sqrt{2\\,\\mathrm{fan\\_in}}}, \\qquad a, b \\sim \\mathcal N(0, 1)

    The phase is uniform and independent of the modulus (Rayleigh distributed), so the distribution
    is invariant to rotations ``w → w e^{iα}``; a linear layer with these weights maps inputs with
    ``E|x_c|² = 1`` to outputs with ``E|y_d|² = 1``.

    Args:
      key: PRNG key.
      shape: weight shape.
      fan_in: number of inputs summed into each output.
      dtype: ``complex64`` or ``complex128``.

    Raises:
      InputError: ``key`` is not a PRNG key, ``shape`` has a negative or non-integer entry, or
        ``fan_in`` is not a positive integer.

    Example:
      >>> w = complex_lecun_normal(jax.random.key(0), (256, 512), fan_in=256)
      >>> round(float(jnp.mean(jnp.abs(w) ** 2) * 256), 1)
      1.0
    """
    return complex_lecun_blocks(key, [(shape, fan_in)], dtype=dtype, where="complex_lecun_normal")[
        0
    ]


def normal_blocks(key: PRNGKey, shapes, dtype) -> list[Array]:
    """Standard normal arrays of the given shapes, cut from **one** draw.

    Every ``jax.random`` call adds its own generator to the compiled program (~0.5 s of XLA:CPU
    compile time each), so the ``init_*`` functions draw all their numbers at once.
    """
    sizes = [math.prod(s) for s in shapes]
    flat = jax.random.normal(key, (sum(sizes),), dtype)
    out, start = [], 0
    for shape, n in zip(shapes, sizes, strict=False):
        out.append(flat[start : start + n].reshape(shape))
        start += n
    return out


def complex_lecun_blocks(
    key: PRNGKey, specs, *, dtype=jnp.complex64, extra_real=(), where: str = "init"
) -> list[Array]:
    """Complex LeCun-normal arrays for ``specs = [(shape, fan_in), ...]`` (then standard normal real
    arrays of the shapes in ``extra_real``), all from one draw. Bad keys, shapes or fans raise
    :class:`~jmeshtex.InputError` naming ``where`` (static checks: nothing is read from a device)."""
    check_key(key, where)
    for shape, fan_in in specs:
        _check_shape(shape, where)
        check_size(fan_in, "fan_in", where)
    dtype = complex_dtype(dtype)
    rdt = real_dtype(dtype)
    blocks = normal_blocks(key, [(2, *shape) for shape, _ in specs] + list(extra_real), rdt)
    out = [
        jax.lax.complex(b[0], b[1]) * jnp.asarray(1.0 / math.sqrt(2.0 * fan_in), rdt).astype(dtype)
        for b, (_, fan_in) in zip(blocks, specs, strict=False)
    ]
    return out + blocks[len(specs) :]


def _check_shape(shape, where: str) -> None:
    try:
        dims = tuple(shape)
    except TypeError:
        dims = None
    if dims is None or not all(is_int(d, 0) for d in dims):
        raise InputError(
            f"{where}: weight shape must be a tuple of integers >= 0 (layer widths), got {shape!r}"
        )

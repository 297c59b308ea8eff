"""Property tests of jitted mesh code that stay fast: a hypothesis profile and shape buckets.

Every new mesh size is a new XLA compilation (seconds on CPU), so hypothesis's default deadline
(200 ms per example) fails and each example recompiles. Padding every drawn mesh to the next power
of two of its sizes (the padding contract makes padded slots inert) lets all examples of a bucket
share one compilation; the profile turns the deadline off and keeps the example count modest.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np
from hypothesis import HealthCheck, settings

from .._config import is_int
from .._errors import InputError
from .._neighborhoods import _AXES, pad_to

T = TypeVar("T")

#: name of the profile :func:`hypothesis_profile` registers
PROFILE = "jmeshtex"


def hypothesis_profile(*, max_examples: int = 20, load: bool = True) -> settings:
    """Register (and by default load) the ``"jmeshtex"`` hypothesis profile for jitted mesh code.

    No deadline (the first example of a shape compiles), the health checks that time slow data
    generation suppressed, failing examples printed as reproducible blobs.

    Args:
      max_examples: examples per test (hypothesis's default is 100; each new bucket compiles).
      load: make it the active profile (``settings.load_profile``).

    Returns:
      The registered ``settings`` (usable as a decorator too).

    Example:
      >>> hypothesis_profile(max_examples=5, load=False).deadline is None
      True
    """
    if not is_int(max_examples, 1):
        raise InputError(
            f"hypothesis_profile: max_examples must be ≥ 1 (an integer), got {max_examples!r}"
        )
    settings.register_profile(
        PROFILE,
        max_examples=int(max_examples),
        deadline=None,
        print_blob=True,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )
    if load:
        settings.load_profile(PROFILE)
    return settings.get_profile(PROFILE)


def bucket(n: int, minimum: int = 8) -> int:
    """The smallest power of two ≥ ``n`` and ≥ ``minimum``: the static size to pad ``n`` to.

    Example:
      >>> [bucket(n) for n in (1, 8, 9, 42, 64, 65)]
      [8, 8, 16, 64, 64, 128]
    """
    for name, value in (("n", n), ("minimum", minimum)):
        if not is_int(value, 0):
            raise InputError(f"bucket: {name} must be a non-negative integer, got {value!r}")
    return 1 << (max(int(n), int(minimum), 1) - 1).bit_length()


def pad_to_bucket(tree: T, minimum: int = 8) -> T:
    """Pad a neighbourhood pytree (``VertexNeighborhood``, ``FaceNeighborhood``, ...) to buckets.

    Every named axis (vertices ``V``, faces ``F``, slots ``K``, ...) is padded to :func:`bucket` of
    its size with :func:`~jmeshtex.pad_to` (masks False, weights 0: the padded slots contribute
    nothing). Pad per-vertex inputs to the same ``V`` with :func:`pad_rows`, and drop the padded
    rows of outputs with ``out[:num_vertices]``.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.geometry import one_ring_neighborhood
      >>> nb = pad_to_bucket(one_ring_neighborhood(*icosphere(1)))
      >>> nb.index.shape, int(nb.vertex_mask.sum())
      ((64, 8), 42)
    """
    name = type(tree).__name__
    if name not in _AXES:
        raise InputError(
            f"pad_to_bucket: {name} is not a neighbourhood pytree; known: {sorted(_AXES)}"
        )
    sizes: dict[str, int] = {}
    for field, axes in _AXES[name].items():
        leaf = getattr(tree, field)
        if leaf is None:
            continue
        for axis, size in zip(axes, np.shape(leaf), strict=False):
            sizes[axis] = max(sizes.get(axis, 0), bucket(size, minimum))
    return pad_to(tree, sizes)


def pad_rows(x, n: int):
    """Pad the leading axis of ``x`` with zeros to ``n`` rows (NumPy or JAX following the input).

    Example:
      >>> pad_rows(np.ones((3, 2)), 4).tolist()
      [[1.0, 1.0], [1.0, 1.0], [1.0, 1.0], [0.0, 0.0]]
    """
    if n < x.shape[0]:
        raise InputError(f"pad_rows: cannot shrink {x.shape[0]} rows to {n}")
    widths = [(0, n - x.shape[0])] + [(0, 0)] * (x.ndim - 1)
    if isinstance(x, np.ndarray):
        return np.pad(x, widths)
    import jax.numpy as jnp

    return jnp.pad(x, widths)

"""Random tangent-vector features and vertex neighbourhoods for the tests of complex ops and layers
(`tests/ops`, `tests/nn`), written once: host NumPy, float64/complex128, padded slots per the
contract (index 0, zero weight, ``False`` mask, zero log, unit transport)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from jmeshtex.geometry import VertexNeighborhood
from jmeshtex.ops import FieldConvParams


def crandn(rng: np.random.Generator, *shape: int) -> np.ndarray:
    """Complex standard normal samples (real and imaginary parts each N(0, 1))."""
    return rng.standard_normal(shape) + 1j * rng.standard_normal(shape)


def rel_err(a, b) -> float:
    """‖a − b‖ / ‖b‖ over all entries."""
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(np.asarray(b)))


def silu(t):
    """x·sigmoid(x) in NumPy (the filters' default activation)."""
    return t / (1 + np.exp(-t))


def random_nbhd(
    rng: np.random.Generator, v: int, k: int, *, self_slot: bool = True, p_pad: float = 0.3
) -> VertexNeighborhood:
    """A valid random k-NN-like neighbourhood of ``v`` vertices and ``k`` slots, about ``p_pad`` of
    them padded; slot 0 is always live, and with ``self_slot`` it is the vertex itself (zero log,
    unit transport)."""
    index = rng.integers(0, v, (v, k))
    mask = rng.random((v, k)) > p_pad
    log = rng.uniform(0.2, 1.0, (v, k)) * np.exp(1j * rng.uniform(-np.pi, np.pi, (v, k)))
    transport = np.exp(1j * rng.uniform(-np.pi, np.pi, (v, k)))
    weight = rng.uniform(0.5, 1.5, (v, k))
    if self_slot:
        index[:, 0], log[:, 0], transport[:, 0] = np.arange(v), 0, 1
    mask[:, 0] = True
    index, log, transport, weight = (
        np.where(mask, a, pad) for a, pad in ((index, 0), (log, 0), (transport, 1), (weight, 0))
    )
    return VertexNeighborhood(
        index=index.astype(np.int32),
        mask=mask,
        log=log,
        transport=transport,
        weight=weight,
        area=rng.uniform(0.5, 1.5, v),
        vertex_mask=np.ones(v, bool),
    )


def gauge_transform(x, nb: VertexNeighborhood, alpha: np.ndarray):
    """Rotate every frame p by alpha_p: features and logs by e^{-iα_p}, transports by
    e^{i(α_q − α_p)}. Returns the transformed ``(x, nb)``."""
    rot = np.exp(-1j * alpha)
    return x * rot[:, None], nb._replace(
        log=nb.log * rot[:, None],
        transport=nb.transport * np.exp(1j * (alpha[nb.index] - alpha[:, None])),
    )


def field_conv_params(seed: int, *, e: int, c: int, d: int, h: int, dtype) -> FieldConvParams:
    """NumPy field-convolution parameters distributed like ``init_field_conv`` (no compilation):
    ``e`` embedding channels, ``c`` → ``d`` channels, ``h`` filter responses; complex ``dtype``
    (``complex128`` or ``complex64``, the filter weights in the matching real dtype)."""
    rng = np.random.default_rng(seed)
    real = np.float64 if dtype == jnp.complex128 else np.float32
    return FieldConvParams(
        filter_weight=(rng.standard_normal((2 + e, h)) / np.sqrt(2 + e)).astype(real),
        filter_bias=rng.standard_normal(h).astype(real),
        mix=(crandn(rng, c, h, d) / np.sqrt(2 * c * h)).astype(dtype),
    )

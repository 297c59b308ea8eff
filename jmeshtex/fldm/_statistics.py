"""Decoder-free statistics of a latent field: what a denoiser has learnt, read off its samples.

The FL-VAE latents ``z [V, d]`` are tangent vectors in per-vertex frames. Their common phase at a
vertex is gauge- and sampling-dependent, so the texture lives in gauge-invariant quantities:

- **cross-channel relative-phase concentration** ``R`` (pointwise structure): the relative phasor
  of two channels at a vertex, ``u_{v,cc'} = z_{vc} conj(z_{vc'}) / |z_{vc} z_{vc'}|``, is
  invariant under a rotation of the vertex's frame; its mean over real vertices ``m_{cc'}`` has
  length 1 when the relative phase is the same everywhere and about ``1/sqrt(V)`` when it is
  random. ``R`` is the (channel-weighted) mean of ``|m_{cc'}|`` over pairs ``c < c'``. Its
  per-vertex form ``r_v = mean_pairs Re(u_{v,cc'} conj(m_{cc'}) / |m_{cc'}|)`` averages to ``R``
  exactly (:func:`pointwise_concentration`);
- **neighbour correlation of |z|²** (spatial structure): the channel energies
  ``e_{vc} = |z_{vc}|²``, standardised per channel over real vertices, correlated over the
  neighbourhood pairs ``(p, q)``, ``q ≠ p``, of a k-NN :class:`~jmeshtex.VertexNeighborhood`;
  magnitudes need no transport. About 0 for latents shuffled over vertices;
- **transported phase coherence**: ``Re Σ z_p · conj(ρ_{q→p} z_q) / Σ |z_p||z_q|`` over the same
  pairs (``ρ`` the neighbourhood's transport): whether neighbouring vectors agree in direction.

:func:`latent_statistics` returns all three (and the channels' power) as one dict of scalars;
:func:`region_statistics` gives ``R`` and the mean energy per region of a labelling;
:func:`energy_field_correlation` compares two energy fields on the same vertices (the
nearest-training-copy check). Baselines with the same marginals: :func:`shuffle_latents` (no spatial
structure) and :func:`random_channel_phases` (no cross-channel phase structure). All statistics are
pure, jitted functions of arrays; padding (``vertex_mask`` False) is ignored.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError

_TINY = 1e-20


def _standard(fn):
    """Run ``fn`` under JAX's standard dtype promotion (the callers mix complex and real arrays)."""

    @functools.wraps(fn)
    def wrapped(*args, **kwargs):
        with jax.numpy_dtype_promotion("standard"):
            return fn(*args, **kwargs)

    return wrapped


def _check_latents(z, what: str = "z") -> None:
    shape = getattr(z, "shape", None)
    if shape is None or len(shape) != 2 or not jnp.iscomplexobj(z):
        raise InputError(
            f"{what} must be complex latents [V, d], got {getattr(z, 'dtype', type(z))} {shape}; "
            "pass one field at a time (vmap over a batch)"
        )


def _vmask(z, vertex_mask):
    if vertex_mask is None:
        return jnp.ones(z.shape[0], bool)
    if vertex_mask.shape != z.shape[:1]:
        raise InputError(f"vertex_mask must be [V] = ({z.shape[0]},), got {vertex_mask.shape}")
    return vertex_mask.astype(bool)


def _pairs(d: int) -> tuple[np.ndarray, np.ndarray]:
    a, b = np.triu_indices(d, k=1)
    return a, b


def _pair_weights(d: int, channel_weight) -> jax.Array:
    a, b = _pairs(d)
    if channel_weight is None:
        return jnp.ones(len(a))
    w = jnp.asarray(channel_weight, jnp.float32)
    if w.shape != (d,):
        raise InputError(f"channel_weight must be [d] = ({d},), got {w.shape}")
    return w[a] * w[b]


def _relative_phasors(z):
    a, b = _pairs(z.shape[1])
    p = z[:, a] * jnp.conj(z[:, b])
    return p / jnp.maximum(jnp.abs(p), _TINY)


@jax.jit
@_standard
def _mean_phasors(z, vmask):
    u = _relative_phasors(z)
    w = vmask.astype(u.real.dtype)[:, None]
    return jnp.sum(u * w, axis=0) / jnp.maximum(jnp.sum(w), 1.0)


@_standard
def relative_phase_concentration(z, vertex_mask=None, *, channel_weight=None) -> jax.Array:
    """Cross-channel relative-phase concentration ``R`` in [0, 1] (module docstring).

    Args:
      z: ``[V, d]`` complex latents (``d ≥ 2``).
      vertex_mask: ``[V]`` True for real vertices (None: all).
      channel_weight: ``[d]`` non-negative weights (pair ``(c, c')`` weighs ``w_c w_c'``; e.g. 0 for
        channels the FL-VAE left collapsed); None: all pairs equal.

    Returns:
      A scalar, 1 when every vertex has the same relative phases, about ``1/sqrt(V)`` when they are
      random.

    Example:
      >>> z = jnp.asarray(np.exp(1j * np.arange(4.0))[:, None] * np.array([[1.0, 1j]]))
      >>> round(float(relative_phase_concentration(z)), 6)
      1.0
    """
    _check_latents(z)
    if z.shape[1] < 2:
        raise InputError(f"relative_phase_concentration needs d >= 2 channels, got {z.shape[1]}")
    m = _mean_phasors(z, _vmask(z, vertex_mask))
    w = _pair_weights(z.shape[1], channel_weight)
    return jnp.sum(w * jnp.abs(m)) / jnp.maximum(jnp.sum(w), _TINY)


@_standard
def pointwise_concentration(z, vertex_mask=None, *, reference=None) -> jax.Array:
    """Per-vertex agreement ``r_v`` of the relative phases with their pooled mean direction.

    ``r_v = mean over pairs of Re(u_{v,cc'} · conj(m̂_{cc'}))``, ``m̂`` the unit mean phasor of
    ``reference`` (default: of ``z`` itself, over its real vertices). With the default reference
    the mean of ``r_v`` over real vertices equals :func:`relative_phase_concentration`.

    Args:
      z: ``[V, d]`` complex latents.
      vertex_mask: ``[V]`` True for real vertices (None: all).
      reference: ``[d(d−1)/2]`` mean phasors of another field (``pair_mean_phasors``), e.g. the
        exemplar's, to ask whether samples have the exemplar's relative phases.

    Returns:
      ``[V]`` in [−1, 1]; 0 on padding.

    Example:
      >>> z = jnp.array([[1.0, 1.0], [1.0, -1.0]], complex)
      >>> pointwise_concentration(z, reference=pair_mean_phasors(z[:1])).tolist()
      [1.0, -1.0]
    """
    _check_latents(z)
    vmask = _vmask(z, vertex_mask)
    m = _mean_phasors(z, vmask) if reference is None else jnp.asarray(reference)
    return _pointwise(z, vmask, m)


@jax.jit
@_standard
def _pointwise(z, vmask, m):
    u = _relative_phasors(z)
    mhat = m / jnp.maximum(jnp.abs(m), _TINY)
    r = jnp.mean(jnp.real(u * jnp.conj(mhat)), axis=1)
    return jnp.where(vmask, r, 0.0)


@_standard
def pair_mean_phasors(z, vertex_mask=None) -> jax.Array:
    """``[d(d−1)/2]`` complex mean relative phasors ``m_{cc'}`` (pairs in ``np.triu_indices`` order).

    Example:
      >>> pair_mean_phasors(jnp.array([[1.0, 1j]], complex)).round(6).tolist()
      [-1j]
    """
    _check_latents(z)
    return _mean_phasors(z, _vmask(z, vertex_mask))


def _edges(neighborhood):
    """Real neighbour pairs ``(p, slot)`` of a k-NN neighbourhood, the self slot excluded."""
    index = jnp.asarray(neighborhood.index)
    mask = jnp.asarray(neighborhood.mask).astype(bool)
    own = jnp.arange(index.shape[0])[:, None]
    return index, mask & (index != own)


@jax.jit
@_standard
def _energy_corr(z, index, emask, vmask, pair_w):
    e = jnp.abs(z) ** 2
    w = vmask.astype(e.dtype)[:, None]
    n = jnp.maximum(jnp.sum(w), 1.0)
    mean = jnp.sum(e * w, axis=0) / n
    var = jnp.sum((e - mean) ** 2 * w, axis=0) / n
    x = (e - mean) / jnp.sqrt(jnp.maximum(var, _TINY)) * w
    ew = (emask & vmask[:, None] & vmask[index]).astype(e.dtype)
    prod = x[:, None, :] * x[index] * ew[..., None]  # [V, K, d]
    rho = jnp.sum(prod, axis=(0, 1)) / jnp.maximum(jnp.sum(ew), 1.0)
    return jnp.sum(rho * pair_w) / jnp.maximum(jnp.sum(pair_w), _TINY), rho


@_standard
def neighbour_energy_correlation(
    z, neighborhood, vertex_mask=None, *, channel_weight=None, per_channel: bool = False
) -> jax.Array:
    """Correlation of the channel energies ``|z|²`` between neighbouring vertices (module docstring).

    Args:
      z: ``[V, d]`` complex latents.
      neighborhood: a :class:`~jmeshtex.VertexNeighborhood` of the same ``V`` vertices
        (``index``, ``mask``; the self slot is skipped), e.g. ``denoiser_geometry(mesh).fine``.
      vertex_mask: ``[V]`` True for real vertices (None: the neighbourhood's ``vertex_mask``).
      channel_weight: ``[d]`` weights of the channels' correlations (None: equal).
      per_channel: return the ``[d]`` per-channel correlations instead of their weighted mean.

    Returns:
      A scalar in [−1, 1], the Pearson correlation over neighbour pairs of the per-channel
      standardised energies;
      about 0 for shuffled latents, near 1 for fields smooth at the neighbourhood's scale.

    Example:
      >>> from jmeshtex.fldm.core import denoiser_geometry
      >>> from jmeshtex.data import icosphere
      >>> m = icosphere(2)
      >>> nb = denoiser_geometry(m, knn=7).fine
      >>> z = jnp.asarray(np.exp(3 * m.vertices[:, :2]) + 0j)
      >>> bool(neighbour_energy_correlation(z, nb) > 0.8)
      True
    """
    _check_latents(z)
    index, emask = _edges(neighborhood)
    if index.shape[0] != z.shape[0]:
        raise InputError(
            f"neighborhood has {index.shape[0]} vertices but z has {z.shape[0]}; use the "
            "neighbourhood of the mesh the latents live on"
        )
    if vertex_mask is None and getattr(neighborhood, "vertex_mask", None) is not None:
        vertex_mask = jnp.asarray(neighborhood.vertex_mask)
    vmask = _vmask(z, vertex_mask)
    d = z.shape[1]
    w = jnp.ones(d) if channel_weight is None else jnp.asarray(channel_weight, jnp.float32)
    if w.shape != (d,):
        raise InputError(f"channel_weight must be [d] = ({d},), got {w.shape}")
    total, rho = _energy_corr(z, index, emask, vmask, w)
    return rho if per_channel else total


@jax.jit
@_standard
def _phase_coherence(z, index, emask, vmask, transport):
    zq = z[index] * transport[..., None]  # q's vector in p's frame
    ew = (emask & vmask[:, None] & vmask[index]).astype(z.real.dtype)[..., None]
    num = jnp.sum(jnp.real(z[:, None, :] * jnp.conj(zq)) * ew)
    den = jnp.sum(jnp.abs(z[:, None, :]) * jnp.abs(zq) * ew)
    return num / jnp.maximum(den, _TINY)


@_standard
def transported_phase_coherence(z, neighborhood, vertex_mask=None) -> jax.Array:
    """Directional agreement of neighbouring latents after parallel transport, in [−1, 1].

    ``Re Σ z_p conj(ρ_{q→p} z_q) / Σ |z_p| |z_q|`` over real neighbour pairs and channels.

    Example:
      >>> from jmeshtex.fldm.core import denoiser_geometry
      >>> from jmeshtex.data import icosphere
      >>> nb = denoiser_geometry(icosphere(2), knn=7).fine
      >>> z = random_channel_phases(jnp.ones((162, 2), complex), key=jax.random.key(0))
      >>> bool(abs(transported_phase_coherence(z, nb)) < 0.2)
      True
    """
    _check_latents(z)
    index, emask = _edges(neighborhood)
    if vertex_mask is None and getattr(neighborhood, "vertex_mask", None) is not None:
        vertex_mask = jnp.asarray(neighborhood.vertex_mask)
    vmask = _vmask(z, vertex_mask)
    return _phase_coherence(z, index, emask, vmask, jnp.asarray(neighborhood.transport))


@_standard
def latent_statistics(z, neighborhood, vertex_mask=None, *, channel_weight=None) -> dict:
    """All pooled statistics of one field as a dict of Python floats.

    Keys: ``concentration`` (:func:`relative_phase_concentration`), ``energy_correlation``
    (:func:`neighbour_energy_correlation`), ``phase_coherence``
    (:func:`transported_phase_coherence`), ``rms`` (root mean squared modulus) and ``power``
    (per-channel mean ``|z|²``, a list).

    Example:
      >>> from jmeshtex.fldm.core import denoiser_geometry
      >>> from jmeshtex.data import icosphere
      >>> nb = denoiser_geometry(icosphere(1), knn=7).fine
      >>> sorted(latent_statistics(jnp.ones((42, 2), complex), nb))
      ['concentration', 'energy_correlation', 'phase_coherence', 'power', 'rms']
    """
    _check_latents(z)
    if vertex_mask is None and getattr(neighborhood, "vertex_mask", None) is not None:
        vertex_mask = jnp.asarray(neighborhood.vertex_mask)
    vmask = _vmask(z, vertex_mask)
    w = vmask.astype(jnp.float32)[:, None]
    power = jnp.sum(jnp.abs(z) ** 2 * w, axis=0) / jnp.maximum(jnp.sum(w), 1.0)
    out = {
        "concentration": float(
            relative_phase_concentration(z, vmask, channel_weight=channel_weight)
        )
        if z.shape[1] > 1
        else float("nan"),
        "energy_correlation": float(
            neighbour_energy_correlation(z, neighborhood, vmask, channel_weight=channel_weight)
        ),
        "phase_coherence": float(transported_phase_coherence(z, neighborhood, vmask)),
        "rms": float(jnp.sqrt(jnp.mean(power))),
        "power": [float(p) for p in np.asarray(power)],
    }
    return out


@_standard
def region_statistics(z, regions, num_regions: int, vertex_mask=None) -> dict:
    """``R`` and the mean channel energies within each region of a vertex labelling.

    Args:
      z: ``[V, d]`` complex latents.
      regions: ``[V]`` integer region of each vertex in ``[0, num_regions)``.
      num_regions: number of regions.
      vertex_mask: ``[V]`` True for real vertices (None: all).

    Returns:
      ``{"concentration": [num_regions], "power": [num_regions, d], "count": [num_regions]}``
      NumPy arrays (``concentration`` NaN for an empty region).

    Example:
      >>> z = jnp.array([[1.0, 1.0], [1.0, 1.0], [1.0, -1.0], [1.0, 1.0]], complex)
      >>> s = region_statistics(z, jnp.array([0, 0, 1, 1]), 2)
      >>> s["concentration"].round(6).tolist(), s["count"].tolist()
      ([1.0, 0.0], [2, 2])
    """
    _check_latents(z)
    regions = jnp.asarray(regions)
    if regions.shape != z.shape[:1] or not jnp.issubdtype(regions.dtype, jnp.integer):
        raise InputError(f"regions must be integers [V] = ({z.shape[0]},), got {regions.shape}")
    vmask = _vmask(z, vertex_mask)
    conc, power, count = _regions(z, regions, vmask, int(num_regions))
    conc = np.where(np.asarray(count) > 0, np.asarray(conc), np.nan)
    return {"concentration": conc, "power": np.asarray(power), "count": np.asarray(count)}


@functools.partial(jax.jit, static_argnums=3)
@_standard
def _regions(z, regions, vmask, n):
    onehot = (regions[:, None] == jnp.arange(n)[None]) & vmask[:, None]  # [V, n]
    w = onehot.astype(z.real.dtype)
    count = jnp.sum(w, axis=0)
    power = (w.T @ (jnp.abs(z) ** 2)) / jnp.maximum(count, 1.0)[:, None]
    if z.shape[1] < 2:
        return jnp.full(n, jnp.nan), power, count.astype(jnp.int32)
    u = _relative_phasors(z)  # [V, P]
    m = (w.T.astype(u.dtype) @ u) / jnp.maximum(count, 1.0)[:, None]
    return jnp.mean(jnp.abs(m), axis=1), power, count.astype(jnp.int32)


@jax.jit
@_standard
def energy_field_correlation(a, b, vertex_mask=None) -> jax.Array:
    """Pearson correlation of the total energies ``Σ_c |z_c|²`` of two fields on the same vertices.

    The memorisation check: a sample compared with a training copy's latents carried to the
    sample's vertices (nearest surface point).

    Example:
      >>> z = jnp.array([[1.0], [2.0], [3.0]], complex)
      >>> [round(float(energy_field_correlation(z, b)), 4) for b in (2 * z, z[::-1])]
      [1.0, -1.0]
    """
    ea = jnp.sum(jnp.abs(a) ** 2, axis=-1)
    eb = jnp.sum(jnp.abs(b) ** 2, axis=-1)
    w = jnp.ones_like(ea) if vertex_mask is None else vertex_mask.astype(ea.dtype)
    n = jnp.maximum(jnp.sum(w), 1.0)
    xa = (ea - jnp.sum(ea * w) / n) * w
    xb = (eb - jnp.sum(eb * w) / n) * w
    return jnp.sum(xa * xb) / jnp.sqrt(jnp.maximum(jnp.sum(xa**2) * jnp.sum(xb**2), _TINY))


@_standard
def shuffle_latents(z, *, key: jax.Array, vertex_mask=None) -> jax.Array:
    """The field permuted over its real vertices (same marginal, no spatial structure).

    Example:
      >>> z = jnp.arange(5.0, dtype=complex)[:, None]
      >>> sorted(shuffle_latents(z, key=jax.random.key(0))[:, 0].real.tolist())
      [0.0, 1.0, 2.0, 3.0, 4.0]
    """
    _check_latents(z)
    real = np.flatnonzero(np.asarray(_vmask(z, vertex_mask)))
    perm = np.asarray(jax.random.permutation(key, real))
    return jnp.asarray(z).at[real].set(jnp.asarray(z)[perm])


@_standard
def random_channel_phases(z, *, key: jax.Array) -> jax.Array:
    """Each ``z_{vc}`` turned by its own uniform random phase (magnitudes kept; ``R`` → ~0).

    Example:
      >>> z = jnp.ones((3, 2), complex)
      >>> np.allclose(jnp.abs(random_channel_phases(z, key=jax.random.key(0))), 1.0)
      True
    """
    _check_latents(z)
    z = jnp.asarray(z)
    theta = jax.random.uniform(key, z.shape, z.real.dtype, minval=0.0, maxval=2 * np.pi)
    return z * jax.lax.complex(jnp.cos(theta), jnp.sin(theta))

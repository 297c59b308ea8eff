"""Numerical equivariance checks for mesh operators, in the spirit of e3nn-jax's ``assert_equivariant``.

An operator under test is a function ``fn(state, **inputs) -> Field`` of a
:class:`~jmeshtex.testing.MeshState` (positions, faces, gauge — from which it builds whatever
geometry it needs) and typed inputs. For a drawn transform :math:`T` (a
:class:`~jmeshtex.testing.Realisation`) the equivariance error is

.. math:: e = \\frac{\\lVert f(T\\cdot M, T\\cdot x) - T\\cdot f(M, x) \\rVert}
                   {\\max(\\lVert T\\cdot f(M, x) \\rVert, \\epsilon)}

over all output entries (Frobenius norm; complex values count real and imaginary parts).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from .._config import is_int
from .._errors import ConfigError, InputError
from ._fields import Field
from ._transforms import Realisation, Transform

DEFAULT_TOLERANCE = {np.dtype("float64"): 1e-10, np.dtype("float32"): 1e-5}


def check_dtype(dtype, where: str) -> np.dtype:
    """The dtype a check runs in: ``None`` follows JAX's x64 setting (float64 when it is on, else
    float32, each checked against its own bound); float64 asked for with x64 off is refused.

    JAX silently computes in float32 when ``jax_enable_x64`` is off, so a float64 check would
    compare float32 round-off (~1e-7) with the float64 bound (1e-10) and fail for no fault of the
    operator.

    Raises:
      ConfigError: ``dtype`` is float64 and x64 is off, or ``dtype`` is neither float32 nor float64.

    Example:
      >>> check_dtype(None, "check") == (np.float64 if jax.config.jax_enable_x64 else np.float32)
      True
    """
    x64 = bool(jax.config.jax_enable_x64)
    if dtype is None:
        return np.dtype(np.float64 if x64 else np.float32)
    dt = np.dtype(dtype)
    if dt not in DEFAULT_TOLERANCE:
        raise ConfigError(f"{where}: dtype must be float32, float64 or None, got {dt}")
    if dt == np.float64 and not x64:
        raise ConfigError(
            f"{where}: dtype=float64 but JAX's x64 mode is off, so the check would run in float32 "
            "against the float64 bound (1e-10); call jax.config.update('jax_enable_x64', True) at "
            "the start of the program, or pass dtype=None (follow x64: float32 here, bound 1e-5)"
        )
    return dt


def relative_error(actual, expected) -> float:
    """``‖actual − expected‖ / max(‖expected‖, tiny)`` over all leaves of two matching pytrees.

    Example:
      >>> relative_error(np.array([1.0, 2.0]), np.array([1.0, 2.0 + 1e-6])) < 1e-6
      True
    """
    a = [np.asarray(x) for x in jax.tree.leaves(actual)]
    b = [np.asarray(x) for x in jax.tree.leaves(expected)]
    if len(a) != len(b) or any(x.shape != y.shape for x, y in zip(a, b, strict=True)):
        raise InputError(
            f"output structures differ: {[x.shape for x in a]} vs {[y.shape for y in b]}"
        )
    num = np.sqrt(
        sum(
            float(np.sum(np.abs(x.astype(np.complex128) - y) ** 2))
            for x, y in zip(a, b, strict=True)
        )
    )
    den = np.sqrt(sum(float(np.sum(np.abs(y.astype(np.complex128)) ** 2)) for y in b))
    if not np.isfinite(num):
        return float("inf")
    return float(num / max(den, np.finfo(np.float64).tiny))


def _to_device(field: Field, dtype) -> Field:
    x = np.asarray(field.value)
    if np.iscomplexobj(x):
        target = jnp.complex128 if jnp.dtype(dtype) == jnp.float64 else jnp.complex64
    elif np.issubdtype(x.dtype, np.floating):
        target = dtype
    else:
        return Field(field.kind, jnp.asarray(x))
    # converted on the host: a device conversion would compile once per shape
    return Field(field.kind, jax.device_put(np.asarray(x, dtype=target)))


def equivariance_error(
    fn: Callable[..., Field],
    realisation: Realisation,
    inputs: Mapping[str, Field],
    *,
    mask: np.ndarray | None = None,
) -> float:
    """Relative error of ``fn(T·M, T·x)`` against ``T·fn(M, x)`` for one drawn transform.

    Args:
      fn: ``fn(state, **values) -> Field``; builds its geometry from ``state``.
      realisation: a drawn transform (``CATALOGUE[name].draw(...)``).
      inputs: typed inputs on the source mesh, ``{name: Field(kind, value)}``.
      mask: optional ``[V]`` or ``[F]`` boolean selection of the output rows (target labels) to
        compare, e.g. the vertices whose discrete neighbourhood choice is the same on both meshes.

    Returns:
      The relative error (0 for an exactly equivariant operator in exact arithmetic).

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.testing import CATALOGUE, MeshState, Field
      >>> def centroid(state, x):  # mean position: equivariant to rigid motions
      ...     return Field("invariant", state.points().mean(0) * 0 + x.sum())
      >>> s = MeshState(*icosahedron())
      >>> r = CATALOGUE["permute_vertices"].draw(np.random.default_rng(0), s)
      >>> equivariance_error(centroid, r, {"x": Field("vertex_scalar", np.arange(12.0))}) < 1e-12
      True
    """
    src_dtype = realisation.source.dtype
    source_out = fn(
        realisation.source, **{k: _to_device(f, src_dtype).value for k, f in inputs.items()}
    )
    if not isinstance(source_out, Field):
        raise TypeError(f"the operator must return a Field(kind, value), got {type(source_out)}")
    mapped = {k: _to_device(realisation.map(f), src_dtype).value for k, f in inputs.items()}
    target_out = fn(realisation.target, **mapped)
    expected = realisation.map(Field(source_out.kind, np.asarray(source_out.value)))
    actual, wanted = np.asarray(target_out.value), np.asarray(expected.value)
    if mask is not None:
        actual, wanted = actual[mask], wanted[mask]
    return relative_error(actual, wanted)


@dataclasses.dataclass(frozen=True)
class Convergence:
    """Errors of a smooth-isometry family as the mesh is refined (resolution doubles each step).

    Attributes:
      resolutions: mesh resolutions n (cells per side); the spacing is ~1/n.
      errors: relative equivariance error at each resolution.
      ratios: ``errors[i] / errors[i+1]`` (≈ 4 for second-order convergence).
      orders: ``log2`` of the ratios.
      floor: True where both errors were at round-off level (no order to measure).
      excluded: per resolution, the fraction of vertices left out because a discrete choice
        flipped (empty when the operator declares no ``selection``).
    """

    resolutions: tuple[int, ...]
    errors: tuple[float, ...]
    ratios: tuple[float, ...]
    orders: tuple[float, ...]
    floor: bool
    excluded: tuple[float, ...] = ()

    @property
    def order(self) -> float:
        """The smallest observed order (the one the bound is checked on)."""
        return float(min(self.orders)) if self.orders else float("nan")


def convergence(
    fn: Callable[..., Field],
    transform: Transform,
    make_inputs: Callable[[object, np.random.Generator], Mapping[str, Field]],
    *,
    resolutions: Sequence[int] = (8, 16, 32, 64),
    dtype=None,
    seed: int = 0,
    floor: float = 1e-12,
    selection: Callable[[object], np.ndarray] | None = None,
    hops: int = 1,
) -> Convergence:
    """Measure the convergence of the equivariance error of a smooth-isometry family.

    Args:
      fn: the operator, as in :func:`equivariance_error`.
      transform: a ``family=True`` transform (``cylinder``, ``cone``, ``catenoid``).
      make_inputs: ``(source_state, rng) -> inputs`` on each resolution's source mesh.
      resolutions: doubling sequence of resolutions.
      dtype: operator dtype; None (default) follows JAX's x64 setting (orders are only
        meaningful in float64; see :func:`~jmeshtex.testing.check_dtype`).
      seed: seed of the draws.
      floor: errors below this are round-off; if every error is, ``floor=True`` and no order is
        asserted (the operator is exactly invariant under the family).
      selection: ``state -> [V, ...]`` a per-vertex signature of the operator's *discrete* choices
        (e.g. which k nearest neighbours were selected). Such choices are discontinuous functions of
        the metric: near a tie, an arbitrarily small bending flips them. Vertices whose signature
        differs between the two meshes are left out of the comparison, and their fraction is
        recorded in ``excluded``.
      hops: the receptive field's depth in selection hops (a network of ``hops`` stacked k-NN
        layers). A flipped choice at q changes the output of every vertex whose receptive field
        contains q, so the vertices that select a left-out vertex are left out too, ``hops - 1``
        times over; the selection must then be ``[V, k]`` neighbour indices (negative: padding).
    """
    if not is_int(hops, 1):
        raise InputError(f"convergence: hops must be an integer ≥ 1, got {hops!r}")
    if not transform.family:
        raise InputError(
            f"convergence: {transform.name!r} is not a family of meshes; pass a transform with "
            "family=True (a smooth-isometry family, see jmeshtex.testing.CATALOGUE)"
        )
    dtype = check_dtype(dtype, "convergence")
    errors, excluded = [], []
    for n in resolutions:
        rng = np.random.default_rng(seed)
        real = transform.draw(rng, resolution=n, dtype=dtype)
        mask = None
        if selection is not None:
            a = np.asarray(selection(real.source))[real.vperm]
            b = np.asarray(selection(real.target))
            mask = np.all((a == b).reshape(len(b), -1), axis=1)
            mask = _within_hops(mask, b, hops)
            excluded.append(float(1.0 - mask.mean()))
        errors.append(equivariance_error(fn, real, make_inputs(real.source, rng), mask=mask))
    errs = np.asarray(errors)
    at_floor = bool(np.all(errs < floor))
    ratios = tuple(float(a / max(b, 1e-300)) for a, b in zip(errs[:-1], errs[1:], strict=True))
    orders = tuple(float(np.log2(max(r, 1e-300))) for r in ratios)
    return Convergence(
        tuple(resolutions), tuple(map(float, errs)), ratios, orders, at_floor, tuple(excluded)
    )


def _within_hops(same: np.ndarray, neighbours: np.ndarray, hops: int) -> np.ndarray:
    """Keep only the vertices no flipped choice can reach in ``hops - 1`` hops of ``neighbours``.

    Example:
      >>> nb = np.array([[1], [2], [2]])  # 0 reads 1, 1 reads 2, 2 reads itself
      >>> _within_hops(np.array([True, True, False]), nb, 2).tolist()
      [True, False, False]
    """
    keep = np.asarray(same, bool).copy()
    if hops == 1:
        return keep
    nb = np.asarray(neighbours).reshape(len(keep), -1)
    if not np.issubdtype(nb.dtype, np.integer):
        raise InputError(
            "convergence: hops > 1 needs a selection of [V, k] integer neighbour indices, "
            f"got dtype {nb.dtype}"
        )
    valid = (nb >= 0) & (nb < len(keep))
    for _ in range(hops - 1):
        reads_flipped = np.any(valid & ~keep[np.where(valid, nb, 0)], axis=1)
        keep &= ~reads_flipped
    return keep

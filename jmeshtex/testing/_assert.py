"""One call that checks a user's operator under the harness's transforms, as e3nn-jax's
``assert_equivariant`` does for irreps: draw, compare, and say which transform and which output
channels broke.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import jax
import numpy as np

from .._config import is_int
from .._errors import InputError
from .._mesh import Mesh
from ._check_cache import CheckCache
from ._equivariance import DEFAULT_TOLERANCE, _to_device, check_dtype, relative_error
from ._fields import KINDS, Field
from ._registry import EXACT, Entry, check, random_inputs
from ._state import MeshState
from ._transforms import CATALOGUE, Realisation

__all__ = ["assert_equivariant"]


def assert_equivariant(
    fn: Callable,
    key,
    inputs: Mapping[str, tuple[str, int] | Field],
    *,
    output: str | None = None,
    mesh=None,
    transforms: Sequence[str | Realisation] = EXACT,
    dtype=None,
    rtol: float | None = None,
    hops: int = 1,
    selection: Callable | None = None,
) -> dict[str, float]:
    """Check ``fn`` under every transform in one call; raise one ``AssertionError`` naming each failure.

    A model of one's own is checked on the catalogue's meshes and on one's own mesh in one call,
    with a one-line adapter that rebuilds its geometry from the state (log maps in mean edges, the
    builders' default)::

        assert_equivariant(lambda state, x: model(params, x, state.knn(8)), key,
                           {"x": ("vertex_tangent", 2)}, output="vertex_tangent", mesh=(v, f))

    Args:
      fn: the operator, ``fn(state, **inputs)``, returning a ``Field`` or, with ``output=``, its
        value; builds its geometry from ``state`` (a :class:`~jmeshtex.testing.MeshState`), e.g.
        ``state.knn(k)`` or ``state.one_ring()`` (so gauge changes and relabellings reach it, and
        the harness compiles it once per mesh size).
      key: a ``jax.random`` key or an int seed; every draw (meshes, transforms, inputs) follows it.
      inputs: ``{name: (kind, channels)}`` drawn at random on each mesh, as the registry does; a
        ``Field`` value is used as given, which needs the transforms to be realisations of its mesh.
      output: the kind (one of ``KINDS``) of what ``fn`` returns, when it returns a bare array;
        None (default): ``fn`` returns a ``Field``.
      mesh: your own mesh (a :class:`~jmeshtex.Mesh`, a ``(vertices, faces)`` pair or a
        ``MeshState``): every named transform that applies to any mesh (rigid, reflection, gauge,
        the relabellings) is drawn on it too, beside the catalogue's meshes; the families (folds,
        smooth isometries) build their own. A failure on it says ``on your mesh``.
      transforms: names in ``CATALOGUE`` (default: the exact ones, see
        ``EXACT``), checked with the registry's bounds (exact: ``rtol``;
        smooth isometries: a convergence order), or drawn :class:`~jmeshtex.testing.Realisation`
        objects of your own mesh.
      dtype: ``jnp.float64`` (bounds 1e-10 / order), ``jnp.float32`` (1e-5; smooth isometries
        reported only) or None (default): float64 when JAX's x64 mode is on, else float32.
        float64 with x64 off raises :class:`~jmeshtex.ConfigError` (JAX would compute in float32).
      rtol: the relative bound of exact checks (default: 1e-10 in float64, 1e-5 in float32).
      hops: depth of the receptive field (number of stacked k-NN layers): where k-NN choices flip
        under a smooth isometry, every vertex within ``hops`` hops is left out (needs ``selection``).
      selection: ``state -> [V, k]`` neighbour indices the operator selected (e.g.
        ``lambda s: s.knn(k).index``); required for smooth isometries of operators with discrete
        neighbour choices.

    Returns:
      ``{transform name: error}`` (the relative error for exact checks, the finest resolution's
      error for smooth isometries).

    Raises:
      AssertionError: one or more transforms broke their bound; the message lists each, and for a
        realisation the relative error of every output channel.
      InputError: an unknown transform name or output kind, a ``Field`` input with a transform
        name (the mesh it lives on is unknown: pass realisations), or a bad ``mesh``.
      TypeError: ``fn`` returned a bare value and no ``output`` kind was declared.

    Example:
      >>> import jax.numpy as jnp
      >>> from jmeshtex.testing import Field
      >>> def spread(state, x):  # distance to the centroid times a scalar: rigid-equivariant
      ...     p = state.points()
      ...     return Field("vertex_scalar", jnp.linalg.norm(p - p.mean(0), axis=1)[:, None] * x)
      >>> errors = assert_equivariant(spread, 0, {"x": ("vertex_scalar", 2)},
      ...                             transforms=("rigid", "permute_vertices"))
      >>> sorted(errors), max(errors.values()) < 1e-10
      (['permute_vertices', 'rigid'], True)
    """
    seed = _seed(key)
    dtype = check_dtype(dtype, "assert_equivariant")
    if output is not None and output not in KINDS:
        raise InputError(f"assert_equivariant: output must be one of {KINDS}, got {output!r}")
    fn = _typed(fn, output)
    own = None if mesh is None else _own_state(mesh, dtype)
    tol = DEFAULT_TOLERANCE[dtype] if rtol is None else float(rtol)
    specs = {k: v for k, v in inputs.items() if not isinstance(v, Field)}
    fixed = {k: v for k, v in inputs.items() if isinstance(v, Field)}
    names = [t for t in transforms if isinstance(t, str)]
    unknown = [t for t in names if t not in CATALOGUE]
    if unknown:
        raise InputError(
            f"assert_equivariant: unknown transforms {unknown}; known: {sorted(CATALOGUE)}"
        )
    if names and fixed:
        raise InputError(
            f"assert_equivariant: inputs {sorted(fixed)} are fixed Fields on one mesh, but "
            f"transforms {names} draw their own meshes; pass (kind, channels) specs, or "
            "realisations of your mesh (CATALOGUE[name].draw(rng, MeshState(v, f)))"
        )
    errors: dict[str, float] = {}
    failures: list[str] = []
    entry = Entry(
        name="assert_equivariant",
        apply=lambda state, params, **x: fn(state, **x),
        inputs=specs,
        transforms=tuple(names),
        hops=hops,
        selection=selection,
    )
    cache = CheckCache()  # one compilation per mesh size, shared by every draw below

    def compiled(state, **x):
        return cache.apply(entry, state, None, x)

    if names:
        for name in names:
            result = check(entry, name, dtype=dtype, seed=seed, cache=cache)
            errors[name] = result.error
            if result.check == "exact" and rtol is not None:
                result.passed = result.error <= tol
            if result.passed is False:
                bound = f"> {tol:.1e}" if result.check == "exact" else "order below the bound"
                detail = f" [{result.detail}]" if result.detail else ""
                failures.append(f"  {name}: relative error {result.error:.3e} {bound}{detail}")
    rng = np.random.default_rng(seed)
    drawn = [(t.name, t, "") for t in transforms if not isinstance(t, str)]
    if own is not None:
        anywhere = [n for n in names if not CATALOGUE[n].family]
        drawn += [(n, CATALOGUE[n].draw(rng, own), " on your mesh") for n in anywhere]
    for name, real, where in drawn:
        values = dict(fixed)
        values.update(random_inputs(specs, real.source, rng))
        err, per_channel = _errors_by_channel(compiled, real, values)
        errors[name] = max(err, errors.get(name, 0.0))
        if not err <= tol:
            worst = ", ".join(f"{c}: {e:.1e}" for c, e in per_channel[:8])
            failures.append(
                f"  {name}{where}: relative error {err:.3e} > {tol:.1e}; per output channel: "
                f"{worst}"
            )
    if failures:
        raise AssertionError(f"not equivariant ({dtype.name}):\n" + "\n".join(failures))
    return errors


def _typed(fn: Callable, output: str | None) -> Callable[..., Field]:
    """``fn`` returning a ``Field``: its value tagged ``output``, or a typed error naming the fix."""

    def typed(state, **inputs):
        out = fn(state, **inputs)
        if isinstance(out, Field):
            return out
        if output is None:
            raise TypeError(
                f"assert_equivariant: the operator returned {type(out).__name__}, not a Field; "
                "declare what it returns once, e.g. output='vertex_tangent', or return "
                "Field(kind, value)"
            )
        return Field(output, out)

    return typed


def _own_state(mesh, dtype) -> MeshState:
    """The user's mesh as a :class:`MeshState` in the checked dtype (validated)."""
    from .._mesh import as_mesh

    if isinstance(mesh, MeshState):
        return mesh.with_(dtype=dtype)
    if not isinstance(mesh, (Mesh, tuple, list)):
        raise InputError(
            "assert_equivariant: mesh must be a jmeshtex.Mesh, a (vertices, faces) pair or a "
            f"MeshState, got {type(mesh).__name__}"
        )
    from ..geometry import check_mesh_arrays

    v, f = check_mesh_arrays(*as_mesh(mesh, what="assert_equivariant: mesh"))
    return MeshState(v, f, dtype=dtype)


def _seed(key) -> int:
    if is_int(key):
        return int(key)
    try:
        data = np.asarray(jax.random.key_data(key))
    except (TypeError, ValueError):
        data = None
    if data is None or data.dtype.kind not in "ui":
        raise InputError(
            f"assert_equivariant: key must be a jax.random key or an int seed, got {type(key)}"
        )
    return int(np.uint64(np.bitwise_xor.reduce(data.astype(np.uint64).ravel())) % (2**31))


def _errors_by_channel(
    fn: Callable[..., Field], real: Realisation, inputs: Mapping[str, Field]
) -> tuple[float, list[tuple[int, float]]]:
    """The relative error, and each output channel's (last axis after the rows), worst first."""
    dt = real.source.dtype
    out = fn(real.source, **{k: _to_device(f, dt).value for k, f in inputs.items()})
    if not isinstance(out, Field):
        raise TypeError(f"the operator must return a Field(kind, value), got {type(out)}")
    mapped = {k: _to_device(real.map(f), dt).value for k, f in inputs.items()}
    actual = np.asarray(fn(real.target, **mapped).value)
    wanted = np.asarray(real.map(Field(out.kind, np.asarray(out.value))).value)
    total = relative_error(actual, wanted)
    if actual.ndim < 2:
        return total, [(0, total)]
    rows, channels = actual.shape[:2]
    a, w = actual.reshape(rows, channels, -1), wanted.reshape(rows, channels, -1)
    per = [(c, relative_error(a[:, c], w[:, c])) for c in range(a.shape[1])]
    return total, sorted(per, key=lambda item: -item[1])

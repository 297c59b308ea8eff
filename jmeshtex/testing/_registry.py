"""The registry of equivariant operators and models, and the runner behind ``jmeshtex verify``.

Every public operator or model that should be equivariant declares here its typed inputs, its output
kind (through the :class:`Field` it returns) and the transforms under which it must commute. The
runner draws each transform, measures the error in float64 and float32, and compares it with the
bound of its class:

- exact transforms (rigid, gauge, relabelling, exact folds): relative error ≤ 1e-10 (float64),
  ≤ 1e-5 (float32);
- smooth isometries (cylinder, cone, catenoid): the error must fall by a factor ≥ 3 per halving of
  the mesh spacing over three refinements (observed order ≳ 1.6), checked in float64; float32 is
  reported only (its round-off floor hides the order). Vertices whose discrete choices flipped
  (``Entry.selection``, within ``Entry.hops``) are left out, at most
  :data:`~jmeshtex.testing.MAX_EXCLUDED` of them at the finest resolution;
- re-triangulation: reported, not asserted.

Negative controls are registered with ``expect_fail``: deliberately broken operators that the named
transforms must flag (the check passes when the error is *above* the bound).

Register a new operator with :func:`register`::

    register(Entry(name="my_op", apply=my_op_under_test, inputs={"x": (VERTEX_TANGENT, 4)},
                   transforms=("rigid", "gauge", "permute_vertices", "fold", "cylinder")))
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable, Iterable, Mapping, Sequence

import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from ._check_cache import CheckCache
from ._equivariance import DEFAULT_TOLERANCE, check_dtype, convergence, equivariance_error
from ._fields import (
    FACE_EDGE,
    FACE_SCALAR,
    FACE_VECTOR,
    POINTS,
    VERTEX_SCALAR,
    VERTEX_TANGENT,
    VERTEX_VECTOR,
    Field,
)
from ._state import MeshState
from ._transforms import CATALOGUE

#: the exact transforms every intrinsic vertex operator must commute with (1e-10 in float64)
EXACT = (
    "rigid",
    "reflection",
    "gauge",
    "permute_vertices",
    "permute_faces",
    "rotate_corners",
    "fold",
    "folds",
    "hinge",
)
#: transforms every intrinsic vertex operator must commute with: the exact ones, the smooth
#: isometries (checked by convergence order) and re-triangulation (reported)
INTRINSIC = (*EXACT, "cylinder", "cone", "catenoid", "retriangulate")
#: transforms an extrinsic (3D) operator must commute with
EXTRINSIC = ("rigid", "gauge", "permute_vertices", "permute_faces", "rotate_corners")
#: transforms of a face operator on positions (DGTS): rigid motions and every relabelling
FACE_OPS = ("rigid", "permute_vertices", "permute_faces", "rotate_corners")


def face_conv_init(widths: tuple[int, ...]) -> Callable:
    """The ``Entry.init`` of a face-convolution stack of ``widths``
    (:func:`jmeshtex.ops.init_face_conv_stack`)."""

    def init(key, dtype):
        from ..ops import init_face_conv_stack

        return init_face_conv_stack(key, widths, dtype=dtype)

    return init


@dataclasses.dataclass(frozen=True)
class Entry:
    """One registered operator.

    Attributes:
      name: unique name shown in reports.
      apply: ``apply(state, params, **inputs) -> Field``; builds its geometry from ``state`` (a
        :class:`MeshState`) so gauge and relabelling reach it. Geometry read through the state's
        cache (``state.one_ring()``, ``state.knn(k)``, ``state.cached(key, build)``) is prepared on
        the host and the rest is compiled once per dtype and mesh shape (:class:`CheckCache`); an
        ``apply`` with host code on its inputs still works, run eagerly.
      inputs: ``{name: (kind, channels)}``; ``points`` inputs are the mesh's own positions.
      transforms: names in ``CATALOGUE`` to check.
      init: ``init(key, dtype) -> params`` (random parameters), or None.
      expect_fail: negative control: transforms that must flag this operator.
      group: ``"geometry"``, ``"ops"``, ``"models"`` or ``"negative"`` (report sections).
      doc: one line for reports.
      resolutions: mesh resolutions used for family transforms (smooth: a doubling sequence).
      selection: ``state -> [V, ...]`` signature of discrete per-vertex choices (k-NN selection);
        vertices where it differs are left out of smooth-isometry comparisons and counted (see
        :func:`~jmeshtex.testing.convergence`).
      hops: the receptive field's depth in k-NN hops (stacked layers): vertices within ``hops`` of
        a flipped choice are left out too (``selection`` must give neighbour indices).
      report: transforms that are measured and reported but not asserted, each for a documented
        reason (e.g. a greedy decimation that is not a continuous function of the metric).
    """

    name: str
    apply: Callable[..., Field]
    inputs: Mapping[str, tuple[str, int]]
    transforms: tuple[str, ...]
    init: Callable | None = None
    expect_fail: tuple[str, ...] = ()
    group: str = "ops"
    doc: str = ""
    resolutions: tuple[int, ...] = (8, 16, 32, 64)
    selection: Callable | None = None
    report: tuple[str, ...] = ()
    hops: int = 1


REGISTRY: dict[str, Entry] = {}


def load_entries() -> dict[str, Entry]:
    """Register every built-in entry (ops and geometry, then each method's) and return the registry.

    The registrations live in ``jmeshtex/testing/_entries.py`` and ``jmeshtex/testing/_methods/``;
    importing them adds their entries to ``REGISTRY`` (once: a module is imported only once).
    """
    from . import _entries  # noqa: F401
    from ._methods import dgts, fl, fldm, meshmatch, surfacecnn  # noqa: F401

    return REGISTRY


#: at most this fraction of vertices may be left out of a smooth-isometry comparison at the finest
#: resolution because a discrete choice (k-NN selection) flipped; coarser meshes may leave out more
#: (near-ties flip at a rate that falls with the spacing, and a deep receptive field multiplies them)
MAX_EXCLUDED = 0.1


def register(entry: Entry, *, replace: bool = False) -> Entry:
    """Add an entry to ``REGISTRY`` (transforms must exist).

    Args:
      entry: the operator to register.
      replace: replace an entry of the same name (re-running a notebook cell) instead of raising.

    Returns:
      ``entry``.

    Raises:
      ValueError: the name is taken (and ``replace`` is False) or a transform is unknown.

    Example:
      >>> from jmeshtex.testing import Field
      >>> e = Entry("user.scale", lambda s, p, x: Field("vertex_scalar", 2 * x), {"x": ("vertex_scalar", 1)},
      ...           ("rigid",))
      >>> register(e, replace=True) is register(e, replace=True)
      True
      >>> _ = REGISTRY.pop("user.scale")
    """
    if entry.name in REGISTRY and not replace:
        raise InputError(
            f"an operator named {entry.name!r} is already registered (replace=True replaces it)"
        )
    unknown = [
        t for t in (*entry.transforms, *entry.expect_fail, *entry.report) if t not in CATALOGUE
    ]
    if unknown:
        raise InputError(
            f"{entry.name}: unknown transforms {unknown}; see jmeshtex.testing.CATALOGUE"
        )
    REGISTRY[entry.name] = entry
    return entry


def _order_detail(conv, entry: Entry, passed: bool | None) -> str:
    """What a convergence verdict rests on, and for a failure, what to try (never what is already set)."""
    if conv.floor:
        return "round-off floor"
    text = ""
    if conv.excluded:
        text = (
            f"excluded {conv.excluded[0]:.1%} → {conv.excluded[-1]:.1%} of vertices, coarsest → "
            "finest (discrete choice flipped"
        )
        text += f" within {entry.hops} hops)" if entry.hops > 1 else ")"
    if passed is not False:
        return text
    if entry.selection is None:
        return (
            "no order: if the operator selects neighbours discretely (k-NN), declare "
            "Entry(selection=...) and hops= so flipped choices are left out"
        )
    if conv.excluded and conv.excluded[-1] > MAX_EXCLUDED:
        text += f"; more than {MAX_EXCLUDED:.0%} left out at the finest resolution"
        if entry.hops == 1:
            text += (
                "; k-NN choices flipped upstream change every output whose receptive field holds "
                "them: if the operator stacks k-NN layers, set Entry(hops=<layers>)"
            )
    elif entry.hops == 1 and conv.excluded:
        text += (
            "; if the operator stacks k-NN layers, a choice flipped in an earlier layer reaches "
            "further: set Entry(hops=<layers>)"
        )
    return text


def random_inputs(
    entry_inputs: Mapping[str, tuple[str, int]], state: MeshState, rng: np.random.Generator
) -> dict[str, Field]:
    """Random typed inputs on ``state``'s mesh (standard normal; complex: unit variance)."""
    V, F = state.num_vertices, state.num_faces
    out = {}
    for name, (kind, c) in entry_inputs.items():
        if kind == POINTS:
            value = state.vertices
        elif kind == VERTEX_SCALAR:
            value = rng.standard_normal((V, c))
        elif kind == FACE_SCALAR:
            value = rng.standard_normal((F, c))
        elif kind == FACE_EDGE:
            value = rng.standard_normal((F, 3, c))
        elif kind == VERTEX_TANGENT:
            value = (rng.standard_normal((V, c)) + 1j * rng.standard_normal((V, c))) / np.sqrt(2)
        elif kind == VERTEX_VECTOR:
            value = rng.standard_normal((V, c, 3))
        elif kind == FACE_VECTOR:
            value = rng.standard_normal((F, c, 3))
        else:
            raise InputError(
                f"{name}: cannot draw random inputs of kind {kind!r}; give the entry a make_inputs"
            )
        out[name] = Field(kind, value)
    return out


def sample_meshes(rng: np.random.Generator) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Irregular meshes for transforms that apply to any mesh: a closed bumpy sphere, an open sheet.

    Both are smooth random deformations (no symmetric ties in distances or angles).
    """
    from ..data import grid, icosphere

    v, f = icosphere(2)
    c = rng.standard_normal((3, 3))
    bump = 1.0 + 0.15 * np.tanh(v @ c[0]) * np.cos(2 * v @ c[1])
    sphere = v * bump[:, None] + 0.02 * rng.standard_normal(v.shape)
    g, gf = grid(7, 6, diagonals="alternate")
    g = g + 0.03 * rng.standard_normal(g.shape) * np.array([1, 1, 0])
    g[:, 2] = 0.3 * np.sin(2.5 * g[:, 0]) * np.cos(1.7 * g[:, 1])
    return [("closed", sphere, f), ("open", g, gf)]


@dataclasses.dataclass
class CheckResult:
    """One cell of the report: an operator under one transform in one dtype."""

    entry: str
    transform: str
    dtype: str
    error: float
    tolerance: float | None
    passed: bool | None  # None: reported only
    check: str  # "exact", "order", "report"
    order: float | None = None
    ratios: tuple[float, ...] = ()
    expect_fail: bool = False
    detail: str = ""

    def as_dict(self) -> dict:
        d = dataclasses.asdict(self)
        for k in ("error", "order", "tolerance"):
            if isinstance(d[k], float) and not math.isfinite(d[k]):
                d[k] = str(d[k])
        return d


def asserted(entry: Entry, transform_name: str, dtype) -> bool:
    """Whether :func:`check` asserts a bound for this case (False: the error is only reported).

    Reported only: the entry's ``report`` transforms, re-triangulation, and smooth isometries in
    float32 (their round-off floor hides the order).

    Example:
      >>> e = load_entries()["ops.field_conv"]
      >>> asserted(e, "cylinder", "float64"), asserted(e, "cylinder", "float32")
      (True, False)
    """
    transform = CATALOGUE[transform_name]
    smooth = transform.family and not transform.exact
    if transform_name in entry.report or transform_name == "retriangulate":
        return False
    return not (smooth and np.dtype(dtype) != np.float64)


def check(
    entry: Entry,
    transform_name: str,
    *,
    dtype=None,
    seed: int = 0,
    cache: CheckCache | None = None,
    meshes: Sequence[str] | None = None,
) -> CheckResult:
    """Check one registered operator under one transform (see the module docstring for bounds).

    Args:
      entry: the registered operator.
      transform_name: a name in ``CATALOGUE``.
      dtype: ``jnp.float64``, ``jnp.float32`` or None (default): follow JAX's x64 setting
        (float64 when ``jax_enable_x64`` is on, else float32 with the float32 bound; the result's
        ``dtype`` and ``tolerance`` say which). float64 with x64 off raises
        :class:`~jmeshtex.ConfigError`.
      seed: seed of the parameters, the draws and the inputs.
      cache: compiled operators and geometry shared with other checks (a fresh one by default).
      meshes: for transforms of any mesh, the names of the ``sample_meshes`` to draw on
        (default: all of them, ``("closed", "open")``).

    Returns:
      The :class:`CheckResult`.
    """
    transform = CATALOGUE[transform_name]
    dtype = check_dtype(dtype, f"check({entry.name!r}, {transform_name!r})")
    cache = CheckCache() if cache is None else cache
    params = cache.params(entry, dtype, seed)

    def fn(state, **inputs):
        return cache.apply(entry, state, params, inputs)

    expect_fail = transform_name in entry.expect_fail
    report_only = transform_name in entry.report
    tol = DEFAULT_TOLERANCE[np.dtype(dtype)]
    name = np.dtype(dtype).name
    smooth = transform.family and not transform.exact

    if smooth and transform_name != "retriangulate" and np.dtype(dtype) == np.float64:
        return _order_check(entry, transform_name, fn, dtype=dtype, seed=seed)
    err = _largest_error(entry, transform, fn, dtype=dtype, seed=seed, meshes=meshes)
    if smooth or report_only:  # float32 smooth isometries, re-triangulation, declared reports
        return CheckResult(
            entry.name, transform_name, name, err, None, None, "report", expect_fail=expect_fail
        )
    passed = err <= tol
    if expect_fail:
        passed = not passed
    return CheckResult(
        entry.name, transform_name, name, err, tol, passed, "exact", expect_fail=expect_fail
    )


def _order_check(entry: Entry, transform_name: str, fn, *, dtype, seed: int) -> CheckResult:
    """A smooth isometry in float64: the convergence order of the error over the entry's
    resolutions (passes at a floor, or with every error ratio at least 3 and few vertices
    excluded at the finest resolution)."""
    expect_fail = transform_name in entry.expect_fail
    conv = convergence(
        fn,
        CATALOGUE[transform_name],
        lambda s, rng: random_inputs(entry.inputs, s, rng),
        resolutions=entry.resolutions,
        dtype=dtype,
        seed=seed,
        selection=entry.selection,
        hops=entry.hops,
    )
    if conv.floor:
        passed = True
    else:
        passed = len(conv.ratios) >= 3 and all(r >= 3.0 for r in conv.ratios)
        # discrete choices may flip near ties: at the finest resolution only at a few vertices
        passed = passed and (not conv.excluded or conv.excluded[-1] <= MAX_EXCLUDED)
    if expect_fail:
        passed = not passed
    if transform_name in entry.report:
        passed = None
    return CheckResult(
        entry.name,
        transform_name,
        np.dtype(dtype).name,
        conv.errors[-1],
        None,
        passed,
        "order",
        order=None if conv.floor else conv.order,
        ratios=conv.ratios,
        expect_fail=expect_fail,
        detail=_order_detail(conv, entry, passed),
    )


def _largest_error(entry: Entry, transform, fn, *, dtype, seed: int, meshes) -> float:
    """The largest equivariance error of one draw of a transform family (at the entry's second
    resolution when smooth), or of one draw on each of the ``sample_meshes`` (those in
    ``meshes``, None: all) for transforms of any mesh."""
    smooth = transform.family and not transform.exact
    rng = np.random.default_rng(seed)
    errors = []
    if transform.family:
        real = transform.draw(rng, resolution=entry.resolutions[1] if smooth else 8, dtype=dtype)
        errors.append(equivariance_error(fn, real, random_inputs(entry.inputs, real.source, rng)))
    else:
        for mesh, v, f in sample_meshes(rng):
            if meshes is not None and mesh not in meshes:
                continue
            state = MeshState(v, f, dtype=dtype)
            real = transform.draw(rng, state)
            errors.append(equivariance_error(fn, real, random_inputs(entry.inputs, state, rng)))
    return float(max(errors))


def run_registry(
    names: Iterable[str] | None = None,
    *,
    dtypes: Sequence = (jnp.float64, jnp.float32),
    seed: int = 0,
    transforms: Iterable[str] | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[CheckResult]:
    """Run the registry (all entries, or ``names``) under every declared transform and dtype."""
    load_entries()
    selected = list(REGISTRY) if names is None else list(names)
    missing = [n for n in selected if n not in REGISTRY]
    if missing:
        raise KeyError(f"not registered: {missing}; registered: {sorted(REGISTRY)}")
    wanted = None if transforms is None else set(transforms)
    cache = CheckCache()
    results = []
    for n in selected:
        entry = REGISTRY[n]
        for t in transforms_of(entry):
            if wanted is not None and t not in wanted:
                continue
            for dt in dtypes:
                if progress is not None:
                    progress(f"{n} × {t} ({np.dtype(dt).name})")
                results.append(check(entry, t, dtype=dt, seed=seed, cache=cache))
    return results


def transforms_of(entry: Entry) -> list[str]:
    names = [*entry.transforms, *entry.expect_fail, *entry.report]
    return list(dict.fromkeys(names))


def format_table(results: Sequence[CheckResult]) -> str:
    """A fixed-width table: operator × transform → error, bound, verdict, observed order."""
    head = f"{'operator':30s} {'transform':17s} {'dtype':8s} {'max rel err':>11s} {'bound':>9s} {'order':>6s}  verdict"
    lines = [head, "-" * len(head)]
    for r in results:
        bound = (
            f"{r.tolerance:.0e}"
            if r.tolerance is not None
            else ("ratio≥3" if r.check == "order" else "-")
        )
        order = f"{r.order:.2f}" if r.order is not None else ("exact" if r.detail else "")
        note = f"  [{r.detail}]" if r.detail and r.order is not None else ""
        if r.passed is None:
            verdict = "reported"
        elif r.expect_fail:
            verdict = "flagged (ok)" if r.passed else "NOT FLAGGED"
        else:
            verdict = "pass" if r.passed else "FAIL"
        lines.append(
            f"{r.entry:30s} {r.transform:17s} {r.dtype:8s} {r.error:11.2e} {bound:>9s} {order:>6s}  {verdict}{note}"
        )
    return "\n".join(lines)


def to_json(results: Sequence[CheckResult]) -> str:
    """The results of :func:`run_registry` as JSON: ``{"results": [...], "failed": n}`` (``jmeshtex verify --json``).

    Example:
      >>> import json
      >>> json.loads(to_json([]))
      {'results': [], 'failed': 0}
    """
    return json.dumps(
        {
            "results": [r.as_dict() for r in results],
            "failed": sum(1 for r in results if r.passed is False),
        },
        indent=2,
    )

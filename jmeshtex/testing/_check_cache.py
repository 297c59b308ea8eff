"""Compiled operators and shared geometry for the checks of one registry run.

A registered operator ``apply(state, params, **inputs)`` reads its geometry from a
:class:`~jmeshtex.testing.MeshState` through the state's cache (``state.one_ring()``,
``state.knn(k)``, ``state.cached(key, build)``, ...). :class:`CheckCache` splits a call in two:

- *prepare* (host): the operator is traced abstractly (``jax.eval_shape``) with the real state, and
  every geometry it reads is built on the host and recorded. The keys it read are remembered per
  entry, dtype and input structure: a later state (the target of every draw, the next mesh) whose
  keys are all the state's own geometry (``one_ring``, ``knn``, ...) has them built directly,
  without tracing the operator again (if it then reads other geometry, it is traced after all);
- *apply* (compiled): the operator runs under one ``jax.jit`` per entry and dtype, with the recorded
  geometry, its parameters and inputs as arguments. JAX compiles it once per array shape, so every
  exact transform of a mesh (same vertex and face counts) reuses one compilation, in the source and
  the target of every draw.

States with the same positions, faces and gauge share one geometry cache (across entries; host
geometry across dtypes too). An operator whose body needs concrete values (host code on its inputs,
a shape read from a geometry leaf) runs eagerly, as before; :attr:`CheckCache.eager` names them.
"""

from __future__ import annotations

import collections
import hashlib
from typing import Any

import jax
import numpy as np

from .._jit import jit_once
from ._fields import Field
from ._state import MeshState


class _Unprepared(Exception):
    """The compiled operator read geometry, or a host attribute, that prepare did not record."""


class _Probe(MeshState):
    """A state that records the geometry keys an operator reads and builds them on the host."""

    def __init__(self, state: MeshState, record: list):
        self.__dict__.update(state.__dict__)  # the same arrays and the same cache dicts
        self._record = record
        self._depth = 0

    def _cached(self, key, build):
        if self._depth == 0 and key not in self._record:
            self._record.append(key)
        self._depth += 1
        try:
            with jax.ensure_compile_time_eval():
                return MeshState._cached(self, key, build)
        finally:
            self._depth -= 1


class _Replay(MeshState):
    """A state inside the compiled operator: its geometry is the traced prepared values."""

    def __init__(self, prepared: dict, num_vertices: int, num_faces: int, dtype):
        self._prepared = prepared
        self._nv, self._nf = num_vertices, num_faces
        self.dtype = dtype

    @property
    def vertices(self):
        raise _Unprepared("vertices read outside a cached build")

    @property
    def faces(self):
        raise _Unprepared("faces read outside a cached build")

    @property
    def gauge(self):
        raise _Unprepared("gauge read outside a cached build")

    @property
    def num_vertices(self) -> int:
        return self._nv

    @property
    def num_faces(self) -> int:
        return self._nf

    def _cached(self, key, build):
        if key not in self._prepared:
            raise _Unprepared(f"geometry {key!r} was not prepared")
        return self._prepared[key]


def _is_array(leaf) -> bool:
    return isinstance(leaf, np.ndarray | np.generic | jax.Array)


def _split(tree) -> tuple[tuple, list]:
    """``(static spec, array leaves)``: non-array leaves (ints, strings) become part of the spec."""
    leaves, treedef = jax.tree.flatten(tree)
    static = tuple((i, leaf) for i, leaf in enumerate(leaves) if not _is_array(leaf))
    return (treedef, len(leaves), static), [leaf for leaf in leaves if _is_array(leaf)]


def _join(spec: tuple, arrays) -> Any:
    treedef, n, static = spec
    fixed = dict(static)
    it = iter(arrays)
    return jax.tree.unflatten(treedef, [fixed[i] if i in fixed else next(it) for i in range(n)])


def _digest(state: MeshState) -> bytes:
    h = hashlib.blake2b(digest_size=16)
    for a in (state.vertices, state.faces, state.gauge):
        h.update(str(a.shape).encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.digest()


class CheckCache:
    """Compiled operators, parameters and mesh geometry shared by the checks of one run.

    :func:`~jmeshtex.testing.run_registry` makes one per call; pass one to
    :func:`~jmeshtex.testing.check` to share it across calls (the test suite keeps one per session).
    Nothing is kept between caches.

    Args:
      max_meshes: how many meshes (positions, faces, gauge) keep their geometry (least recently
        used first out).

    Example:
      >>> import jax.numpy as jnp
      >>> from jmeshtex.testing import CheckCache, check, load_entries
      >>> cache = CheckCache()
      >>> entry = load_entries()["ops.complex_linear"]
      >>> [check(entry, t, dtype=jnp.float64, cache=cache).passed for t in ("rigid", "gauge")]
      [True, True]
      >>> cache.eager
      {}
    """

    def __init__(self, *, max_meshes: int = 256):
        self.max_meshes = max_meshes
        #: entries that run eagerly, with the reason their compiled form failed
        self.eager: dict[str, str] = {}
        self._jitted: dict[Any, Any] = {}
        self._kinds: dict[Any, str] = {}
        self._keys: dict[Any, tuple] = {}  # geometry keys each entry read, per dtype and shapes
        #: how many times an operator was traced to find the geometry it reads (for tests)
        self.probes = 0
        self._params: dict[Any, Any] = {}
        self._host: collections.OrderedDict = collections.OrderedDict()
        self._device: collections.OrderedDict = collections.OrderedDict()

    def params(self, entry, dtype, seed: int):
        """``entry.init(key(seed), dtype)``, made once per entry, dtype and seed."""
        if entry.init is None:
            return None
        k = (entry.name, np.dtype(dtype).name, seed)
        if k not in self._params:
            self._params[k] = entry.init(jax.random.key(seed), np.dtype(dtype))
        return self._params[k]

    def share(self, state: MeshState) -> MeshState:
        """Point ``state``'s geometry caches at those of every state with the same mesh and gauge."""
        digest = _digest(state)
        host = self._lru(self._host, digest, state._host)
        device = self._lru(self._device, (digest, np.dtype(state.dtype).name), state._cache)
        for mine, shared in ((state._host, host), (state._cache, device)):
            if mine is not shared:
                for k, v in mine.items():
                    shared.setdefault(k, v)
        state._host, state._cache = host, device
        return state

    def _lru(self, table: collections.OrderedDict, key, default: dict) -> dict:
        if key in table:
            table.move_to_end(key)
            return table[key]
        table[key] = default
        while len(table) > self.max_meshes:
            table.popitem(last=False)
        return default

    def apply(self, entry, state: MeshState, params, inputs: dict) -> Field:
        """``entry.apply(state, params, **inputs)``, compiled once per entry, dtype and shape."""
        self.share(state)
        if entry.name in self.eager:
            return entry.apply(state, params, **inputs)
        try:
            return self._compiled(entry, state, params, inputs)
        except Exception as e:  # noqa: BLE001 - the eager call below raises any real error
            self.eager[entry.name] = f"{type(e).__name__}: {e}".splitlines()[0][:200]
            return entry.apply(state, params, **inputs)

    def _compiled(self, entry, state: MeshState, params, inputs: dict) -> Field:
        par_spec, par = _split(params)
        # what the operator read on an earlier mesh (of any size): the same keys, as a rule
        signature = (entry.name, np.dtype(state.dtype).name, par_spec, _signature(inputs))
        try:
            known = self._keys.get(signature)
            replay = known is not None and all(state._rebuild(k) for k in known)
        except TypeError:  # unhashable static leaves: trace every time
            signature, replay = None, False
        if replay:
            try:
                return self._run(entry, state, known, par_spec, par, inputs)
            except _Unprepared:  # this state's operator read other geometry: trace it below
                pass
        keys: list = []
        self.probes += 1
        jax.eval_shape(
            lambda p, x: _value(entry.apply(_Probe(state, keys), _join(par_spec, p), **x)),
            par,
            inputs,
        )
        if signature is not None:
            self._keys[signature] = tuple(keys)
        return self._run(entry, state, keys, par_spec, par, inputs)

    def _run(self, entry, state: MeshState, keys, par_spec, par, inputs: dict) -> Field:
        geo_spec, geo = _split([state._cached(k, _never) for k in keys])
        static = (
            tuple(keys),
            geo_spec,
            par_spec,
            state.num_vertices,
            state.num_faces,
            np.dtype(state.dtype).name,
        )
        fn = self._jitted.get((entry.name, static[-1]))
        if fn is None:
            # a check runs its program a few times on small meshes: XLA's fastest compile
            fn = self._jitted[(entry.name, static[-1])] = jit_once(
                self._traced(entry), static_argnums=0
            )
        value = fn(static, geo, par, inputs)
        return Field(self._kinds[(entry.name, static)], value)

    def _traced(self, entry):
        def run(static, geo, par, inputs):
            keys, geo_spec, par_spec, V, F, dtype = static
            prepared = dict(zip(keys, _join(geo_spec, geo), strict=True))
            out = entry.apply(
                _Replay(prepared, V, F, np.dtype(dtype)), _join(par_spec, par), **inputs
            )
            value = _value(out)
            self._kinds[(entry.name, static)] = out.kind
            return value

        return run


def _signature(tree) -> tuple:
    """A hashable record of a pytree's structure, its leaves' dtypes and their shapes past the
    rows (vertex or face counts change from mesh to mesh; channels do not)."""
    leaves, treedef = jax.tree.flatten(tree)
    return treedef, tuple(
        (np.shape(a)[1:], str(getattr(a, "dtype", type(a).__name__))) for a in leaves
    )


def _value(out):
    if not isinstance(out, Field):
        raise TypeError(f"the operator must return a Field(kind, value), got {type(out)}")
    return out.value


def _never():
    raise _Unprepared("prepared geometry is built by the probe")

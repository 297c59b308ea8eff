"""A mesh as the equivariance harness sees it: positions, faces and a choice of tangent gauge.

Operators under test receive a :class:`MeshState` and build their geometry through it, so that a
gauge change (which has no effect on positions or faces) reaches every neighbourhood pytree, and so
that the same geometry is not rebuilt for every operator.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .._mesh import Mesh
from .._neighborhoods import VertexNeighborhood, to_jax


def regauge_neighborhood(nbhd: VertexNeighborhood, alpha: np.ndarray) -> VertexNeighborhood:
    """Express a neighbourhood in frames turned by ``alpha[p]`` at every vertex p.

    .. math:: \\log_p(q) \\to \\log_p(q)\\, e^{-i\\alpha_p}, \\qquad
              \\rho_{q\\to p} \\to \\rho_{q\\to p}\\, e^{i(\\alpha_q - \\alpha_p)}

    Args:
      nbhd: host :class:`~jmeshtex.VertexNeighborhood` (NumPy).
      alpha: ``[V]`` frame rotation angles (radians, counter-clockwise).

    Example:
      >>> import numpy as np
      >>> nb = VertexNeighborhood(np.array([[1], [0]]), np.ones((2, 1), bool), np.array([[1 + 0j], [1j]]),
      ...     np.ones((2, 1), complex), np.ones((2, 1)), np.ones(2), np.ones(2, bool))
      >>> np.round(regauge_neighborhood(nb, np.array([np.pi / 2, 0.0])).log[0, 0], 12)
      np.complex128(-1j)
    """
    alpha = np.asarray(alpha, dtype=np.float64)
    turn_p = np.exp(-1j * alpha)[:, None]
    turn_q = np.exp(1j * alpha)[nbhd.index]
    mask = np.asarray(nbhd.mask)
    log = np.asarray(nbhd.log) * turn_p
    transport = np.where(mask, np.asarray(nbhd.transport) * turn_q * turn_p, nbhd.transport)
    return nbhd._replace(log=log, transport=transport)


def _is_host(value) -> bool:
    """Whether every leaf of ``value`` is a NumPy array or a Python scalar (no JAX array)."""
    return not any(isinstance(leaf, jax.Array) for leaf in jax.tree.leaves(value))


class MeshState:
    """Positions, faces and a tangent gauge, with cached geometry built from them.

    Attributes:
      vertices: ``[V, 3]`` float64.
      faces: ``[F, 3]`` int64.
      gauge: ``[V]`` rotation of each vertex frame relative to the intrinsic gauge of
        :mod:`jmeshtex.geometry` (0 everywhere for a freshly built mesh).
      dtype: the real dtype the operators run in (``jnp.float32`` or ``jnp.float64``); None
        (default): float64 when JAX's x64 mode is on, else float32.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> s = MeshState(*icosahedron())
      >>> s.num_vertices, s.one_ring().index.shape[0]
      (12, 12)
    """

    num_vertices = Mesh.num_vertices  # the same record sizes as a Mesh
    num_faces = Mesh.num_faces

    def __init__(self, vertices, faces, *, gauge=None, dtype=None):
        self.vertices = np.asarray(vertices, dtype=np.float64)
        self.faces = np.asarray(faces, dtype=np.int64)
        V = self.vertices.shape[0]
        self.gauge = np.zeros(V) if gauge is None else np.asarray(gauge, dtype=np.float64)
        if dtype is None:
            dtype = jnp.float64 if jax.config.jax_enable_x64 else jnp.float32
        self.dtype = jnp.dtype(dtype)
        self._cache: dict[Any, Any] = {}  # values holding JAX arrays (in ``dtype``)
        self._host: dict[Any, Any] = {}  # host (NumPy) values: the same in every dtype

    @property
    def complex_dtype(self):
        return jnp.complex128 if self.dtype == jnp.float64 else jnp.complex64

    def with_(self, *, vertices=None, faces=None, gauge=None, dtype=None) -> MeshState:
        """A new state with some attributes replaced (and a fresh cache)."""
        return MeshState(
            self.vertices if vertices is None else vertices,
            self.faces if faces is None else faces,
            gauge=self.gauge if gauge is None else gauge,
            dtype=self.dtype if dtype is None else dtype,
        )

    def _cached(self, key, build):
        if key in self._cache:
            return self._cache[key]
        if key in self._host:
            return self._host[key]
        value = build()
        (self._host if _is_host(value) else self._cache)[key] = value
        return value

    # -- host geometry (NumPy, float64, in this state's gauge) ---------------------------------
    def host_one_ring(self, *, scale: str | float | None = "mean_edge") -> VertexNeighborhood:
        """One-ring :class:`~jmeshtex.VertexNeighborhood` as NumPy float64 arrays (``scale``: see
        :func:`~jmeshtex.geometry.one_ring_neighborhood`)."""
        from ..geometry import one_ring_neighborhood

        return self._cached(
            ("host_one_ring", scale),
            lambda: regauge_neighborhood(
                one_ring_neighborhood(self.vertices, self.faces, scale=scale), self.gauge
            ),
        )

    def host_knn(
        self, k: int = 8, *, scale: str | float | None = "mean_edge"
    ) -> VertexNeighborhood:
        """k-NN :class:`~jmeshtex.VertexNeighborhood` as NumPy float64 arrays (``scale``: see
        :func:`~jmeshtex.geometry.geodesic_knn_neighborhood`)."""
        from ..geometry import geodesic_knn_neighborhood

        return self._cached(
            ("host_knn", k, scale),
            lambda: regauge_neighborhood(
                geodesic_knn_neighborhood(self.vertices, self.faces, k=k, scale=scale), self.gauge
            ),
        )

    # -- JAX geometry in this state's dtype ---------------------------------------------------
    def one_ring(self, *, scale: str | float | None = "mean_edge") -> VertexNeighborhood:
        """One-ring :class:`~jmeshtex.VertexNeighborhood` as JAX arrays in ``dtype``.

        Args:
          scale: the unit of ``log``: ``"mean_edge"`` (default: this mesh's mean edge, recorded in
            ``log_unit``), a positive length, or None (mesh units), as
            :func:`~jmeshtex.geometry.one_ring_neighborhood`.
        """
        return self._cached(
            ("one_ring", scale), lambda: to_jax(self.host_one_ring(scale=scale), self.dtype)
        )

    def knn(self, k: int = 8, *, scale: str | float | None = "mean_edge") -> VertexNeighborhood:
        """k-NN geodesic :class:`~jmeshtex.VertexNeighborhood` as JAX arrays in ``dtype``.

        Args:
          k: slots per vertex, the vertex itself included.
          scale: the unit of ``log``: ``"mean_edge"`` (default: this mesh's mean edge, so filters
            see one edge as about 1 on every mesh the harness draws; recorded in ``log_unit``), a
            positive length, or None (mesh units), as
            :func:`~jmeshtex.geometry.geodesic_knn_neighborhood`.

        Example:
          >>> from jmeshtex.data import icosahedron
          >>> s = MeshState(*icosahedron())
          >>> nb = s.knn(6)
          >>> round(float(abs(nb.log[0, 1])), 6), s.knn(6, scale=None).log_unit is None
          (1.0, True)
        """
        return self._cached(
            ("knn", k, scale), lambda: to_jax(self.host_knn(k, scale=scale), self.dtype)
        )

    def face_neighborhood(self):
        """:class:`~jmeshtex.FaceNeighborhood` as JAX arrays."""
        from ..geometry import face_neighborhood

        return self._cached(
            "face_nbhd",
            lambda: to_jax(face_neighborhood(self.faces, self.num_vertices), self.dtype),
        )

    def points(self):
        """Vertex positions as a JAX array in ``dtype``."""
        return self._cached(
            "points", lambda: jax.device_put(np.asarray(self.vertices, dtype=self.dtype))
        )

    def _rebuild(self, key) -> bool:
        """Build the geometry one of this class's methods caches under ``key``; False for a key of
        :meth:`cached` (its build is the caller's), whose geometry only the operator can build."""
        if key in self._cache or key in self._host:
            return True
        name, args = (key[0], key[1:]) if isinstance(key, tuple) and key else (key, ())
        if name in ("one_ring", "host_one_ring") and len(args) == 1:
            getattr(self, name)(scale=args[0])
        elif name in ("knn", "host_knn") and len(args) == 2:
            getattr(self, name)(args[0], scale=args[1])
        elif name in ("face_nbhd", "points") and not args:
            {"face_nbhd": self.face_neighborhood, "points": self.points}[name]()
        else:
            return False
        return True

    def cached(self, key, build):
        """Cache any other per-state geometry (e.g. a hierarchy) under ``key``."""
        return self._cached(key, build)

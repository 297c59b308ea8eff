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
    def num_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def num_faces(self) -> int:
        return int(self.faces.shape[0])

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
    def host_one_ring(self) -> VertexNeighborhood:
        from ..geometry import one_ring_neighborhood

        return self._cached(
            "host_one_ring",
            lambda: regauge_neighborhood(
                one_ring_neighborhood(self.vertices, self.faces), self.gauge
            ),
        )

    def host_knn(self, k: int = 8) -> VertexNeighborhood:
        from ..geometry import geodesic_knn_neighborhood

        return self._cached(
            ("host_knn", k),
            lambda: regauge_neighborhood(
                geodesic_knn_neighborhood(self.vertices, self.faces, k=k), self.gauge
            ),
        )

    # -- JAX geometry in this state's dtype ---------------------------------------------------
    def one_ring(self) -> VertexNeighborhood:
        """One-ring :class:`~jmeshtex.VertexNeighborhood` as JAX arrays in ``dtype``."""
        return self._cached("one_ring", lambda: to_jax(self.host_one_ring(), self.dtype))

    def knn(self, k: int = 8) -> VertexNeighborhood:
        """k-NN geodesic :class:`~jmeshtex.VertexNeighborhood` as JAX arrays in ``dtype``."""
        return self._cached(("knn", k), lambda: to_jax(self.host_knn(k), self.dtype))

    def face_neighborhood(self):
        """:class:`~jmeshtex.FaceNeighborhood` as JAX arrays."""
        from ..geometry import face_neighborhood

        return self._cached(
            "face_nbhd",
            lambda: to_jax(face_neighborhood(self.faces, self.num_vertices), self.dtype),
        )

    def points(self):
        """Vertex positions as a JAX array in ``dtype``."""
        return self._cached("points", lambda: jnp.asarray(self.vertices, dtype=self.dtype))

    def cached(self, key, build):
        """Cache any other per-state geometry (e.g. a hierarchy) under ``key``."""
        return self._cached(key, build)

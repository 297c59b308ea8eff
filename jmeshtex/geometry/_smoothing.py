"""Taubin λ/μ smoothing with the uniform graph Laplacian (Taubin 1995): a smooth copy of a mesh that
keeps its size, the base that detail heights and displacements are measured from."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .._config import is_int
from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._types import Float, Int
from ._edges import unique_edges

#: Taubin's shrink and inflate factors: a pass band ``k_PB = 1/λ + 1/μ ≈ 0.11`` of the uniform
#: Laplacian (Taubin 1995 uses λ = 0.33, μ = −0.34)
TAUBIN_LAMBDA = 0.5
TAUBIN_MU = -0.53


def uniform_average(faces: Int[np.ndarray, "F 3"], num_vertices: int) -> sp.csr_matrix:
    """``D⁻¹A``: the one-ring mean as a sparse ``[V, V]`` matrix (rows of isolated vertices are 0).

    Args:
      faces: ``[F, 3]`` vertex indices.
      num_vertices: ``V``.

    Returns:
      The ``[V, V]`` CSR matrix whose row ``i`` averages the neighbours of vertex ``i``.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> v, f = icosahedron()
      >>> a = uniform_average(f, len(v))
      >>> bool(np.allclose(a.sum(axis=1), 1.0))
      True
    """
    e = unique_edges(np.asarray(faces, np.int64), num_vertices)
    a = sp.coo_matrix(
        (np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(num_vertices, num_vertices)
    ).tocsr()
    a = a + a.T
    deg = np.asarray(a.sum(axis=1)).ravel()
    return (sp.diags(1.0 / np.maximum(deg, 1)) @ a).tocsr()


def taubin_smooth(
    mesh: Mesh | tuple,
    *,
    steps: int | np.integer = 10,
    lam: float = TAUBIN_LAMBDA,
    mu: float = TAUBIN_MU,
) -> Float[np.ndarray, "V 3"]:
    """Taubin λ/μ smoothing of a mesh's vertices with the uniform Laplacian (no shrinkage).

    .. math:: x \\leftarrow (I + \\mu \\Delta)(I + \\lambda \\Delta)\\, x, \\qquad \\Delta = D^{-1}A - I

    repeated ``steps`` times (Taubin 1995, eq. 8). Frequencies ``k`` of ``−Δ`` are scaled by
    ``(1 − λk)(1 − μk)``: about 1 below the pass band ``1/λ + 1/μ`` (smooth shapes keep their
    size), below 1 above it.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])``.
      steps: number of λ/μ pairs.
      lam: the shrinking factor, ``0 < λ < 1``.
      mu: the inflating factor, ``−1 < μ < −λ``.

    Returns:
      ``[V, 3]`` float64 smoothed vertex positions.

    Raises:
      InputError: factors outside ``0 < λ < 1``, ``−1 < μ < −λ``, or ``steps`` not an integer
        ``>= 0``.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> v, f = icosphere(3)
      >>> r = np.linalg.norm(taubin_smooth((v, f), steps=10), axis=1)
      >>> bool(abs(r.mean() - 1) < 5e-3)                 # the unit sphere keeps its radius
      True
    """
    if not (0 < lam < 1 and -1 < mu < -lam):
        raise InputError(
            f"taubin_smooth needs 0 < lam < 1 and -1 < mu < -lam, got lam={lam}, mu={mu}"
        )
    if not is_int(steps, 0):
        raise InputError(f"steps must be an integer >= 0, got {steps!r}")
    mesh = as_mesh(mesh)
    x = np.asarray(mesh.vertices, np.float64)
    avg = uniform_average(mesh.faces, len(x))
    for _ in range(int(steps)):
        x = x + lam * (avg @ x - x)
        x = x + mu * (avg @ x - x)
    return x

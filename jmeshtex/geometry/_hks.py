"""Laplace–Beltrami eigenpairs and the heat kernel signature (Sun, Ovsjanikov & Guibas 2009).

The Laplacian is the robust (intrinsic Delaunay, mollified) cotangent Laplacian of Sharp & Crane
2020 (``robust_laplacian.mesh_laplacian``): it depends on edge lengths only, so everything computed
here is invariant under isometries that keep the mesh's edge lengths (rigid motions, folds along
mesh lines), and it stays well behaved on poor triangulations. MeshMatch (Chen et al. 2012) uses the
HKS as a per-vertex descriptor.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from .._config import is_int
from .._errors import InputError
from .._mesh import accepts_mesh
from .._types import ArrayLike, Float, Int
from ._validate import check_float_range, check_mesh_arrays

# relative threshold under which an eigenvalue counts as zero (one per connected component); the
# shift-invert solve returns the null space at ~1e-12 relative, the first non-zero mode is far above
_ZERO_EIGENVALUE = 1e-9


class LaplacianEigenpairs(NamedTuple):
    """Smallest eigenpairs of the generalised problem ``L φ = λ M φ``.

    Attributes:
      values: ``[k]`` eigenvalues in ascending order, ``>= 0`` (the first, 0, repeats once per
        connected component).
      vectors: ``[V, k]`` eigenvectors, M-orthonormal: ``vectors.T @ (mass[:, None] * vectors) = I``.
      mass: ``[V]`` lumped vertex areas (the diagonal of M).
    """

    values: Float[ArrayLike, " k"]
    vectors: Float[ArrayLike, "V k"]
    mass: Float[ArrayLike, " V"]


@accepts_mesh
def laplacian_eigenpairs(
    vertices: Float[ArrayLike, "V 3"],
    faces: Int[ArrayLike, "F 3"],
    *,
    k: int = 100,
    mollify_factor: float = 1e-5,
) -> LaplacianEigenpairs:
    """The ``k`` smallest eigenpairs of the robust cotangent Laplacian (Sharp & Crane 2020).

    .. math:: L \\varphi_i = \\lambda_i M \\varphi_i, \\qquad \\varphi_i^\\top M \\varphi_j = \\delta_{ij}

    ``L`` is the positive semi-definite weak Laplacian, ``M`` the lumped mass matrix. Solved with
    ``scipy.sparse.linalg.eigsh`` in shift-invert mode around a small negative shift (``L - σM`` is
    then positive definite and one sparse LU factorisation serves every iteration); the starting
    vector is fixed, so results are deterministic. Cost grows about linearly with V at k = 100
    (``docs/performance.md``), mostly ARPACK's reorthogonalisation.

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` triangles (non-manifold input is accepted: the robust Laplacian handles it).
      k: number of eigenpairs, ``1 <= k < V``.
      mollify_factor: intrinsic mollification of ``robust_laplacian`` (relative to mean edge length).

    Returns:
      :class:`LaplacianEigenpairs`.

    Raises:
      InputError: ``k`` out of range; mesh array errors from the shared checks.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> ev = laplacian_eigenpairs(*icosphere(2), k=4)
      >>> [round(float(x), 1) for x in ev.values]  # l(l+1) on the unit sphere: 0, 2, 2, 2
      [0.0, 2.0, 2.0, 2.0]
    """
    import robust_laplacian
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    v, f = check_mesh_arrays(vertices, faces)
    check_float_range(v, f)  # SuperLU fails on the overflowing or vanishing mass matrix outside
    n = len(v)
    if not is_int(k, 1) or k >= n:
        raise InputError(
            f"k={k!r} eigenpairs requested for a mesh with V={n} vertices: k must be an integer with "
            f"1 <= k < V (ARPACK cannot return all V of them). Pass a smaller k or a finer mesh."
        )
    L, M = robust_laplacian.mesh_laplacian(v, f, mollify_factor=mollify_factor)
    mass = np.asarray(M.diagonal(), dtype=np.float64)
    # shift just below zero relative to the spectrum's scale (mean diagonal ratio ~ 1/h^2)
    sigma = -1e-8 * float(np.mean(L.diagonal() / mass))
    # factor L - σM once, ourselves, with SuperLU's COLAMD column ordering: on mesh Laplacians the
    # minimum-degree orderings (MMD_AT_PLUS_A, MMD_ATA) have a fill cliff, 300x slower at 35K
    # vertices (docs/performance.md)
    lu = spla.splu(sp.csc_matrix(L - sigma * M), permc_spec="COLAMD")
    shift_invert = spla.LinearOperator(L.shape, matvec=lu.solve, dtype=np.float64)
    v0 = np.random.default_rng(0).standard_normal(n)  # fixed start vector: deterministic output
    values, vectors = spla.eigsh(
        sp.csc_matrix(L),
        k=k,
        M=sp.csc_matrix(M),
        sigma=sigma,
        which="LM",
        v0=v0,
        OPinv=shift_invert,
    )
    order = np.argsort(values)
    values, vectors = values[order], vectors[:, order]
    vectors = vectors / np.sqrt(np.einsum("vk,v,vk->k", vectors, mass, vectors))
    return LaplacianEigenpairs(values=np.maximum(values, 0.0), vectors=vectors, mass=mass)


def hks_times(values: Float[ArrayLike, " k"], *, num: int = 8) -> Float[ArrayLike, " T"]:
    """Log-spaced HKS times from the spectrum (the range Sun et al. 2009 use in their experiments).

    .. math:: t \\in [\\, 4 \\ln 10 / \\lambda_{\\max},\\ 4 \\ln 10 / \\lambda_1 \\,]

    where ``λ_1`` is the smallest non-zero eigenvalue: at ``t_min`` the truncated modes contribute
    less than ``e^{-4 ln 10} = 10^{-4}`` of their weight, at ``t_max`` the signature is dominated by
    the first non-constant mode.

    Args:
      values: ``[k]`` ascending eigenvalues (from :func:`laplacian_eigenpairs`).
      num: number of times ``T``.

    Returns:
      ``[T]`` increasing times.

    Example:
      >>> t = hks_times(np.array([0.0, 2.0, 6.0, 12.0]), num=3)
      >>> bool(np.isclose(t[0], 4 * np.log(10) / 12)), bool(np.isclose(t[-1], 4 * np.log(10) / 2))
      (True, True)
    """
    values = np.asarray(values, dtype=np.float64)
    if num < 1:
        raise InputError(f"num must be >= 1 HKS times, got {num}")
    nonzero = values[values > _ZERO_EIGENVALUE * values.max()] if values.size else values
    if nonzero.size == 0:
        raise InputError(
            "all computed eigenvalues are zero (as many connected components as eigenpairs): "
            "pass a larger k or explicit times"
        )
    return np.geomspace(4 * np.log(10) / nonzero.max(), 4 * np.log(10) / nonzero.min(), num)


@accepts_mesh
def heat_kernel_signature(
    vertices: Float[ArrayLike, "V 3"],
    faces: Int[ArrayLike, "F 3"],
    *,
    times: Float[ArrayLike, " T"] | Sequence[float] | None = None,
    k: int = 100,
    eigenpairs: LaplacianEigenpairs | None = None,
) -> Float[ArrayLike, "V T"]:
    """Heat kernel signature of every vertex at several times (Sun et al. 2009, the HKS definition).

    .. math:: \\mathrm{HKS}(x, t) = k_t(x, x) = \\sum_{i=0}^{k-1} e^{-\\lambda_i t}\\, \\varphi_i(x)^2

    Positive (the constant mode alone gives ``1/area``), decreasing in ``t``, and intrinsic: it is
    unchanged by rigid motions and by bending that keeps edge lengths. Units are 1/area; rescale the
    mesh (``rescale_to_mean_edge``) before comparing signatures of differently sized meshes.

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` triangles.
      times: ``[T]`` positive diffusion times; default 8 log-spaced times from the spectrum
        (:func:`hks_times`).
      k: number of eigenpairs, ``1 <= k < V`` (ignored when ``eigenpairs`` is given).
      eigenpairs: precomputed :func:`laplacian_eigenpairs` of this mesh, to reuse a solve.

    Returns:
      ``[V, T]`` float64 signature, one column per time.

    Raises:
      InputError: ``k >= V``, non-positive or non-finite times, eigenpairs of another mesh.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> h = heat_kernel_signature(*icosphere(2), k=9)
      >>> h.shape, bool((h > 0).all()), bool((np.diff(h, axis=1) < 0).all())
      ((162, 8), True, True)
    """
    if eigenpairs is None:
        ev = laplacian_eigenpairs(vertices, faces, k=k)
    else:
        ev = eigenpairs
        n = len(check_mesh_arrays(vertices, faces)[0])
        if ev.vectors.shape[0] != n:
            raise InputError(
                f"eigenpairs are of a mesh with {ev.vectors.shape[0]} vertices, this mesh has {n}: "
                "pass the laplacian_eigenpairs of the same mesh"
            )
    if times is None:
        times = hks_times(ev.values)
    times = np.asarray(times, dtype=np.float64)
    if times.ndim != 1 or times.size == 0 or not np.all(np.isfinite(times)) or np.any(times <= 0):
        raise InputError(
            f"times must be a non-empty 1-D array of positive finite numbers, got {times}"
        )
    return (ev.vectors**2) @ np.exp(-np.outer(ev.values, times))

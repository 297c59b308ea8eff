"""Coherent field latents: the common phase of flat rings synchronised over the k-NN connection.

Beyond the paper (docs/results.md, "FLDM": coherent latents). An FL-VAE encoder is equivariant, so on
a ring whose colour is flat (rotation-symmetric) it must break the symmetry to output a nonzero
``μ``, and the phase it picks is the direction of the sample and triangulation asymmetry: noise from
vertex to vertex. A flat ring decodes to the same colours whatever that phase (the decoded field
around ``p`` turns with ``μ_p``, and a flat field is unchanged by a turn), so the phase can be chosen
freely there; textured rings carry edge orientation in it and keep theirs.

:func:`synchronize_phases` multiplies every free vertex's latents (all channels together, so the
relative phases between channels, which the colours depend on, stay) by a unit ``u_p`` that
maximises the transported agreement

.. math:: \\sum_{p}\\sum_{q \\in N(p)} \\mathrm{Re}\\; u_p\\,\\overline{u_q}\\; w_{pq},
   \\qquad w_{pq} = \\sum_c z_{pc}\\,\\overline{\\rho_{q\\to p}\\, z_{qc}},

by a shifted power iteration with the pinned vertices held at ``u = 1``. :func:`ring_color_spread`
measures which rings are flat: the root-mean-square deviation of the colours at fixed points of the
ring (the deterministic per-wedge rule of :func:`jmeshtex.fl.core.one_ring_samples`) from their
mean, in [0, 1] RGB units.
"""

from __future__ import annotations

import numpy as np

from .._errors import InputError
from .._mesh import Mesh, as_mesh

#: default flat-ring threshold of :func:`ring_color_spread` (RGB RMS; measured in
#: ``docs/results.md``, the phase-sync study)
FLAT_SPREAD = 0.02


def ring_color_spread(mesh: Mesh, colors) -> np.ndarray:
    """Root-mean-square deviation of the colours in every one-ring from their mean, ``[V]``.

    Args:
      mesh: the (re-triangulated) mesh whose rings are measured.
      colors: a :class:`jmeshtex.fl.core.SurfaceColors` to read (the original surface's, for a copy).

    Returns:
      ``[V]`` float64, ``sqrt(mean_s |c_s − c̄|²)`` over the 6 fixed points per wedge (3 channels
      summed); 0 on a flat ring.

    Example:
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.fl.core import surface_colors
      >>> v, f = grid(4)
      >>> m = Mesh(v, f, vertex_colors=np.full((25, 3), 0.5))
      >>> float(ring_color_spread(m, surface_colors(m)).max())
      0.0
    """
    from ..fl.core import one_ring_samples

    mesh = as_mesh(mesh)
    s = one_ring_samples(mesh.vertices, mesh.faces, 1, rng=None)
    points = np.einsum(
        "vsk,vskd->vsd", s.bary, np.asarray(mesh.vertices, np.float64)[mesh.faces[s.face]]
    )
    if colors.faces.shape == mesh.faces.shape and np.array_equal(colors.faces, mesh.faces):
        rgb = colors.at_barycentric(s.face.reshape(-1), s.bary.reshape(-1, 3))
    else:
        rgb = colors.at_points(points.reshape(-1, 3))
    rgb = rgb.reshape(*s.face.shape, 3)
    w = s.mask.astype(np.float64)[..., None]
    n = np.maximum(w.sum(1), 1.0)
    mean = (rgb * w).sum(1) / n
    return np.sqrt((((rgb - mean[:, None]) ** 2) * w).sum((1, 2)) / n[:, 0])


def synchronize_phases(
    z: np.ndarray,
    neighborhood,
    *,
    pinned: np.ndarray | None = None,
    iterations: int = 200,
) -> np.ndarray:
    """Turn the latents of the free vertices so that neighbours agree after transport (module docstring).

    Args:
      z: ``[V, d]`` complex latents in the frames of ``neighborhood``.
      neighborhood: a :class:`~jmeshtex.VertexNeighborhood` on the same ``V`` vertices (``index``,
        ``mask``, ``transport``; the self slot is skipped), e.g. ``denoiser_geometry(mesh).fine``.
      pinned: ``[V]`` bool, vertices that keep their phase (textured rings); None: none pinned.
      iterations: power-iteration sweeps.

    Returns:
      ``[V, d]`` complex, ``u_p z_p`` with ``|u_p| = 1`` (``u_p = 1`` where pinned); every vertex's
      moduli and relative phases between channels unchanged.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> from jmeshtex.fldm.core import denoiser_geometry, transported_phase_coherence
      >>> nb = denoiser_geometry(icosphere(2), knn=7).fine
      >>> rng = np.random.default_rng(0)
      >>> z = np.exp(2j * np.pi * rng.random((162, 1))) * np.array([[1.0, 0.5j]])
      >>> float(transported_phase_coherence(z, nb)) < 0.2
      True
      >>> float(transported_phase_coherence(synchronize_phases(z, nb), nb)) > 0.9
      True
    """
    z = np.asarray(z)
    if z.ndim != 2 or not np.iscomplexobj(z):
        raise InputError(f"synchronize_phases: z must be complex [V, d], got {z.dtype} {z.shape}")
    index = np.asarray(neighborhood.index)
    if index.shape[0] != z.shape[0]:
        raise InputError(
            f"synchronize_phases: the neighbourhood has {index.shape[0]} vertices, z has {z.shape[0]}"
        )
    V = z.shape[0]
    mask = np.asarray(neighborhood.mask).astype(bool) & (index != np.arange(V)[:, None])
    rho = np.asarray(neighborhood.transport)
    free = np.ones(V, bool) if pinned is None else ~np.asarray(pinned, bool).reshape(V)
    zc = z.astype(np.complex128)
    w = np.einsum("pc,pkc->pk", zc, np.conj(rho[..., None] * zc[index])) * mask  # [V, K]
    rows = np.repeat(np.arange(V), index.shape[1])
    cols = index.reshape(-1)
    wf = w.reshape(-1)
    shift = np.abs(w).sum(1)
    np.add.at(shift, cols, np.abs(wf))
    u = np.ones(V, np.complex128)
    for _ in range(int(iterations)):
        # X_p = Σ_out u_q conj(w_pq) + Σ_in u_q w_qp, plus a shift that damps oscillation
        x = (np.conj(w) * u[index]).sum(1)
        np.add.at(x, cols, wf * u[rows])
        x = x + shift * u
        mod = np.abs(x)
        new = np.where(mod > 1e-300, x / np.maximum(mod, 1e-300), u)
        u = np.where(free, new, 1.0 + 0j)
    return (z * u[:, None].astype(z.dtype)).astype(z.dtype)

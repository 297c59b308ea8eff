"""Trivial per-vertex codecs that bound an FL-VAE reconstruction from below (the oracle rows in ``docs/results.md``).

A field latent stores ``d`` complex numbers per vertex; the simplest codec stores 3 real ones, a
colour per vertex, and interpolates it linearly over each triangle (P1). Two such codecs on the
latent mesh, scored on the same texels as the model:

- :func:`p1_interpolate` of the *true* colour sampled at each vertex (the "P1 oracle": what a
  decoder that only learnt the vertex colour would give);
- :func:`p1_least_squares`: the vertex colours minimising the squared error over the atlas texels
  (the best any P1 field can do, in PSNR).

An FL-VAE that does not beat them carries no more than a vertex colour. :func:`p1_baselines` builds
both atlases for a :class:`~jmeshtex.fl.Reconstruction`; :func:`baseline_metrics` scores them, and
the best flat colour (the used texels' mean: the do-nothing codec), like the reconstruction.
"""

from __future__ import annotations

import numpy as np

from .._config import is_int
from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._types import Float, Int
from ._colors import surface_colors


def _check_texels(corners, bary, name: str) -> tuple[np.ndarray, np.ndarray]:
    corners = np.asarray(corners)
    bary = np.asarray(bary, np.float64)
    if corners.ndim != 2 or corners.shape[1] != 3 or bary.shape != corners.shape:
        raise InputError(
            f"{name}: corners and bary must both be [N, 3], got {corners.shape} and {bary.shape}"
        )
    if not np.issubdtype(corners.dtype, np.integer):
        raise InputError(f"{name}: corners must be integer vertex ids, got {corners.dtype}")
    if not np.isfinite(bary).all():
        raise InputError(f"{name}: bary contains NaN or inf")
    return corners, bary


def p1_interpolate(
    vertex_colors: Float[np.ndarray, "V C"],
    corners: Int[np.ndarray, "N 3"],
    bary: Float[np.ndarray, "N 3"],
) -> Float[np.ndarray, "N C"]:
    """Linear (P1) interpolation of per-vertex colours at points inside triangles.

    .. math:: c(x) = \\sum_{k=1}^{3} b_k(x)\\, c_{v_k}

    Args:
      vertex_colors: ``[V, C]`` one colour per vertex.
      corners: ``[N, 3]`` vertex ids of the triangle holding each point.
      bary: ``[N, 3]`` barycentric coordinates of the points in those triangles.

    Returns:
      ``[N, C]`` float64 colours.

    Raises:
      InputError: shapes that do not match, or vertex ids out of range.

    Example:
      >>> c = np.array([[0.0], [1.0], [0.5]])
      >>> p1_interpolate(c, np.array([[0, 1, 2]]), np.array([[0.5, 0.25, 0.25]])).tolist()
      [[0.375]]
    """
    corners, bary = _check_texels(corners, bary, "p1_interpolate")
    colors = np.asarray(vertex_colors, np.float64)
    if colors.ndim != 2:
        raise InputError(f"p1_interpolate: vertex_colors must be [V, C], got {colors.shape}")
    if corners.size and (corners.min() < 0 or corners.max() >= len(colors)):
        raise InputError(
            f"p1_interpolate: corners must lie in [0, {len(colors)}), got "
            f"{corners.min()}..{corners.max()}"
        )
    return np.einsum("nk,nkc->nc", bary, colors[corners])


def p1_least_squares(
    corners: Int[np.ndarray, "N 3"],
    bary: Float[np.ndarray, "N 3"],
    target: Float[np.ndarray, "N C"],
    *,
    num_vertices: int,
    damping: float = 1e-6,
) -> Float[np.ndarray, "V C"]:
    """Per-vertex colours whose P1 interpolation best fits ``target`` in the least-squares sense.

    .. math:: \\min_c \\sum_n \\Big\\lVert \\sum_k b_{nk} c_{v_{nk}} - t_n \\Big\\rVert^2
       + \\epsilon \\sum_v \\lVert c_v - \\bar t \\rVert^2

    The small ``ε`` (``damping`` times the mean squared barycentric weight per vertex) only decides
    the colour of vertices that no point touches (they get the mean target colour ``t̄``); it
    changes the fit elsewhere by a relative ``O(ε)``.

    Args:
      corners: ``[N, 3]`` vertex ids of the triangle holding each point (e.g. each atlas texel).
      bary: ``[N, 3]`` barycentric coordinates of the points.
      target: ``[N, C]`` colours to fit.
      num_vertices: ``V``, the number of vertices of the mesh.
      damping: ``ε`` relative to the data term (> 0).

    Returns:
      ``[V, C]`` float64 colours; :func:`p1_interpolate` of them is the fit.

    Raises:
      InputError: shapes that do not match, ids out of range, no points, ``damping <= 0``.

    Example:
      >>> corners = np.array([[0, 1, 2]] * 3)
      >>> bary = np.eye(3)
      >>> p1_least_squares(corners, bary, np.array([[0.0], [1.0], [0.5]]), num_vertices=3).round(4).tolist()
      [[0.0], [1.0], [0.5]]
    """
    import scipy.sparse
    import scipy.sparse.linalg

    corners, bary = _check_texels(corners, bary, "p1_least_squares")
    target = np.asarray(target, np.float64)
    if target.ndim != 2 or len(target) != len(corners):
        raise InputError(
            f"p1_least_squares: target must be [N, C] with N = {len(corners)}, got {target.shape}"
        )
    if len(corners) == 0:
        raise InputError("p1_least_squares: no points to fit")
    if not is_int(num_vertices, 1):
        raise InputError(
            f"p1_least_squares: num_vertices must be an int >= 1, got {num_vertices!r}"
        )
    if corners.min() < 0 or corners.max() >= num_vertices:
        raise InputError(
            f"p1_least_squares: corners must lie in [0, {num_vertices}), got "
            f"{corners.min()}..{corners.max()}"
        )
    if not damping > 0:
        raise InputError(f"p1_least_squares: damping must be > 0, got {damping}")
    n = len(corners)
    rows = np.repeat(np.arange(n), 3)
    a = scipy.sparse.csr_matrix(
        (bary.ravel(), (rows, corners.ravel())), shape=(n, int(num_vertices))
    )
    ata = (a.T @ a).tocsc()
    eps = float(damping) * max(float(ata.diagonal().mean()), 1e-300)
    mean = target.mean(0)
    rhs = a.T @ target + eps * mean[None, :]
    system = ata + eps * scipy.sparse.identity(int(num_vertices), format="csc")
    solve = scipy.sparse.linalg.factorized(system)
    return np.stack([solve(rhs[:, c]) for c in range(target.shape[1])], axis=1)


def p1_baselines(mesh: Mesh, result) -> dict[str, np.ndarray]:
    """The P1 oracle and the least-squares P1 fit on a reconstruction's latent mesh, as atlases.

    Args:
      mesh: the textured reference given to :func:`~jmeshtex.fl.reconstruct`.
      result: its :class:`~jmeshtex.fl.Reconstruction` (the texels' points on the latent mesh).

    Returns:
      ``{"p1_oracle": [H, W, 3], "p1_fit": [H, W, 3]}`` atlases clipped to [0, 1] (0 on unused
      texels), to compare with ``result.target`` over ``result.valid`` like ``result.texture``.

    Example:
      >>> import jax
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.fl import Config, init, reconstruct
      >>> v, f = grid(3)
      >>> mesh = Mesh(v, f, uv=v[f][..., :2], texture=np.full((16, 16, 3), 0.5, np.float32))
      >>> r = reconstruct(init(Config(num_samples=4), key=jax.random.key(0)), mesh, key=jax.random.key(1), lpips=False)
      >>> out = p1_baselines(mesh, r)
      >>> sorted(out), float(np.abs(out["p1_oracle"] - r.target).max()) < 1e-6
      (['p1_fit', 'p1_oracle'], True)
    """
    mesh = as_mesh(mesh, what="mesh")
    if result.texels is None:
        raise InputError(
            "p1_baselines needs a Reconstruction from fl.reconstruct (with its texels)"
        )
    row, col, face, bary = result.texels
    latent = result.latent_mesh
    corners = np.asarray(latent.faces)[face]
    colors = surface_colors(mesh)
    if latent is mesh:
        at_vertex = colors.at_points(np.asarray(mesh.vertices, np.float64))
    else:
        at_vertex = colors.at_points(np.asarray(latent.vertices, np.float64))
    fitted = p1_least_squares(
        corners, bary, result.target[row, col], num_vertices=latent.num_vertices
    )
    out = {}
    for name, vc in (("p1_oracle", at_vertex), ("p1_fit", fitted)):
        atlas = np.zeros_like(result.target)
        atlas[row, col] = np.clip(p1_interpolate(vc, corners, bary), 0.0, 1.0)
        out[name] = atlas
    return out


def baseline_metrics(mesh: Mesh, result, *, lpips: bool = True) -> dict[str, dict]:
    """PSNR / DSSIM / LPIPS of the P1 oracle, the least-squares P1 fit and the best flat colour.

    Scored like ``result.metrics`` (:func:`~jmeshtex.fl.core.atlas_metrics` on the same texels),
    so the three bound the reconstruction: the flat colour from below (no texture at all), the P1
    codecs from what one colour per latent vertex carries.

    Args:
      mesh: the textured reference given to :func:`~jmeshtex.fl.reconstruct`.
      result: its :class:`~jmeshtex.fl.Reconstruction`.
      lpips: score LPIPS-VGG too.

    Returns:
      ``{"p1_oracle": {...}, "p1_fit": {...}, "flat_color": {...}}``, each a metrics dict.

    Example:
      >>> import jax
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.fl import Config, init, reconstruct
      >>> v, f = grid(3)
      >>> tex = np.full((16, 16, 3), 0.5, np.float32); tex[:, :8] = 0.2
      >>> mesh = Mesh(v, f, uv=v[f][..., :2], texture=tex)
      >>> r = reconstruct(init(Config(num_samples=4), key=jax.random.key(0)), mesh, key=jax.random.key(1), lpips=False)
      >>> m = baseline_metrics(mesh, r, lpips=False)
      >>> sorted(m), m["p1_fit"]["psnr"] > m["flat_color"]["psnr"]
      (['flat_color', 'p1_fit', 'p1_oracle'], True)
    """
    from ._reconstruct import atlas_metrics

    atlases = p1_baselines(mesh, result)
    valid = np.asarray(result.valid, bool)
    flat = np.zeros_like(result.target)
    flat[valid] = result.target[valid].mean(0)
    atlases["flat_color"] = flat
    return {
        name: atlas_metrics(a, result.target, valid, lpips=lpips) for name, a in atlases.items()
    }

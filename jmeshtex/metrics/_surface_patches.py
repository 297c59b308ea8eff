"""Texture statistics of a mesh texture measured on the surface: geodesic patches at the texel scale.

Renders magnify texels, mix in shading and silhouettes, and let the mean colour rule an uncentred
Gram matrix, so render metrics cannot tell a synthesised texture from a flat or permuted one at the
sizes a CPU affords. This measure reads the texture where the synthesis sees it: ``P`` patches of
``S × S`` pixels, each resampled on the surface with the exponential map (pixel ``(i, j)`` is the
end of the straightest geodesic (:func:`jmeshtex.geometry.trace_geodesics`) from the patch centre
along ``(j − c)·t + (i − c)·d``, ``c = (S − 1)/2``, in units of ``step``; ``t`` a global direction
projected on the surface, ``d = −i·t``, the surface CNN's frames), and compares them with crops of
the exemplar at the same scale:

- :func:`patch_gram_distance`: the squared Frobenius distance between the patch sets' mean VGG
  Gram matrices (``G = FᵀF / hw``), per layer divided by ``C²``, summed over layers;
- :func:`patch_spectrum_distance`: the L1 distance between the patch sets' mean log radial power
  spectra of luminance (network-independent);
- :class:`SurfacePatches` reports how many UV charts every patch reads (seam crossings).

:func:`surface_patch_table` scores a texture with its baselines (flat colour, permuted texels,
initial noise, the exemplar tiled in UV space) and the exemplar-crop floor (a second, independent
set of exemplar crops).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Float, Int
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from ..geometry import (
    global_direction_field,
    project_direction,
    sample_texture,
    trace_geodesics,
    tracer_geometry,
)
from ._vgg import VGGWeights, vgg_features
from ._vgg_load import load_vgg16

#: the Gram layers of :func:`patch_gram_distance`: every ReLU of the first three VGG blocks (a
#: 32-pixel patch is 8 pixels wide at block 3)
PATCH_GRAM_LAYERS = ("relu1_1", "relu1_2", "relu2_1", "relu2_2", "relu3_1", "relu3_2", "relu3_3")


class SurfacePatches(NamedTuple):
    """Where the pixels of surface patches lie in the texture (reusable for any texture on the UVs).

    Attributes:
      uv: ``[P, S, S, 2]`` texture coordinates of every patch pixel.
      face: ``[P]`` the centre's face.
      charts: ``[P]`` int64 number of distinct UV charts a patch reads (1: no seam crossed).
      off_chart: ``[P]`` share of a patch's pixels read in another chart than its centre's.
      stopped: ``[P]`` share of a patch's walks that hit a mesh boundary.
    """

    uv: Float[np.ndarray, "P S S 2"]
    face: Int[np.ndarray, " P"]
    charts: Int[np.ndarray, " P"]
    off_chart: Float[np.ndarray, " P"]
    stopped: Float[np.ndarray, " P"]

    def sample(self, texture: Float[np.ndarray, "H W 3"]) -> Float[np.ndarray, "P S S 3"]:
        """The patches of ``texture`` (bilinear, :func:`jmeshtex.geometry.sample_texture`)."""
        return np.asarray(sample_texture(np.asarray(texture, np.float64), self.uv), np.float64)


def uv_charts(faces: Int[np.ndarray, "F 3"], uv: Float[np.ndarray, "F 3 2"]) -> np.ndarray:
    """The UV chart of every face: faces sharing an edge with the same UVs at both ends are glued.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(1)
      >>> uv = v[f][..., :2].copy()
      >>> uv_charts(f, uv).tolist(), uv_charts(f, uv + [[[0.0, 0]], [[2, 0]]]).tolist()
      ([0, 0], [0, 1])
    """
    faces = np.asarray(faces, np.int64)
    F = len(faces)
    key = np.round(np.asarray(uv, np.float64) * 1e9).astype(np.int64)  # [F, 3, 2]
    a, b = [0, 1, 2], [1, 2, 0]
    va, vb = faces[:, a].ravel(), faces[:, b].ravel()
    ua, ub = key[:, a].reshape(-1, 2), key[:, b].reshape(-1, 2)
    swap = va > vb
    lo = np.where(swap, vb, va)
    hi = np.where(swap, va, vb)
    ulo = np.where(swap[:, None], ub, ua)
    uhi = np.where(swap[:, None], ua, ub)
    rows = np.column_stack([lo, hi, ulo, uhi])
    _, edge = np.unique(rows, axis=0, return_inverse=True)
    face = np.repeat(np.arange(F), 3)
    order = np.argsort(edge, kind="stable")
    e, fo = edge.ravel()[order], face[order]
    same = e[1:] == e[:-1]
    graph = coo_matrix((np.ones(same.sum()), (fo[:-1][same], fo[1:][same])), shape=(F, F))
    return connected_components(graph, directed=False)[1].astype(np.int64)


def surface_patches(
    mesh: Mesh,
    *,
    num: int,
    step: float,
    key: jax.Array,
    size: int = 32,
    frame_vector=(1.0, 0.0, 0.0),
) -> SurfacePatches:
    """Place ``num`` geodesic patches of ``size × size`` pixels, ``step`` world units apart, on a mesh.

    Centres are uniform on the surface (area-weighted faces, uniform barycentrics). Pixel ``(i, j)``
    of a patch is the end of the straightest geodesic from its centre along
    ``(j − c) t + (i − c) d`` (``c = (size − 1)/2``), ``|·|·step`` long: the exponential map in the
    frame ``t`` = ``frame_vector`` projected on the surface (the surface CNN's ``"global"`` frames,
    Kovács et al. 2024, Sec. 4.2), ``d = −i·t`` (row grows clockwise from ``t`` seen from outside).

    Args:
      mesh: a :class:`~jmeshtex.Mesh` with ``uv`` ``[F, 3, 2]``.
      num: number of patches.
      step: world length of one patch pixel (the texel size, for the texture's own scale).
      key: PRNG key of the centres.
      size: patch side in pixels.
      frame_vector: the world vector the patch frames follow.

    Returns:
      :class:`SurfacePatches`.

    Raises:
      InputError: no UVs, ``num``/``size`` < 1 or ``step`` not positive.

    Example:
      >>> import jax
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> v, f = grid(4)
      >>> p = surface_patches(Mesh(v, f, uv=v[f][..., :2]), num=2, step=1 / 64, size=8,
      ...                     key=jax.random.key(0))
      >>> p.uv.shape, p.charts.tolist()
      ((2, 8, 8, 2), [1, 1])
    """
    mesh = as_mesh(mesh)
    if mesh.uv is None:
        raise InputError("surface_patches: the mesh has no UVs; give a Mesh with uv [F, 3, 2]")
    if num < 1 or size < 1 or not step > 0:
        raise InputError(
            f"surface_patches: need num >= 1, size >= 1 and step > 0, got {num}, {size}, {step}"
        )
    v, f = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    geometry = tracer_geometry(v, f)
    tri = v[f]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(normal, axis=1)
    rng = np.random.default_rng(np.asarray(jax.random.key_data(key)).ravel())
    face = rng.choice(len(f), size=num, p=area / area.sum())
    r = rng.uniform(size=(num, 2))
    flip = r.sum(axis=1) > 1
    r[flip] = 1 - r[flip]
    bary = np.column_stack([1 - r.sum(axis=1), r])
    # the frame t in each centre face's tracer frame (x along edge 01, y = n × x)
    p = np.asarray(frame_vector, np.float64)
    field = global_direction_field(v, f, primary=p, secondary=_second(p))
    n = normal[face] / area[face, None]
    t3 = project_direction(
        np.einsum("nk,nkd->nd", bary, field[f[face]]), n, primary=p, secondary=_second(p)
    )
    x = tri[face, 1] - tri[face, 0]
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(n, x)
    t = np.sum(t3 * x, axis=1) + 1j * np.sum(t3 * y, axis=1)
    t /= np.abs(t)
    d = -1j * t
    c = (size - 1) / 2
    jj, ii = np.meshgrid(np.arange(size) - c, np.arange(size) - c)  # [S, S]: column j, row i
    offset = jj.ravel()[None] * t[:, None] + ii.ravel()[None] * d[:, None]  # [P, S²]
    length = np.abs(offset) * step
    unit = np.where(
        np.abs(offset) > 0, offset / np.where(offset == 0, 1, np.abs(offset)), t[:, None]
    )
    res = trace_geodesics(
        v,
        f,
        np.repeat(face, size * size),
        np.repeat(bary, size * size, axis=0),
        unit.ravel(),
        length.ravel(),
        geometry=geometry,
    )
    uv_f = np.asarray(mesh.uv, np.float64)[res.face]  # [P S², 3, 2]
    uv = np.einsum("nk,nkd->nd", res.bary, uv_f).reshape(num, size, size, 2)
    chart = uv_charts(f, mesh.uv)
    pix_chart = chart[res.face].reshape(num, size * size)
    charts = np.array([len(np.unique(row)) for row in pix_chart], np.int64)
    off = (pix_chart != chart[face][:, None]).mean(axis=1)
    stopped = np.asarray(res.stopped).reshape(num, size * size).mean(axis=1)
    return SurfacePatches(uv, face, charts, off, stopped)


def _second(p: np.ndarray) -> np.ndarray:
    """A fallback direction not parallel to ``p`` (the global frames' secondary vector)."""
    e = np.zeros(3)
    e[int(np.argmin(np.abs(p)))] = 1.0
    return e


def exemplar_crops(
    exemplar: Float[np.ndarray, "H W 3"],
    *,
    num: int,
    key: jax.Array,
    size: int = 32,
    scale: float = 1.0,
) -> Float[np.ndarray, "P S S 3"]:
    """``num`` random ``size × size`` crops of an exemplar at ``scale`` texels per exemplar pixel.

    A crop covers ``size / scale`` exemplar pixels, resampled bilinearly to ``size`` pixels (scale 1:
    plain crops).

    Example:
      >>> import jax
      >>> exemplar_crops(np.zeros((40, 40, 3)), num=3, key=jax.random.key(0), size=8).shape
      (3, 8, 8, 3)
    """
    ex = np.asarray(exemplar, np.float64)
    H, W = ex.shape[:2]
    span = size / scale
    if span > min(H, W):
        raise InputError(
            f"exemplar_crops: a {size}-pixel crop at scale {scale} spans {span:.1f} exemplar pixels, "
            f"more than the {H}×{W} exemplar; use a smaller size or a larger scale"
        )
    rng = np.random.default_rng(np.asarray(jax.random.key_data(key)).ravel())
    y0 = rng.uniform(0, H - span, size=num)
    x0 = rng.uniform(0, W - span, size=num)
    g = (np.arange(size) + 0.5) / scale  # pixel centres, exemplar pixels from the crop corner
    ys = y0[:, None] + g[None]  # [P, S]
    xs = x0[:, None] + g[None]
    u = np.broadcast_to(xs[:, None, :] / W, (num, size, size))
    vv = np.broadcast_to(1.0 - ys[:, :, None] / H, (num, size, size))
    return np.asarray(sample_texture(ex, np.stack([u, vv], axis=-1)), np.float64)


def tiled_exemplar(
    exemplar: Float[np.ndarray, "E F 3"], shape: tuple[int, int], *, scale: float = 1.0
) -> Float[np.ndarray, "H W 3"]:
    """The exemplar repeated over an ``H × W`` texture image at ``scale`` texels per exemplar pixel,
    ignoring the surface (nearest exemplar pixel): the UV-tiled baseline of
    :func:`surface_patch_table`.

    Example:
      >>> ex = np.arange(4.0).reshape(2, 2, 1).repeat(3, axis=2)
      >>> tiled_exemplar(ex, (3, 5))[..., 0].tolist()
      [[0.0, 1.0, 0.0, 1.0, 0.0], [2.0, 3.0, 2.0, 3.0, 2.0], [0.0, 1.0, 0.0, 1.0, 0.0]]
    """
    ex = np.asarray(exemplar, np.float64)
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    return ex[
        (np.floor((rows + 0.5) / scale).astype(int)) % ex.shape[0],
        (np.floor((cols + 0.5) / scale).astype(int)) % ex.shape[1],
    ]


def _mean_grams(patches, weights: VGGWeights, layers) -> dict:
    feats = vgg_features(jnp.asarray(patches, jnp.float32), weights, layers=tuple(layers))
    out = {}
    for name in layers:
        fl = feats[name].reshape(feats[name].shape[0], -1, feats[name].shape[-1])
        out[name] = jnp.mean(jnp.einsum("bnc,bnd->bcd", fl, fl) / fl.shape[1], axis=0)
    return out


def patch_gram_distance(
    a: Float[np.ndarray, "P S S 3"],
    b: Float[np.ndarray, "Q S S 3"],
    *,
    weights: VGGWeights | None = None,
    layers: tuple[str, ...] = PATCH_GRAM_LAYERS,
) -> float:
    """Distance of the mean VGG Gram matrices of two patch sets.

    .. math:: d = \\sum_l \\frac{1}{C_l^2}\\Big\\lVert \\overline{G_l}(a) - \\overline{G_l}(b)
       \\Big\\rVert_F^2, \\qquad G_l = \\tfrac{1}{hw} F_l^\\top F_l

    Args:
      a, b: patch stacks in [0, 1].
      weights: the network (default the embedded VGG-16).
      layers: Gram layers (default ``PATCH_GRAM_LAYERS``).

    Example:
      >>> x = np.random.default_rng(0).uniform(size=(2, 16, 16, 3))
      >>> patch_gram_distance(x, x)
      0.0
    """
    weights = load_vgg16() if weights is None else weights
    ga, gb = _mean_grams(a, weights, layers), _mean_grams(b, weights, layers)
    return float(sum(jnp.mean((ga[n] - gb[n]) ** 2) for n in layers))


def log_radial_spectrum(
    patches: Float[np.ndarray, "P S S 3"], *, bins: int = 12
) -> Float[np.ndarray, " B"]:
    """Mean log radial power spectrum of the patches' luminance (Hann-windowed, mean removed).

    Returns:
      ``[bins]`` ``log10(power + 1e-10)`` averaged over the patches, in radial frequency bins from
      the lowest non-zero frequency to Nyquist.

    Example:
      >>> log_radial_spectrum(np.full((2, 16, 16, 3), 0.5)).round(3).tolist()[:2]
      [-10.0, -10.0]
    """
    x = np.asarray(patches, np.float64)
    lum = x @ np.array([0.299, 0.587, 0.114])
    S = lum.shape[1]
    lum = lum - lum.mean(axis=(1, 2), keepdims=True)
    window = np.outer(np.hanning(S), np.hanning(S))
    power = np.abs(np.fft.fft2(lum * window)) ** 2 / (window**2).sum()
    fy, fx = np.meshgrid(np.fft.fftfreq(S), np.fft.fftfreq(S), indexing="ij")
    radius = np.hypot(fy, fx)
    edges = np.linspace(1.0 / S, 0.5, bins + 1)
    which = np.digitize(radius, edges) - 1
    mean_power = power.mean(axis=0)
    out = np.empty(bins)
    for k in range(bins):
        sel = which == k
        out[k] = mean_power[sel].mean() if sel.any() else 0.0
    return np.log10(out + 1e-10)


def patch_spectrum_distance(a, b, *, bins: int = 12) -> float:
    """Mean absolute difference of two patch sets' :func:`log_radial_spectrum` (decades).

    Example:
      >>> x = np.random.default_rng(0).uniform(size=(2, 16, 16, 3))
      >>> patch_spectrum_distance(x, x)
      0.0
    """
    return float(
        np.mean(np.abs(log_radial_spectrum(a, bins=bins) - log_radial_spectrum(b, bins=bins)))
    )


def surface_patch_table(
    mesh: Mesh,
    texture: Float[np.ndarray, "H W 3"],
    exemplar: Float[np.ndarray, "E F 3"],
    *,
    step: float,
    key: jax.Array,
    num: int = 32,
    size: int = 32,
    scale: float = 1.0,
    initial: Float[np.ndarray, "H W 3"] | None = None,
    valid: np.ndarray | None = None,
    weights: VGGWeights | None = None,
    frame_vector=(1.0, 0.0, 0.0),
) -> dict[str, dict[str, float]]:
    """Score a mesh texture and its baselines with surface patches against exemplar crops.

    Rows: ``"texture"``; ``"flat"`` (the exemplar's mean colour); ``"permuted"`` (the texture's
    valid texels shuffled); ``"initial"`` (``initial``, e.g. the optimisation's starting noise,
    when given); ``"uv_tiled"`` (:func:`tiled_exemplar` at ``scale``); ``"floor"`` (a second set
    of exemplar crops: the measure's noise floor). Each row holds ``gram``
    (:func:`patch_gram_distance`), ``spectrum`` (:func:`patch_spectrum_distance`), and for surface
    rows ``charts`` (mean charts per patch) and ``off_chart`` (mean share of pixels across a seam).

    Args:
      mesh: the mesh with ``uv``.
      texture: ``[H, W, 3]`` the texture in the mesh's UV layout.
      exemplar: the exemplar image.
      step: world length of one texel (patch pixels are texels).
      key: PRNG key (patch centres, crops, permutation).
      num, size: patches per set and their side.
      scale: texels per exemplar pixel of the synthesis.
      initial: the initial texture, scored as a baseline when given.
      valid: ``[H, W]`` bool texels on the mesh (the permutation shuffles these; default all).
      weights: the network of the Gram term (default the embedded VGG-16).
      frame_vector: patch frames (as the synthesis').

    Returns:
      ``{row: {"gram": d, "spectrum": d, ...}}``.
    """
    k_patch, k_crop, k_floor, k_perm = jax.random.split(key, 4)
    weights = load_vgg16() if weights is None else weights
    texture = np.asarray(texture, np.float64)
    patches = surface_patches(
        mesh, num=num, step=step, key=k_patch, size=size, frame_vector=frame_vector
    )
    crops = exemplar_crops(exemplar, num=num, key=k_crop, size=size, scale=scale)
    floor = exemplar_crops(exemplar, num=num, key=k_floor, size=size, scale=scale)
    ex = np.asarray(exemplar, np.float64)
    H, W = texture.shape[:2]
    if valid is None:
        valid = np.ones((H, W), bool)
    perm = texture.copy()
    flat_valid = perm.reshape(-1, 3)[valid.ravel()]
    rng = np.random.default_rng(np.asarray(jax.random.key_data(k_perm)).ravel())
    perm.reshape(-1, 3)[valid.ravel()] = flat_valid[rng.permutation(len(flat_valid))]
    tiled = tiled_exemplar(ex, (H, W), scale=scale)
    candidates = {
        "texture": texture,
        "flat": np.broadcast_to(ex.reshape(-1, 3).mean(axis=0), texture.shape),
        "permuted": perm,
        "uv_tiled": tiled,
    }
    if initial is not None:
        candidates["initial"] = np.asarray(initial, np.float64)
    table = {}
    for name, image in candidates.items():
        p = patches.sample(image)
        table[name] = {
            "gram": patch_gram_distance(p, crops, weights=weights),
            "spectrum": patch_spectrum_distance(p, crops),
            "charts": float(patches.charts.mean()),
            "off_chart": float(patches.off_chart.mean()),
        }
    table["floor"] = {
        "gram": patch_gram_distance(floor, crops, weights=weights),
        "spectrum": patch_spectrum_distance(floor, crops),
    }
    return table

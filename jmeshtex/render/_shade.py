"""Shading as a pure, jit-compiled JAX function of a visibility buffer.

Everything that depends on the camera and the mesh's connectivity (which face each sample sees,
barycentrics, per-corner normals, each face's mip level) is frozen on the host; this module turns
those arrays into colours. It is differentiable with respect to the colours and the texture, so
losses through renders are possible.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._types import Array, ArrayLike, Float, Int
from ..geometry import bilinear_blend, bilinear_taps

#: ambient, diffuse and specular weights and the Blinn-Phong exponent
AMBIENT, DIFFUSE, SPECULAR, SHININESS = 0.3, 0.7, 0.12, 32.0
#: grey of a mesh without colours
GREY = (0.78, 0.80, 0.86)


class Lighting(NamedTuple):
    """A directional light and the viewing direction, both unit ``[3]`` world vectors.

    Attributes:
      light: direction from the surface towards the light.
      view: direction from the surface towards the viewer (the camera's ``-forward``).
    """

    light: Float[ArrayLike, "3"]
    view: Float[ArrayLike, "3"]


def camera_lighting(camera) -> Lighting:
    """The standard light of a camera: above-left of it, ``normalize(1.0·(-w) + 0.6·u - 0.45·r)``."""
    r, u, w = camera.frame()
    light = -w + 0.6 * u - 0.45 * r
    return Lighting(light=light / np.linalg.norm(light), view=-w)


def mip_pyramid(texture: Float[ArrayLike, "H W C"]) -> list[Array]:
    """Mip levels of a texture: level 0 is the texture, level ``k`` is ``ceil(H / 2^k) × ceil(W / 2^k)``.

    Each level is the 2×2 box average of the previous one (an odd last row or column is repeated
    first), down to one texel a side; differentiable with respect to the texture.

    Example:
      >>> [lv.shape for lv in mip_pyramid(jnp.zeros((5, 8, 3)))]
      [(5, 8, 3), (3, 4, 3), (2, 2, 3), (1, 1, 3)]
    """
    levels = [jnp.asarray(texture)]
    while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
        x = levels[-1]
        h, w, c = x.shape
        if h % 2 and h > 1:
            x = jnp.concatenate([x, x[-1:]], axis=0)
        if w % 2 and w > 1:
            x = jnp.concatenate([x, x[:, -1:]], axis=1)
        sh, sw = (2 if h > 1 else 1), (2 if w > 1 else 1)
        levels.append(x.reshape(x.shape[0] // sh, sh, x.shape[1] // sw, sw, c).mean(axis=(1, 3)))
    return levels


def _bilinear_level(flat, offset, h, w, u, v):
    """Bilinear lookup in one level stored flat at ``offset`` (``geometry.bilinear_taps``, clamped)."""
    (ya, yb, xa, xb), (fx, fy) = bilinear_taps(u, v, h, w)
    t = lambda yy, xx: jnp.take(flat, offset + yy * w + xx, axis=0)  # noqa: E731
    return bilinear_blend(t(ya, xa), t(ya, xb), t(yb, xa), t(yb, xb), fx[..., None], fy[..., None])


def sample_mipmapped(
    texture: Float[ArrayLike, "H W C"],
    uv: Float[ArrayLike, "*N 2"],
    lod: Float[ArrayLike, "*N"] | None = None,
) -> Float[Array, "*N C"]:
    """Trilinear (mip-mapped bilinear) texture lookup, built on the bilinear kernel of
    :func:`jmeshtex.geometry.bilinear_taps` (the same texel convention as
    :func:`jmeshtex.geometry.sample_texture`).

    UVs wrap into [0, 1) (u right, v up; row 0 of the texture is v = 1); within a level the lookup
    clamps at the borders. ``lod`` is the mip level (``log2`` of texels per sample along a side);
    level ``floor(lod)`` and the next are blended by ``lod - floor(lod)``; ``lod <= 0`` (or None) is
    plain bilinear on the full texture.

    Example:
      >>> tex = jnp.arange(12.0).reshape(2, 2, 3)
      >>> sample_mipmapped(tex, jnp.array([[0.25, 0.75]]))  # the top-left texel's centre
      Array([[0., 1., 2.]], dtype=float64)
    """
    tex = jnp.asarray(texture)
    uv = jnp.asarray(uv)
    u, v = uv[..., 0] % 1.0, uv[..., 1] % 1.0
    if lod is None:
        h, w = tex.shape[:2]
        return _bilinear_level(tex.reshape(h * w, -1), 0, h, w, u, v)
    levels = mip_pyramid(tex)
    flat = jnp.concatenate([lv.reshape(-1, tex.shape[2]) for lv in levels])
    sizes = np.array([lv.shape[:2] for lv in levels])
    offsets = np.concatenate([[0], np.cumsum(sizes[:, 0] * sizes[:, 1])[:-1]]).astype(np.int32)
    top = len(levels) - 1
    lod = jnp.clip(jnp.asarray(lod, uv.dtype), 0.0, float(top))
    l0 = jnp.floor(lod).astype(jnp.int32)
    l1 = jnp.minimum(l0 + 1, top)
    frac = (lod - l0.astype(lod.dtype))[..., None]
    hs, ws, offs = (
        jnp.asarray(sizes[:, 0], jnp.int32),
        jnp.asarray(sizes[:, 1], jnp.int32),
        jnp.asarray(offsets),
    )
    a = _bilinear_level(flat, offs[l0], hs[l0], ws[l0], u, v)
    b = _bilinear_level(flat, offs[l1], hs[l1], ws[l1], u, v)
    return a * (1 - frac) + b * frac


def _gather_columns(tables: dict[str, Array], index: Array) -> dict[str, Array]:
    """``{name: table[index]}`` for per-face tables ``[F, ...]``, gathered as one ``[F, Σ]`` table.

    Example:
      >>> t = {"a": jnp.arange(6.0).reshape(3, 2), "b": jnp.arange(3.0).reshape(3, 1)}
      >>> {k: v.tolist() for k, v in _gather_columns(t, jnp.array([[2, 0]])).items()}
      {'a': [[[4.0, 5.0], [0.0, 1.0]]], 'b': [[[2.0], [0.0]]]}
    """
    if not tables:
        return {}
    names = list(tables)
    flat = [tables[k].reshape(tables[k].shape[0], -1) for k in names]
    cuts = np.cumsum([0, *(t.shape[1] for t in flat)])
    per = jnp.take(jnp.concatenate(flat, axis=1), index, axis=0)
    return {
        k: per[..., cuts[i] : cuts[i + 1]].reshape(index.shape + tables[k].shape[1:])
        for i, k in enumerate(names)
    }


@functools.partial(jax.jit, static_argnames=("lit", "supersample", "background"))
def shade(
    face: Int[ArrayLike, "Hs Ws"],
    bary: Float[ArrayLike, "Hs Ws 3"],
    normals: Float[ArrayLike, "F 3 3"],
    lighting: Lighting,
    *,
    corner_colors: Float[ArrayLike, "F 3 C"] | None = None,
    uv: Float[ArrayLike, "F 3 2"] | None = None,
    texture: Float[ArrayLike, "H W C"] | None = None,
    lod: Float[ArrayLike, " F"] | None = None,
    lit: bool = True,
    supersample: int = 1,
    background: str = "white",
) -> Float[Array, "H W C"]:
    """Colours of a visibility buffer: interpolated albedo × Lambert + Blinn-Phong, then a box filter.

    Per sample seeing face ``f`` with barycentrics ``b`` (perspective-correct, from
    :func:`jmeshtex.render.rasterize`), the albedo ``a`` is ``Σ_i b_i c_{f,i}`` (corner colours),
    or the trilinear texture lookup at ``Σ_i b_i uv_{f,i}`` on mip level ``lod_f``, or grey. The
    normal ``n = normalize(Σ_i b_i n_{f,i})`` (per-corner normals: vertex normals for smooth
    shading, the face normal three times for flat) is turned towards the viewer (two-sided), and

    .. math:: c = a\\,(k_a + k_d \\max(0, n\\cdot\\ell)) + k_s \\max(0, n\\cdot h)^{p},
       \\quad h = \\frac{\\ell + v}{|\\ell + v|}

    with :math:`k_a = 0.3, k_d = 0.7, k_s = 0.12, p = 32` (``lit=False``: ``c = a``). The
    ``supersample × supersample`` blocks of samples are then averaged (antialiasing): over white
    (``background="white"``), or into premultiplied coverage alpha (``"transparent"``, the colour
    channels un-premultiplied, zero where nothing is seen).

    Differentiable with respect to ``corner_colors``, ``texture`` and ``normals``.

    Args:
      face: ``[Hs, Ws]`` int face index per sample, ``-1`` for background.
      bary: ``[Hs, Ws, 3]`` barycentrics of each sample in its face.
      normals: ``[F, 3, 3]`` unit normal at each face corner (world frame).
      lighting: unit light and view directions (world frame), e.g. :func:`camera_lighting`.
      corner_colors: ``[F, 3, C]`` albedo at each corner in [0, 1] (``vertex_colors[faces]``).
      uv: ``[F, 3, 2]`` per-corner texture coordinates, with ``texture``.
      texture: ``[H, W, C]`` albedo image in [0, 1], row 0 at the top (v = 1).
      lod: ``[F]`` mip level per face (see :func:`jmeshtex.render.texture_lod`); None: level 0.
      lit: apply the lighting (False: the albedo as it is, e.g. to check a texture).
      supersample: samples per output pixel side; ``Hs`` and ``Ws`` must be multiples of it.
      background: ``"white"`` (``C = 3``) or ``"transparent"`` (``C = 4``, RGBA).

    Returns:
      ``[Hs / supersample, Ws / supersample, 3 | 4]`` floats in [0, 1], dtype of ``bary``.

    Example:
      >>> face = jnp.array([[0, -1]])
      >>> bary = jnp.array([[[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]])
      >>> up = jnp.tile(jnp.array([0.0, 0.0, 1.0]), (1, 3, 1))
      >>> red = jnp.tile(jnp.array([1.0, 0.0, 0.0]), (1, 3, 1))
      >>> img = shade(face, bary, up, Lighting(jnp.array([0.0, 0.0, 1.0]), jnp.array([0.0, 0.0, 1.0])),
      ...             corner_colors=red)
      >>> img.round(2).tolist()  # red lit head-on (0.3 + 0.7 + 0.12 highlight, clipped), white
      [[[1.0, 0.12, 0.12], [1.0, 1.0, 1.0]]]
    """
    face = jnp.asarray(face)
    bary = jnp.asarray(bary)
    dtype = bary.dtype
    hit = face >= 0
    fi = jnp.where(hit, face, 0)
    if texture is not None and uv is None:
        raise InputError("shade: texture needs uv")
    # one gather of every per-face attribute (a 2D table gathers far faster than several 3D ones),
    # read back by name: each column block is (name, per-corner shape)
    n_faces = jnp.asarray(normals).shape[0]
    tables = {}
    if lit:
        tables["normals"] = jnp.asarray(normals, dtype).reshape(n_faces, 3, 3)
    if corner_colors is not None:
        tables["colors"] = jnp.asarray(corner_colors, dtype)[..., :3].reshape(n_faces, 3, 3)
    elif texture is not None:
        tables["uv"] = jnp.asarray(uv, dtype).reshape(n_faces, 3, 2)
        if lod is not None:
            tables["lod"] = jnp.asarray(lod, dtype).reshape(n_faces, 1)
    columns = _gather_columns(tables, fi)

    b = bary[..., None]  # [Hs, Ws, 3, 1]
    n = (columns["normals"] * b).sum(axis=-2) if lit else None
    if corner_colors is not None:
        albedo = (columns["colors"] * b).sum(axis=-2)
    elif texture is not None:
        st = (columns["uv"] * b).sum(axis=-2)
        lod_px = columns["lod"][..., 0] if lod is not None else None
        albedo = sample_mipmapped(jnp.asarray(texture, dtype), st, lod_px)[..., :3]
    else:
        albedo = jnp.broadcast_to(jnp.asarray(GREY, dtype), face.shape + (3,))
    if lit:
        light, view = jnp.asarray(lighting.light, dtype), jnp.asarray(lighting.view, dtype)
        n = n * jax.lax.rsqrt(jnp.maximum((n * n).sum(-1, keepdims=True), 1e-30))
        n = jnp.where((n @ view)[..., None] < 0, -n, n)  # two-sided: turn towards the viewer
        half = (light + view) / jnp.linalg.norm(light + view)
        diffuse = jnp.maximum(n @ light, 0.0)[..., None]
        spec = jnp.maximum(n @ half, 0.0)[..., None] ** SHININESS
        color = albedo * (AMBIENT + DIFFUSE * diffuse) + SPECULAR * spec
    else:
        color = albedo
    color = jnp.clip(color, 0.0, 1.0)
    s = supersample
    hs, ws = face.shape
    cover = hit.astype(dtype)[..., None]
    if background == "white":
        out = color * cover + (1.0 - cover)
        return out.reshape(hs // s, s, ws // s, s, 3).mean(axis=(1, 3))
    if background == "transparent":
        pre = (color * cover).reshape(hs // s, s, ws // s, s, 3).mean(axis=(1, 3))
        alpha = cover.reshape(hs // s, s, ws // s, s, 1).mean(axis=(1, 3))
        rgb = pre / jnp.maximum(alpha, 1e-12)
        return jnp.concatenate([rgb, alpha], axis=-1)
    raise InputError(f"background must be 'white' or 'transparent', got {background!r}")

"""MeshMatch front ends: colour / UV-texture transfer, painting by example, displacement transfer.

All three reduce to :func:`~jmeshtex.meshmatch.meshmatch` on per-vertex signals:

- textures are read at the source's vertices (each vertex averages its corners' texture samples)
  and, on a target with UVs, written back by looking every texel up in the synthesised per-vertex
  field (barycentric interpolation in the triangle that covers the texel; empty texels take the
  nearest covered one, which pads charts against bleeding);
- painting by example matches the whole mesh against its painted part and keeps the paint;
- detail transfer moves the signed normal offset of the source from its smoothed self.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._mesh import Mesh
from .._types import Float, Int
from ..geometry import fill_unused_texels, rasterize_uv, sample_texture, tangent_frames
from ._config import MeshMatchConfig
from ._fans import smooth, smoother
from ._patchmatch import MeshMatchResult, meshmatch


class TransferResult(NamedTuple):
    """A synthesised target.

    Attributes:
      mesh: the target :class:`~jmeshtex.Mesh` with ``vertex_colors`` set (and ``texture`` filled
        when the target has UVs).
      match: the :class:`MeshMatchResult` (nearest-neighbour field, rotations, costs, timings).
    """

    mesh: Mesh
    match: MeshMatchResult


def vertex_colors_from_texture(mesh: Mesh) -> Float[np.ndarray, "V C"]:
    """Per-vertex colours read from a UV texture: the mean of the texture at the vertex's corners.

    .. math:: c_v = \\frac{1}{|\\{(f,k): F_{fk} = v\\}|} \\sum_{(f, k):\\, F_{fk} = v} T(uv_{fk})

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> uv = v[f][..., :2]
      >>> tex = np.zeros((4, 4, 3), np.float32); tex[:, 2:] = 1.0   # right half white
      >>> c = vertex_colors_from_texture(Mesh(v, f, uv=uv, texture=tex))
      >>> c[[0, 2], 0].tolist()          # left and right corners
      [0.0, 1.0]
    """
    if mesh.uv is None or mesh.texture is None:
        raise InputError(f"mesh {mesh.name!r} has no UV texture: pass vertex colours or a texture")
    samples = np.asarray(sample_texture(np.asarray(mesh.texture, np.float64), np.asarray(mesh.uv, np.float64)))
    if samples.ndim == 2:
        samples = samples[..., None]
    samples = samples[..., :3]
    V = mesh.num_vertices
    corner_vertex = np.asarray(mesh.faces).ravel()
    count = np.bincount(corner_vertex, minlength=V).astype(np.float64)
    out = np.stack([np.bincount(corner_vertex, weights=samples.reshape(-1, samples.shape[-1])[:, c], minlength=V)
                    for c in range(samples.shape[-1])], axis=1)
    return out / np.maximum(count, 1)[:, None]


def bake_texture(
    uv: Float[np.ndarray, "F 3 2"],
    faces: Int[np.ndarray, "F 3"],
    colors: Float[np.ndarray, "V C"],
    *,
    size: int = 512,
) -> Float[np.ndarray, "H W C"]:
    """Fill a ``size × size`` texture by looking each texel centre up in a per-vertex field.

    Each texel whose centre ``(u, v) = ((i + ½)/W, 1 − (j + ½)/H)`` lies in a UV triangle
    (:func:`~jmeshtex.geometry.rasterize_uv`, ``coverage="center"``) gets the barycentric
    interpolation of the covering face's vertex colours (overlapping charts: the last face wins);
    texels no triangle covers copy the nearest covered texel (padding charts against bleeding).

    Args:
      uv: ``[F, 3, 2]`` per-corner texture coordinates.
      faces: ``[F, 3]`` triangles.
      colors: ``[V, C]`` per-vertex values.
      size: texture width and height.

    Returns:
      ``[size, size, C]`` float32 image, row 0 at the top (v = 1).

    Example:
      >>> uv = np.array([[[0, 0], [1, 0], [0, 1]], [[1, 0], [1, 1], [0, 1]]], float)
      >>> tex = bake_texture(uv, np.array([[0, 1, 2], [1, 3, 2]]), np.array([[0.0], [1.0], [0.0], [1.0]]), size=4)
      >>> np.round(tex[0, :, 0], 3).tolist()             # top row: u = 1/8 .. 7/8
      [0.125, 0.375, 0.625, 0.875]
    """
    uv = np.asarray(uv, np.float64)
    faces = np.asarray(faces, np.int64)
    colors = np.asarray(colors, np.float64)
    if uv.shape != (len(faces), 3, 2):
        raise InputError(f"uv must have shape [F={len(faces)}, 3, 2], got {uv.shape}")
    texels = rasterize_uv(uv, size)  # texel centres in UV triangles, barycentrics clipped
    face, row, col, bary = texels.face, texels.row, texels.col, texels.bary
    out = np.zeros((size * size, colors.shape[1]))
    hit = np.zeros(size * size, bool)
    flat = row * size + col
    out[flat] = np.einsum("nk,nkc->nc", bary, colors[faces[face]])  # overlapping charts: last wins
    hit[flat] = True
    return fill_unused_texels(out.reshape(size, size, -1), hit.reshape(size, size)).astype(np.float32)


def _colors_of(mesh: Mesh, colors) -> np.ndarray:
    if colors is not None:
        return np.asarray(colors, np.float64)
    if mesh.vertex_colors is not None:
        return np.asarray(mesh.vertex_colors, np.float64)[:, :3]
    if mesh.uv is not None and mesh.texture is not None:
        return vertex_colors_from_texture(mesh)
    raise InputError(
        f"mesh {mesh.name!r} has neither vertex colours nor a UV texture: give the source a texture "
        "(--source-texture) or vertex colours"
    )


def transfer_texture(
    source: Mesh,
    target: Mesh,
    *,
    config: MeshMatchConfig | None = None,
    source_colors: Float[np.ndarray, "Vs C"] | None = None,
    correspondences: Int[np.ndarray, "m 2"] | None = None,
    texture_size: int = 512,
    seed: int = 0,
    progress=False,
) -> TransferResult:
    """Transfer a source mesh's colours (vertex colours or UV texture) onto a target mesh.

    .. math:: c_t = c^{src}_{\\text{NNF}(t)}

    (MeshMatch, Chen et al. 2012: coarse-to-fine PatchMatch, final nearest copy.) A target with
    UVs also gets a baked texture (:func:`bake_texture`).

    Args:
      source: exemplar with ``vertex_colors`` or ``uv`` + ``texture`` (or pass ``source_colors``).
      target: mesh to texture (same units as the source).
      config: :class:`MeshMatchConfig`.
      source_colors: ``[Vs, C]`` per-vertex colours overriding the source's own.
      correspondences: ``[m, 2]`` (source vertex, target vertex) pairs.
      texture_size: size of the baked texture for a target with UVs.
      seed: PRNG seed.
      progress: see :func:`meshmatch`.

    Returns:
      :class:`TransferResult`.

    Example:
      >>> from jmeshtex.data import torus
      >>> v, f = torus(24, 12)
      >>> colors = 0.5 + 0.4 * np.sin(5 * np.arctan2(v[:, 1], v[:, 0]))[:, None] * np.ones(3)
      >>> out = transfer_texture(Mesh(v, f, vertex_colors=colors), Mesh(v, f),
      ...                        config=MeshMatchConfig(levels=2, iterations=3, hks_eigenpairs=8))
      >>> out.mesh.vertex_colors.shape
      (288, 3)
    """
    colors = _colors_of(source, source_colors)
    result = meshmatch(source.vertices, source.faces, colors, target.vertices, target.faces,
                       config=config, seed=seed, correspondences=correspondences, progress=progress)
    out = np.clip(result.colors, 0.0, 1.0).astype(np.float32)
    mesh = target.replace(vertex_colors=out)
    if target.uv is not None:
        mesh = mesh.replace(texture=bake_texture(target.uv, target.faces, out, size=texture_size))
    return TransferResult(mesh, result)


def paint_by_example(
    mesh: Mesh,
    mask: np.ndarray,
    *,
    colors: Float[np.ndarray, "V C"] | None = None,
    config: MeshMatchConfig | None = None,
    seed: int = 0,
    progress=False,
) -> TransferResult:
    """Propagate the painted part of a mesh (``mask``) to the unpainted part, by example.

    The mesh is matched against itself with matches restricted to painted vertices; painted
    vertices are pinned to themselves, so they keep their colour exactly.

    Args:
      mesh: the mesh, with vertex colours or a UV texture (or ``colors``).
      mask: ``[V]`` bool, True where the user painted (the example), or integer vertex indices.
      colors: ``[V, C]`` colours overriding the mesh's own.
      config, seed, progress: as :func:`meshmatch`.

    Returns:
      :class:`TransferResult` whose mesh carries the completed vertex colours.

    Raises:
      InputError: an empty or complete mask, wrong shapes.

    Example:
      >>> from jmeshtex.data import torus
      >>> v, f = torus(24, 12)
      >>> colors = 0.5 + 0.4 * np.sin(5 * np.arctan2(v[:, 1], v[:, 0]))[:, None] * np.ones(3)
      >>> painted = v[:, 0] > 0
      >>> out = paint_by_example(Mesh(v, f, vertex_colors=colors), painted,
      ...                        config=MeshMatchConfig(levels=2, iterations=2, hks_eigenpairs=8))
      >>> bool(np.allclose(out.mesh.vertex_colors[painted], colors[painted], atol=1e-6))
      True
    """
    V = mesh.num_vertices
    mask = np.asarray(mask)
    if mask.dtype != bool:
        if not np.issubdtype(mask.dtype, np.integer) or mask.ndim != 1:
            raise InputError("mask must be a [V] bool array or a list of painted vertex indices")
        if mask.size and (mask.min() < 0 or mask.max() >= V):
            raise InputError(f"mask vertex indices out of range [0, {V})")
        full = np.zeros(V, bool)
        full[mask] = True
        mask = full
    if mask.shape != (V,):
        raise InputError(f"mask must have shape [V={V}], got {mask.shape}")
    if not mask.any():
        raise InputError("the mask paints no vertex: mark the painted (example) region with True")
    if mask.all():
        raise InputError("the mask paints every vertex: nothing is left to synthesise")
    base = _colors_of(mesh, colors)
    pin = np.where(mask, np.arange(V), -1)
    result = meshmatch(mesh.vertices, mesh.faces, base, mesh.vertices, mesh.faces, config=config,
                       seed=seed, source_mask=mask, pin=pin, progress=progress)
    out = np.where(mask[:, None], base, result.colors)
    return TransferResult(mesh.replace(vertex_colors=np.clip(out, 0.0, 1.0).astype(np.float32)), result)


def detail_displacement(
    vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"], *, steps: int = 10
) -> Float[np.ndarray, " V"]:
    """Signed geometric detail: the offset from the smoothed surface along the vertex normal.

    .. math:: d_v = (x_v - (S^n x)_v) \\cdot n_v

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(8)
      >>> float(np.abs(detail_displacement(v, f)).max())      # flat: no detail
      0.0
    """
    v = np.asarray(vertices, np.float64)
    smooth_v = np.asarray(smooth(jnp.asarray(v), smoother(faces, len(v)), steps))
    normal = tangent_frames(v, faces).normal
    return np.einsum("vd,vd->v", v - smooth_v, normal)


def transfer_displacement(
    source_vertices: Float[np.ndarray, "Vs 3"],
    source_faces: Int[np.ndarray, "Fs 3"],
    target_vertices: Float[np.ndarray, "Vt 3"],
    target_faces: Int[np.ndarray, "Ft 3"],
    *,
    config: MeshMatchConfig | None = None,
    steps: int = 10,
    seed: int = 0,
    progress=False,
) -> tuple[Float[np.ndarray, "Vt 3"], MeshMatchResult]:
    """Transfer geometric detail (normal displacements) from source to target by MeshMatch.

    The source's :func:`detail_displacement` is the transferred signal; the target moves along its
    normals by the synthesised displacement: ``x'_t = x_t + d_t n_t``.

    Returns:
      ``(new target vertices [Vt, 3], MeshMatchResult)``.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(12)
      >>> bumpy = v.copy(); bumpy[:, 2] = 0.02 * np.sin(20 * v[:, 0])
      >>> new_v, _ = transfer_displacement(bumpy, f, v, f,
      ...                                  config=MeshMatchConfig(levels=1, iterations=2, up=None))
      >>> new_v.shape, bool(np.abs(new_v[:, 2]).max() > 0.001)
      ((169, 3), True)
    """
    d = detail_displacement(source_vertices, source_faces, steps=steps)
    result = meshmatch(source_vertices, source_faces, d[:, None], target_vertices, target_faces,
                       config=config, seed=seed, progress=progress)
    tv = np.asarray(target_vertices, np.float64)
    normal = tangent_frames(tv, target_faces).normal
    return tv + result.colors[:, :1] * normal, result

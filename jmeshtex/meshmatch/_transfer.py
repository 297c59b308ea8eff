"""MeshMatch front ends: colour / UV-texture transfer, painting by example, displacement transfer.

All three reduce to :func:`~jmeshtex.meshmatch.meshmatch` on per-vertex signals:

- textures are read at the source's vertices, averaged over each vertex's one-ring with its hat
  function as the weight (:func:`vertex_colors_from_texture`: detail finer than the vertices
  averages out instead of aliasing; point samples at the corners on request)
  and, on a target with UVs, written back by looking every texel up in the synthesised per-vertex
  field (barycentric interpolation in the triangle that covers the texel; empty texels take the
  nearest covered one, which pads charts against bleeding);
- painting by example matches the whole mesh against its painted part and keeps the paint;
- detail transfer (``jmeshtex/meshmatch/_displacement.py``) moves the signed normal offset of the
  source from its Taubin-smoothed base.

Each returns a :class:`Transfer`: the synthesised target mesh and the match behind it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import numpy as np

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._triangles import triangle_areas
from .._types import Float, Int
from ..geometry import fill_unused_texels, rasterize_uv, sample_texture
from ._config import Config
from ._match import Match, meshmatch


class Transfer(NamedTuple):
    """A synthesised target: what :func:`transfer`, :func:`paint_by_example` and
    :func:`~jmeshtex.meshmatch.transfer_displacement` return (write it with :func:`~jmeshtex.meshmatch.save`).

    Attributes:
      mesh: the target :class:`~jmeshtex.Mesh` with ``vertex_colors`` set (and ``texture`` filled
        when the target has UVs), or with displaced ``vertices`` (displacement transfer).
      match: the :class:`~jmeshtex.meshmatch.Match` (nearest-neighbour field,
        rotations, costs, timings).
    """

    mesh: Mesh
    match: Match


#: the most texture samples :func:`vertex_colors_from_texture` takes per face (a 16 × 16
#: subdivision of the face) and in all
MAX_FACE_SUBDIVISION = 16
MAX_TEXTURE_SAMPLES = 4_000_000


def _subtriangle_centroids(n: int) -> np.ndarray:
    """``[n², 3]`` barycentric centroids of the ``n²`` equal-area triangles of a face split ``n`` ways."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    up = (i + j) <= n - 1
    down = (i + j) <= n - 2
    b1 = np.concatenate([(i[up] + 1 / 3) / n, (i[down] + 2 / 3) / n])
    b2 = np.concatenate([(j[up] + 1 / 3) / n, (j[down] + 2 / 3) / n])
    return np.stack([1 - b1 - b2, b1, b2], axis=1)


def _face_subdivisions(mesh: Mesh, size: tuple[int, int]) -> np.ndarray:
    """Per face, the subdivision ``n`` whose samples lie about a texel apart (2 to 16, capped so
    that all faces together take at most :data:`MAX_TEXTURE_SAMPLES` samples)."""
    uv = np.asarray(mesh.uv, np.float64) * np.asarray(
        size[::-1], np.float64
    )  # in texels (x = u W, y = v H)
    edges = np.linalg.norm(uv - np.roll(uv, 1, axis=1), axis=2).max(axis=1)
    n = np.clip(np.ceil(edges), 2, MAX_FACE_SUBDIVISION).astype(np.int64)
    total = float(np.sum(n.astype(np.float64) ** 2))
    if total > MAX_TEXTURE_SAMPLES:
        n = np.clip(
            np.floor(n * np.sqrt(MAX_TEXTURE_SAMPLES / total)), 2, MAX_FACE_SUBDIVISION
        ).astype(np.int64)
    return n


def vertex_colors_from_texture(mesh: Mesh, *, prefilter: str = "area") -> Float[np.ndarray, "V C"]:
    """Per-vertex colours read from a UV texture, averaged over each vertex's area (default) or
    point-sampled at its corners.

    ``prefilter="area"``: the texture's mean over the vertex's one-ring, weighted by the vertex's
    hat function ``φ_v`` (1 at the vertex, 0 at the ring's far edges, linear in each face) and the
    surface area (the lumped L2 projection of the texture onto the mesh's linear elements):

    .. math:: c_v = \\frac{\\int \\varphi_v\\, T(uv)\\, dA}{\\int \\varphi_v\\, dA}
              \\approx \\frac{\\sum_{f \\ni v} \\frac{|f|}{n_f^2} \\sum_{j} b_{v,j}\\, T(uv_{f,j})}
              {\\sum_{f \\ni v} \\frac{|f|}{n_f^2} \\sum_j b_{v,j}}

    with the samples ``j`` at the centroids of the ``n_f²`` equal-area triangles of face ``f`` split
    ``n_f`` ways (``n_f`` about the face's longest UV edge in texels, between 2 and
    16 (``MAX_FACE_SUBDIVISION``); bilinear lookups), ``b_{v,j}`` the sample's barycentric coordinate
    of ``v``. The footprint is the vertex spacing, so texture detail finer than the vertices (which
    a per-vertex signal cannot hold) averages out instead of aliasing: a checker finer than the
    mesh gives colours near its mean, where point samples land on either square.

    ``prefilter="point"``: the mean of the bilinear texture samples at the vertex's corners (one per
    incident face; several where UV seams split the vertex):

    .. math:: c_v = \\frac{1}{|\\{(f,k): F_{fk} = v\\}|} \\sum_{(f, k):\\, F_{fk} = v} T(uv_{fk})

    Args:
      mesh: a :class:`~jmeshtex.Mesh` with ``uv`` ``[F, 3, 2]`` and ``texture`` ``[H, W, C]``.
      prefilter: ``"area"`` (default) or ``"point"``.

    Returns:
      ``[V, min(C, 3)]`` float64 colours.

    Raises:
      InputError: the mesh has no UV texture; an unknown ``prefilter``.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> uv = v[f][..., :2]
      >>> tex = np.zeros((4, 4, 3), np.float32); tex[:, 2:] = 1.0   # right half white
      >>> c = vertex_colors_from_texture(Mesh(v, f, uv=uv, texture=tex), prefilter="point")
      >>> c[[0, 2], 0].tolist()          # left and right corners
      [0.0, 1.0]
      >>> c = vertex_colors_from_texture(Mesh(v, f, uv=uv, texture=tex))
      >>> np.round(c[[0, 1, 2], 0], 2).tolist()    # the centre column's ring spans both halves
      [0.0, 0.5, 1.0]
    """
    if mesh.uv is None or mesh.texture is None:
        raise InputError(f"mesh {mesh.name!r} has no UV texture: pass vertex colours or a texture")
    if prefilter not in ("area", "point"):
        raise InputError(f"prefilter must be 'area' or 'point', got {prefilter!r}")
    texture = np.asarray(mesh.texture, np.float64)
    if texture.ndim == 2:
        texture = texture[..., None]
    texture = texture[..., :3]
    uv = np.asarray(mesh.uv, np.float64)
    faces = np.asarray(mesh.faces, np.int64)
    V, C = mesh.num_vertices, texture.shape[-1]
    if prefilter == "point":
        samples = np.asarray(sample_texture(texture, uv)).reshape(-1, C)
        corner_vertex = faces.ravel()
        count = np.bincount(corner_vertex, minlength=V).astype(np.float64)
        out = np.stack(
            [np.bincount(corner_vertex, weights=samples[:, c], minlength=V) for c in range(C)],
            axis=1,
        )
        return out / np.maximum(count, 1)[:, None]
    area = triangle_areas(np.asarray(mesh.vertices, np.float64)[faces])
    sub = _face_subdivisions(mesh, texture.shape[:2])
    num = np.zeros((V, C))
    den = np.zeros(V)
    for n in np.unique(sub):
        fs = np.nonzero(sub == n)[0]
        b = _subtriangle_centroids(int(n))  # [S, 3]
        points = np.einsum("sk,fkd->fsd", b, uv[fs])  # [F_n, S, 2]
        values = np.asarray(sample_texture(texture, points)).reshape(len(fs), len(b), C)
        w = (area[fs] / n**2)[:, None, None] * b[None]  # [F_n, S, 3]: sample weight per corner
        corner_sum = np.einsum("fsk,fsc->fkc", w, values)  # [F_n, 3, C]
        corner = faces[fs].ravel()
        for c in range(C):
            num[:, c] += np.bincount(corner, weights=corner_sum[..., c].ravel(), minlength=V)
        den += np.bincount(corner, weights=w.sum(axis=1).ravel(), minlength=V)
    degenerate = den <= 0  # vertices only on zero-area faces keep their point samples
    if degenerate.any():
        num[degenerate] = vertex_colors_from_texture(mesh, prefilter="point")[degenerate]
        den[degenerate] = 1.0
    return num / den[:, None]


def bake_texture(
    mesh: Mesh,
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
      mesh: a :class:`~jmeshtex.Mesh` with ``uv`` (``[F, 3, 2]`` per-corner texture coordinates).
      colors: ``[V, C]`` per-vertex values.
      size: texture width and height.

    Returns:
      ``[size, size, C]`` float32 image, row 0 at the top (v = 1).

    Raises:
      InputError: the mesh has no UVs, or they do not have shape ``[F, 3, 2]``.

    Example:
      >>> v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
      >>> f = np.array([[0, 1, 2], [1, 3, 2]])
      >>> square = Mesh(v, f, uv=v[f][..., :2])
      >>> tex = bake_texture(square, np.array([[0.0], [1.0], [0.0], [1.0]]), size=4)
      >>> np.round(tex[0, :, 0], 3).tolist()             # top row: u = 1/8 .. 7/8
      [0.125, 0.375, 0.625, 0.875]
    """
    if not isinstance(mesh, Mesh) or mesh.uv is None:
        raise InputError(
            "bake_texture needs a jmeshtex.Mesh with uv (per-corner texture coordinates)"
        )
    uv = np.asarray(mesh.uv, np.float64)
    faces = np.asarray(mesh.faces, np.int64)
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
    return fill_unused_texels(out.reshape(size, size, -1), hit.reshape(size, size)).astype(
        np.float32
    )


def _colors_of(mesh: Mesh, colors, prefilter: str = "area") -> np.ndarray:
    if colors is not None:
        return np.asarray(colors, np.float64)
    if mesh.vertex_colors is not None:
        return np.asarray(mesh.vertex_colors, np.float64)[:, :3]
    if mesh.uv is not None and mesh.texture is not None:
        return vertex_colors_from_texture(mesh, prefilter=prefilter)
    raise InputError(
        f"mesh {mesh.name!r} has neither vertex colours nor a UV texture: give the source a texture "
        "(--source-texture) or vertex colours"
    )


def transfer(
    source: Mesh | tuple,
    target: Mesh | tuple,
    *,
    key: jax.Array,
    config: Config | None = None,
    source_colors: Float[np.ndarray, "Vs C"] | None = None,
    correspondences: Int[np.ndarray, "m 2"] | None = None,
    texture_size: int = 512,
    voted: bool = False,
    texture_prefilter: str = "area",
    progress: bool | Callable[[str], Any] = False,
) -> Transfer:
    """Transfer a source mesh's colours (vertex colours or UV texture) onto a target mesh.

    .. math:: c_t = c^{src}_{\\text{NNF}(t)}

    (MeshMatch, Chen et al. 2012: coarse-to-fine PatchMatch, final nearest copy; with
    ``voted=True`` the finest level's Gaussian-weighted vote instead, which interpolates between
    the matched source vertices: smoother, and higher PSNR on smooth fields —
    ``docs/design_notes.md``, ``vote``.) A target with UVs also gets a baked texture
    (:func:`bake_texture`).

    Args:
      source: exemplar :class:`~jmeshtex.Mesh` with ``vertex_colors`` or ``uv`` + ``texture`` (or
        pass ``source_colors``); ``Vs`` vertices.
      target: mesh to texture (same units as the source), ``Vt`` vertices.
      key: a ``jax.random`` key for the random initialisation and search.
      config: :class:`~jmeshtex.meshmatch.Config` (default settings when None).
      source_colors: ``[Vs, C]`` per-vertex colours overriding the source's own.
      correspondences: ``[m, 2]`` (source vertex, target vertex) pairs.
      texture_size: size of the baked texture for a target with UVs.
      voted: output the finest level's vote instead of the nearest copy.
      texture_prefilter: how a source texture becomes per-vertex colours
        (:func:`vertex_colors_from_texture`): ``"area"`` (default, each vertex's hat-weighted
        one-ring mean) or ``"point"`` (samples at the corners).
      progress: see :func:`~jmeshtex.meshmatch.meshmatch`.

    Returns:
      :class:`Transfer` whose mesh carries ``[Vt, 3]`` float32 vertex colours in [0, 1].

    Example:
      >>> import jax
      >>> from jmeshtex.data import torus
      >>> v, f = torus(24, 12)
      >>> colors = 0.5 + 0.4 * np.sin(5 * np.arctan2(v[:, 1], v[:, 0]))[:, None] * np.ones(3)
      >>> out = transfer(Mesh(v, f, vertex_colors=colors), Mesh(v, f), key=jax.random.key(0),
      ...                        config=Config(levels=2, steps=3, hks_eigenpairs=8))
      >>> out.mesh.vertex_colors.shape
      (288, 3)
    """
    source, target = as_mesh(source, what="source"), as_mesh(target, what="target")
    colors = _colors_of(source, source_colors, texture_prefilter)
    result = meshmatch(
        source,
        colors,
        target,
        key=key,
        config=config,
        correspondences=correspondences,
        progress=progress,
    )
    out = np.clip(result.voted if voted else result.colors, 0.0, 1.0).astype(np.float32)
    mesh = target.replace(vertex_colors=out)
    if target.uv is not None:
        mesh = mesh.replace(texture=bake_texture(target, out, size=texture_size))
    return Transfer(mesh, result)


def paint_by_example(
    mesh: Mesh | tuple,
    mask: np.ndarray,
    *,
    key: jax.Array,
    colors: Float[np.ndarray, "V C"] | None = None,
    config: Config | None = None,
    progress: bool | Callable[[str], Any] = False,
) -> Transfer:
    """Propagate the painted part of a mesh (``mask``) to the unpainted part, by example.

    The mesh is matched against itself with matches restricted to painted vertices; painted
    vertices are pinned to themselves, so they keep their colour exactly.

    Args:
      mesh: the :class:`~jmeshtex.Mesh`, with vertex colours or a UV texture (or ``colors``).
      mask: ``[V]`` bool, True where the user painted (the example), or integer vertex indices.
      key: a ``jax.random`` key.
      colors: ``[V, C]`` colours overriding the mesh's own.
      config: :class:`~jmeshtex.meshmatch.Config`; None: :meth:`Config.intrinsic() <jmeshtex.meshmatch.Config.intrinsic>`,
        the pose-free features: the aligned default's position prior pulls every unpainted
        vertex towards the painted vertices nearest in space (the boundary) instead of the
        patches that fit (``docs/design_notes.md``, MeshMatch).
      progress: see :func:`~jmeshtex.meshmatch.meshmatch`.

    Returns:
      :class:`Transfer` whose mesh carries the completed ``[V, 3]`` vertex colours.

    Raises:
      InputError: an empty or complete mask, wrong shapes.

    Example:
      >>> import jax
      >>> from jmeshtex.data import torus
      >>> v, f = torus(24, 12)
      >>> colors = 0.5 + 0.4 * np.sin(5 * np.arctan2(v[:, 1], v[:, 0]))[:, None] * np.ones(3)
      >>> painted = v[:, 0] > 0
      >>> out = paint_by_example(Mesh(v, f, vertex_colors=colors), painted, key=jax.random.key(0),
      ...                        config=Config(levels=2, steps=2, hks_eigenpairs=8))
      >>> bool(np.allclose(out.mesh.vertex_colors[painted], colors[painted], atol=1e-6))
      True
    """
    mesh = as_mesh(mesh)
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
    config = Config.intrinsic() if config is None else config
    if not isinstance(config, Config):
        raise InputError(
            f"config must be a jmeshtex.meshmatch.Config (Config.from_dict(d) reads a dict), "
            f"got {type(config).__name__}"
        )
    result = meshmatch(
        mesh, base, mesh, key=key, config=config, source_mask=mask, pin=pin, progress=progress
    )
    out = np.where(mask[:, None], base, result.colors)
    return Transfer(mesh.replace(vertex_colors=np.clip(out, 0.0, 1.0).astype(np.float32)), result)

"""Off-screen mesh rendering with matplotlib's Agg canvas: no display, no pyplot, no global state.

A rendered mesh is a :class:`~mpl_toolkits.mplot3d.art3d.Poly3DCollection` of flat-shaded triangles
that matplotlib depth-sorts back to front (painter's algorithm, ``zsort="average"``). It is meant
for looking at results (figures, demos, notebooks, test artefacts), not for speed: about a second
per 10K faces. Every image is an RGB ``uint8`` array ``[H, W, 3]``; PNGs are written atomically
with :func:`jmeshtex.io.save_png`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from .._errors import InputError
from .._types import Array, Float, Int, Num
from ..geometry import check_mesh_arrays
from ..io import save_png

_DEFAULT_COLOR = np.array([0.78, 0.80, 0.86])
_AMBIENT, _DIFFUSE = 0.35, 0.65
_DPI = 100


def render_mesh(
    vertices: Float[Array, "V 3"],
    faces: Int[Array, "F 3"],
    path: str | os.PathLike | None = None,
    *,
    vertex_colors: Num[Array, "V C"] | None = None,
    face_colors: Num[Array, "F C"] | None = None,
    scalars: Float[Array, " V_or_F"] | None = None,
    cmap: str = "viridis",
    clim: tuple[float, float] | None = None,
    uv: Float[Array, "F 3 2"] | None = None,
    texture: Num[Array, "H W C"] | None = None,
    vectors: Float[Array, "V 3"] | None = None,
    vector_scale: float | None = None,
    max_arrows: int = 1500,
    edges: Int[Array, "E 2"] | None = None,
    view: tuple[float, float] = (25.0, -60.0),
    size: tuple[int, int] = (512, 512),
    title: str | None = None,
) -> np.ndarray:
    """Render a triangle mesh off-screen to an RGB image, optionally writing it as a PNG.

    Flat (per-face) shading with one directional light placed above-left of the camera, two-sided:

    .. math:: c_f = \\text{base}_f \\, (0.35 + 0.65\\, |n_f \\cdot \\ell|)

    Faces are drawn back to front by their mean depth (painter's algorithm). At most one colour
    source may be given; without one the mesh is light grey.

    Args:
      vertices: ``[V, 3]`` positions (world frame, z up in the default view).
      faces: ``[F, 3]`` triangles.
      path: where to write a PNG (parent folders are created; written to a temporary name and
        renamed, so a reader never sees a half-written file). ``None``: only return the image.
      vertex_colors: ``[V, 3|4]`` colours (float in [0, 1], clipped, or uint8); a face shows the
        mean of its corners (alpha ignored).
      face_colors: ``[F, 3|4]`` colours, as ``vertex_colors``.
      scalars: ``[V]`` per-vertex or ``[F]`` per-face values mapped through ``cmap`` (per-vertex
        when ``V == F``); vertex values are averaged per face.
      cmap: a matplotlib colormap name.
      clim: ``(vmin, vmax)`` for ``scalars``; default their min and max.
      uv: ``[F, 3, 2]`` per-corner texture coordinates (or ``[V, 2]`` per vertex), with ``texture``.
      texture: ``[H, W]`` or ``[H, W, 3|4]`` image (float in [0, 1] or uint8), row 0 at the top
        (v = 1). A face gets the mean of bilinear samples at its three corner UVs and its centroid
        UV: textures show at face resolution (enough to check UV layouts, not to inspect texels).
      vectors: ``[V, 3]`` tangent field drawn as arrows from the vertices (3D, world frame). On a
        closed mesh arrows of vertices facing away from the camera are hidden.
      vector_scale: arrow length per unit of ``|vector|``; default: the longest arrow is 0.9 mean
        edge lengths.
      max_arrows: draw at most this many arrows (an evenly spaced subset of the vertices).
      edges: ``[E, 2]`` vertex pairs drawn as red lines on top (e.g. boundary loops, seams).
      view: ``(elevation, azimuth)`` of the camera in degrees (matplotlib's convention).
      size: ``(width, height)`` in pixels.
      title: text at the top of the image.

    Returns:
      ``[height, width, 3]`` uint8 RGB image.

    Raises:
      InputError: wrong shapes, non-finite values, several colour sources, unknown colormap.
      MeshIOError: the PNG cannot be written.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> v, f = icosphere(1)
      >>> img = render_mesh(v, f, scalars=v[:, 2], size=(64, 48))
      >>> img.shape, img.dtype
      ((48, 64, 3), dtype('uint8'))
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    v, f = check_mesh_arrays(vertices, faces)
    width, height = _check_size(size)
    elev, azim = _check_view(view)
    base = _base_colors(v, f, vertex_colors, face_colors, scalars, cmap, clim, uv, texture)
    vec = None if vectors is None else _check_vectors(vectors, len(v))
    e = None if edges is None else _check_edges(edges, len(v))

    normals = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    unit = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    light = _direction(elev + 30.0, azim - 35.0)
    shade = _AMBIENT + _DIFFUSE * np.abs(unit @ light)
    colors = np.clip(base * shade[:, None], 0.0, 1.0)

    fig = Figure(figsize=(width / _DPI, height / _DPI), dpi=_DPI, facecolor="white")
    canvas = FigureCanvasAgg(fig)
    top = 1.0 if title is None else 1.0 - min(0.12, 26.0 / height)
    ax = fig.add_axes((0.0, 0.0, 1.0, top), projection="3d", computed_zorder=False)
    ax.set_proj_type("ortho")
    ax.view_init(elev=elev, azim=azim)
    ax.set_axis_off()
    # fit the bounding sphere (view independent): with these limits an orthographic sphere of radius
    # `radius` spans 0.595 · zoom of the shorter image side (measured), 92 % at this zoom
    center = 0.5 * (v.min(axis=0) + v.max(axis=0))
    radius = float(np.linalg.norm(v - center, axis=1).max()) or 1.0
    ax.set_xlim(center[0] - radius, center[0] + radius)
    ax.set_ylim(center[1] - radius, center[1] + radius)
    ax.set_zlim(center[2] - radius, center[2] + radius)
    ax.set_box_aspect((1.0, 1.0, 1.0), zoom=1.55)
    # edges in the face colour hide the hairline gaps anti-aliasing leaves between polygons
    ax.add_collection3d(
        Poly3DCollection(v[f], facecolors=colors, edgecolors=colors, linewidths=0.3, zsort="average", zorder=1)
    )
    if vec is not None:
        _add_arrows(ax, v, f, unit, vec, vector_scale, max_arrows, elev, azim)
    if e is not None:
        ax.add_collection3d(Line3DCollection(v[e], colors="#d62728", linewidths=1.6, zorder=3))
    if title is not None:
        fig.text(0.5, 1.0 - 0.5 * (1.0 - top), str(title), ha="center", va="center", fontsize=10)
    canvas.draw()
    image = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    if path is not None:
        save_png(image, path, parents=True)
    return image


def render_grid(
    images: Sequence[np.ndarray],
    path: str | os.PathLike | None = None,
    *,
    titles: Sequence[str] | None = None,
    columns: int | None = None,
) -> np.ndarray:
    """Tile several images into one panel (row-major), each with an optional title above it.

    Args:
      images: ``N`` images ``[H, W]``, ``[H, W, 3]`` or ``[H, W, 4]`` (uint8, or float in [0, 1]);
        sizes may differ (each cell is as large as the largest image).
      path: where to write the panel as a PNG (atomically); ``None``: only return it.
      titles: ``N`` strings (or None) shown above the images.
      columns: images per row; default ``ceil(sqrt(N))``.

    Returns:
      ``[rows·(h + title strip), columns·w, 3]`` uint8 RGB panel.

    Example:
      >>> tiles = [np.zeros((20, 30, 3), np.uint8), np.ones((20, 30))]
      >>> render_grid(tiles, titles=["black", "white"]).shape  # 2 columns, 20 px title strips
      (40, 60, 3)
      >>> render_grid(tiles, columns=1).shape
      (40, 30, 3)
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if len(images) == 0:
        raise InputError("render_grid needs at least one image")
    tiles = [_as_rgb(img, f"images[{i}]") for i, img in enumerate(images)]
    if titles is not None and len(titles) != len(tiles):
        raise InputError(f"got {len(titles)} titles for {len(tiles)} images: pass one title per image")
    n = len(tiles)
    cols = int(columns) if columns is not None else int(np.ceil(np.sqrt(n)))
    if cols < 1:
        raise InputError(f"columns must be >= 1, got {columns}")
    rows = -(-n // cols)
    cell_w = max(t.shape[1] for t in tiles)
    cell_h = max(t.shape[0] for t in tiles)
    strip = 0 if titles is None else 20
    width, height = cols * cell_w, rows * (cell_h + strip)

    fig = Figure(figsize=(width / _DPI, height / _DPI), dpi=_DPI, facecolor="white")
    canvas = FigureCanvasAgg(fig)
    for i, tile in enumerate(tiles):
        r, c = divmod(i, cols)
        h, w = tile.shape[:2]
        left = c * cell_w + (cell_w - w) // 2
        bottom = height - (r + 1) * (cell_h + strip) + (cell_h - h) // 2
        ax = fig.add_axes((left / width, bottom / height, w / width, h / height))
        ax.imshow(tile, interpolation="nearest", aspect="auto")
        ax.set_axis_off()
        if titles is not None and titles[i]:
            y = (height - r * (cell_h + strip) - strip / 2) / height
            fig.text((c * cell_w + cell_w / 2) / width, y, str(titles[i]), ha="center", va="center", fontsize=10)
    canvas.draw()
    panel = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    if path is not None:
        save_png(panel, path, parents=True)
    return panel


def _check_size(size) -> tuple[int, int]:
    try:
        width, height = (int(s) for s in size)
    except (TypeError, ValueError) as err:
        raise InputError(f"size must be (width, height) in pixels, got {size!r}") from err
    if not (16 <= width <= 8192 and 16 <= height <= 8192):
        raise InputError(f"size must be between 16 and 8192 pixels each way, got {size!r}")
    return width, height


def _check_view(view) -> tuple[float, float]:
    try:
        elev, azim = (float(x) for x in view)
    except (TypeError, ValueError) as err:
        raise InputError(f"view must be (elevation, azimuth) in degrees, got {view!r}") from err
    if not (np.isfinite(elev) and np.isfinite(azim)):
        raise InputError(f"view angles must be finite, got {view!r}")
    return elev, azim


def _direction(elev_deg: float, azim_deg: float) -> np.ndarray:
    """Unit vector from the origin towards a camera at (elevation, azimuth), matplotlib's convention."""
    e, a = np.radians(elev_deg), np.radians(azim_deg)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def _colors01(values, rows: int, name: str) -> np.ndarray:
    """``[rows, 3|4]`` colours (uint8 or float) to float64 RGB in [0, 1]."""
    c = np.asarray(values)
    if c.ndim != 2 or c.shape[0] != rows or c.shape[1] not in (3, 4) or not np.issubdtype(c.dtype, np.number):
        raise InputError(f"{name} must be numeric [{rows}, 3] or [{rows}, 4] colours, got shape {c.shape}")
    if np.issubdtype(c.dtype, np.integer):
        return c[:, :3] / 255.0
    if not np.isfinite(c).all():
        raise InputError(f"{name} holds NaN or infinite values")
    return np.clip(c[:, :3].astype(np.float64), 0.0, 1.0)


def _as_rgb(image, name: str) -> np.ndarray:
    """An image ``[H, W]`` / ``[H, W, 3|4]`` (uint8 or float in [0, 1]) as uint8 RGB ``[H, W, 3]``."""
    img = np.asarray(image)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    if img.ndim != 3 or img.shape[2] not in (3, 4) or min(img.shape[:2]) < 1 or not np.issubdtype(img.dtype, np.number):
        raise InputError(f"{name} must be an image [H, W], [H, W, 3] or [H, W, 4], got shape {img.shape}")
    img = img[..., :3]
    if img.dtype == np.uint8:
        return img
    if np.issubdtype(img.dtype, np.integer):
        raise InputError(f"{name}: integer images must be uint8, got {img.dtype}")
    if not np.isfinite(img).all():
        raise InputError(f"{name} holds NaN or infinite values")
    return np.round(np.clip(img, 0.0, 1.0) * 255.0).astype(np.uint8)


def _base_colors(v, f, vertex_colors, face_colors, scalars, cmap, clim, uv, texture) -> np.ndarray:
    """Unshaded ``[F, 3]`` face colours from whichever single colour source was given."""
    given = [name for name, x in (("vertex_colors", vertex_colors), ("face_colors", face_colors),
                                  ("scalars", scalars), ("uv/texture", uv if uv is not None else texture)) if x is not None]
    if len(given) > 1:
        raise InputError(f"give at most one colour source, got {', '.join(given)}")
    n_v, n_f = len(v), len(f)
    if vertex_colors is not None:
        return _colors01(vertex_colors, n_v, "vertex_colors")[f].mean(axis=1)
    if face_colors is not None:
        return _colors01(face_colors, n_f, "face_colors")
    if scalars is not None:
        return _scalar_colors(scalars, f, n_v, n_f, cmap, clim)
    if uv is not None or texture is not None:
        if uv is None or texture is None:
            raise InputError("uv and texture go together: pass both to show a texture")
        return _texture_colors(uv, texture, f, n_v)
    return np.broadcast_to(_DEFAULT_COLOR, (n_f, 3))


def _scalar_colors(scalars, f, n_v, n_f, cmap, clim) -> np.ndarray:
    import matplotlib

    s = np.asarray(scalars)
    if s.ndim != 1 or len(s) not in (n_v, n_f) or not np.issubdtype(s.dtype, np.number) or np.iscomplexobj(s):
        raise InputError(f"scalars must be real [V={n_v}] or [F={n_f}] values, got shape {s.shape} ({s.dtype})")
    s = s.astype(np.float64)
    if not np.isfinite(s).all():
        raise InputError("scalars hold NaN or infinite values")
    per_face = s[f].mean(axis=1) if len(s) == n_v else s
    vmin, vmax = (float(s.min()), float(s.max())) if clim is None else (float(clim[0]), float(clim[1]))
    if not vmax > vmin:
        vmax = vmin + 1.0  # constant field: one colour
    try:
        colormap = matplotlib.colormaps[cmap]
    except KeyError as err:
        raise InputError(f"unknown colormap {cmap!r}: use a matplotlib name such as 'viridis'") from err
    return colormap(np.clip((per_face - vmin) / (vmax - vmin), 0.0, 1.0))[:, :3]


def _texture_colors(uv, texture, f, n_v) -> np.ndarray:
    tex = _as_rgb(texture, "texture").astype(np.float64) / 255.0
    uv = np.asarray(uv)
    if uv.ndim == 2 and uv.shape == (n_v, 2):
        uv = uv[f]
    if uv.ndim != 3 or uv.shape != (len(f), 3, 2) or not np.issubdtype(uv.dtype, np.number):
        raise InputError(f"uv must be per-corner [F={len(f)}, 3, 2] or per-vertex [V={n_v}, 2], got {uv.shape}")
    if not np.isfinite(uv).all():
        raise InputError("uv holds NaN or infinite values")
    samples = np.concatenate([uv, uv.mean(axis=1, keepdims=True)], axis=1)  # corners + centroid
    return _bilinear(tex, samples.reshape(-1, 2)).reshape(len(f), 4, 3).mean(axis=1)


def _bilinear(tex: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup at ``[N, 2]`` UVs (u right, v up; wrapped into [0, 1)), texel centres at (i + ½)/W."""
    h, w = tex.shape[:2]
    x = (uv[:, 0] % 1.0) * w - 0.5
    y = (1.0 - uv[:, 1] % 1.0) * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
    xs = np.clip([x0, x0 + 1], 0, w - 1)
    ys = np.clip([y0, y0 + 1], 0, h - 1)
    top = tex[ys[0], xs[0]] * (1 - fx) + tex[ys[0], xs[1]] * fx
    bottom = tex[ys[1], xs[0]] * (1 - fx) + tex[ys[1], xs[1]] * fx
    return top * (1 - fy) + bottom * fy


def _check_vectors(vectors, n_vertices: int) -> np.ndarray:
    vec = np.asarray(vectors)
    if vec.shape != (n_vertices, 3) or not np.issubdtype(vec.dtype, np.number) or np.iscomplexobj(vec):
        raise InputError(
            f"vectors must be real [V={n_vertices}, 3] 3D tangent vectors (convert complex tangent "
            f"coordinates with the tangent frames first), got shape {vec.shape} ({vec.dtype})"
        )
    vec = vec.astype(np.float64)
    if not np.isfinite(vec).all():
        raise InputError("vectors hold NaN or infinite values")
    return vec


def _check_edges(edges, n_vertices: int) -> np.ndarray:
    e = np.asarray(edges)
    if e.ndim != 2 or e.shape[1] != 2 or not np.issubdtype(e.dtype, np.integer) or ((e < 0) | (e >= n_vertices)).any():
        raise InputError(f"edges must be integer vertex pairs [E, 2] in [0, {n_vertices}), got shape {e.shape}")
    return e


def _add_arrows(ax, v, f, face_unit, vec, vector_scale, max_arrows, elev, azim) -> None:
    edge_len = np.linalg.norm(v[f] - v[np.roll(f, -1, axis=1)], axis=-1).mean()
    vertex_normal = np.zeros_like(v)
    np.add.at(vertex_normal, f.ravel(), np.repeat(face_unit, 3, axis=0))
    keep = np.linalg.norm(vec, axis=1) > 0
    if _is_closed(f):  # the far side's arrows would show through the surface
        keep &= vertex_normal @ _direction(elev, azim) > 0
    idx = np.nonzero(keep)[0]
    if len(idx) > max_arrows:
        idx = idx[np.linspace(0, len(idx) - 1, max_arrows).round().astype(np.int64)]
    if len(idx) == 0:
        return
    longest = float(np.linalg.norm(vec[idx], axis=1).max())
    scale = 0.9 * edge_len / longest if vector_scale is None else float(vector_scale)
    n_unit = vertex_normal[idx] / np.maximum(np.linalg.norm(vertex_normal[idx], axis=1, keepdims=True), 1e-300)
    start = v[idx] + 0.05 * edge_len * n_unit  # lift off the surface so faces do not cut the arrows
    d = vec[idx] * scale
    ax.quiver(*start.T, *d.T, length=1.0, normalize=False, arrow_length_ratio=0.3, color="#d62728",
              linewidths=0.8, zorder=2)


def _is_closed(f: np.ndarray) -> bool:
    """Every undirected edge is shared by exactly two faces."""
    e = np.sort(np.stack([f, np.roll(f, -1, axis=1)], axis=-1).reshape(-1, 2), axis=1)
    _, counts = np.unique(e[:, 0] * (int(f.max()) + 1) + e[:, 1], return_counts=True)
    return bool(np.all(counts == 2))

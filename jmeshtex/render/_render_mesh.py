"""``render_mesh``: the one-call picture of a mesh (colours, scalars, texture, arrows, edges, title).

It is :func:`jmeshtex.render.render` from an ``(elevation, azimuth)`` view, plus overlays drawn
in image space with PIL: tangent vectors as arrows (hidden where the surface covers them, by the
depth buffer), edges as red lines on top, and a title strip.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from .._errors import InputError
from .._mesh import Mesh
from .._types import ArrayLike, Float, Int, Num
from ..io import save_png
from ._camera import _check_size, view_camera
from ._render import _Scene, to_uint8
from ._visibility import project

_RED = (214, 39, 40)  # matplotlib's "#d62728"


def render_mesh(
    mesh: Mesh | tuple,
    path: str | os.PathLike | None = None,
    *,
    face_colors: Num[ArrayLike, "F C"] | None = None,
    scalars: Float[ArrayLike, " V_or_F"] | None = None,
    cmap: str = "viridis",
    clim: tuple[float, float] | None = None,
    vectors: Float[ArrayLike, "V 3"] | None = None,
    vector_scale: float | None = None,
    max_arrows: int = 1500,
    edges: Int[ArrayLike, "E 2"] | None = None,
    view: tuple[float, float] = (25.0, -60.0),
    size: tuple[int, int] = (512, 512),
    title: str | None = None,
    up: str | Sequence[float] = "z",
    shading: str = "smooth",
) -> np.ndarray:
    """Render a triangle mesh off-screen to an RGB image, optionally writing it as a PNG.

    The picture is :func:`jmeshtex.render.render` (per-pixel visibility, smooth shading with one
    directional light above-left of the camera, 2×2 supersampling) from an orthographic camera at
    ``view = (elevation, azimuth)`` about ``up``, framed so the bounding sphere spans 92 % of the
    shorter side:

    .. math:: c = a\\,(0.3 + 0.7 \\max(0, n\\cdot\\ell)) + 0.12 \\max(0, n\\cdot h)^{32}

    The colours are the mesh's own (as :func:`jmeshtex.render.render`: its UV texture, else its
    vertex colours, else light grey), or ``face_colors`` or ``scalars`` instead.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])`` (world frame, ``up``
        pointing up); a ``Mesh``'s ``uv`` + ``texture`` (looked up per pixel, trilinear,
        mip-mapped) or ``vertex_colors`` colour it. Other colours:
        ``mesh.replace(vertex_colors=c)`` or ``Mesh(v, f, vertex_colors=c)``.
      path: where to write a PNG (parent folders are created; written to a temporary name and
        renamed, so a reader never sees a half-written file). ``None``: only return the image.
      face_colors: ``[F, 3|4]`` colours, one per face (float in [0, 1], clipped, or uint8).
      scalars: ``[V]`` per-vertex or ``[F]`` per-face values mapped through ``cmap`` (per-vertex
        when ``V == F``).
      cmap: a matplotlib colormap name.
      clim: ``(vmin, vmax)`` for ``scalars``; default their min and max.
      vectors: ``[V, 3]`` tangent field drawn as arrows from the vertices (3D, world frame); arrows
        whose base the surface hides (depth test) are left out.
      vector_scale: arrow length per unit of ``|vector|``; default: the longest arrow is 0.9 mean
        edge lengths.
      max_arrows: draw at most this many arrows (an evenly spaced subset of the vertices).
      edges: ``[E, 2]`` vertex pairs drawn as red lines on top (e.g. boundary loops, seams).
      view: ``(elevation, azimuth)`` of the camera in degrees (matplotlib's convention for ``up="z"``).
      size: ``(width, height)`` in pixels.
      title: text in a strip at the top of the image.
      up: world up axis, ``"x"|"y"|"z"|"-x"|"-y"|"-z"`` or a 3-vector (``"y"`` for most OBJ files).
      shading: ``"smooth"``, ``"flat"`` or ``"unlit"``.

    Returns:
      ``[height, width, 3]`` uint8 RGB image.

    Raises:
      InputError: wrong shapes, non-finite values, both ``face_colors`` and ``scalars``, unknown
        colormap.
      MeshIOError: the PNG cannot be written.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> v, f = icosphere(1)
      >>> img = render_mesh((v, f), scalars=v[:, 2], size=(64, 48))
      >>> img.shape, img.dtype
      ((48, 64, 3), dtype('uint8'))
    """
    scene = _Scene(
        mesh, face_colors=face_colors, scalars=scalars, cmap=cmap, clim=clim, shading=shading
    )
    v = scene.vertices
    width, height = _check_size(size)
    elev, azim = _check_view(view)
    vec = None if vectors is None else _check_vectors(vectors, len(v))
    e = None if edges is None else _check_edges(edges, len(v))
    strip = 0 if title is None else int(min(26, max(12, round(0.12 * height))))
    if height - strip < 16:
        raise InputError(f"size {size!r} leaves no room for the picture under a title")
    camera = view_camera(v, elev, azim, up=up, size=(width, height - strip))
    vis = scene.visibility(camera, 2)
    image = to_uint8(scene.shade(vis, "white"))
    if vec is not None or e is not None:
        image = _overlays(image, scene, vis, vec, vector_scale, max_arrows, e)
    if title is not None:
        image = np.concatenate([title_strip(str(title), width, strip), image], axis=0)
    if path is not None:
        save_png(image, path, parents=True)
    return image


def font(px: int):
    """PIL's bundled font at ``px`` pixels (FreeType; the bitmap default where FreeType is missing)."""
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=max(6, int(px)))
    except (TypeError, OSError, ImportError):  # pragma: no cover - Pillow without FreeType
        return ImageFont.load_default()


def title_strip(text: str, width: int, height: int) -> np.ndarray:
    """A white ``[height, width, 3]`` strip with ``text`` centred in black."""
    from PIL import Image, ImageDraw

    img = Image.new("RGB", (width, height), "white")
    if text:
        draw = ImageDraw.Draw(img)
        fnt = font(round(height * 0.62))
        draw.text((width / 2, height / 2), text, fill="black", font=fnt, anchor="mm")
    return np.asarray(img)


def _overlays(image, scene, vis, vec, vector_scale, max_arrows, e) -> np.ndarray:
    from PIL import Image, ImageDraw

    cam = vis.camera
    v, f = scene.vertices, scene.faces
    screen, _ = project(v, cam, cam.width, cam.height)
    pil = Image.fromarray(image)
    draw = ImageDraw.Draw(pil)
    lw = max(1, round(min(cam.width, cam.height) / 300))
    if vec is not None:
        edge_len = float(np.linalg.norm(v[f] - v[np.roll(f, -1, axis=1)], axis=-1).mean())
        normal = scene.normals.reshape(-1, 3)
        vertex_normal = np.zeros_like(v)
        np.add.at(vertex_normal, f.ravel(), normal)
        keep = (np.linalg.norm(vec, axis=1) > 0) & _unoccluded(v, vis, tol=0.5 * edge_len)
        idx = np.nonzero(keep)[0]
        if len(idx) > max_arrows:
            idx = idx[np.linspace(0, len(idx) - 1, max_arrows).round().astype(np.int64)]
        if len(idx):
            longest = float(np.linalg.norm(vec[idx], axis=1).max())
            scale = 0.9 * edge_len / longest if vector_scale is None else float(vector_scale)
            n_unit = vertex_normal[idx] / np.maximum(
                np.linalg.norm(vertex_normal[idx], axis=1, keepdims=True), 1e-300
            )
            start = v[idx] + 0.05 * edge_len * n_unit
            a, _ = project(start, cam, cam.width, cam.height)
            b, _ = project(start + vec[idx] * scale, cam, cam.width, cam.height)
            for p, q in zip(a - 0.5, b - 0.5, strict=True):
                if not (np.isfinite(p).all() and np.isfinite(q).all()):
                    continue
                draw.line([tuple(p), tuple(q)], fill=_RED, width=lw)
                d = q - p
                length = float(np.hypot(*d))
                if length > 2.0:
                    for ang in (2.7, -2.7):  # the two barbs of the head, 0.3 of the shaft long
                        c, s = np.cos(ang), np.sin(ang)
                        tip = q + 0.3 * np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]])
                        draw.line([tuple(q), tuple(tip)], fill=_RED, width=lw)
    if e is not None:
        pts = screen - 0.5
        for i, j in e:
            p, q = pts[i], pts[j]
            if np.isfinite(p).all() and np.isfinite(q).all():
                draw.line([tuple(p), tuple(q)], fill=_RED, width=max(lw, 2))
    return np.asarray(pil)


def _unoccluded(points: np.ndarray, vis, *, tol: float) -> np.ndarray:
    """``[N]`` bool: points no farther than ``tol`` behind the surface the buffer sees at their pixel."""
    cam = vis.camera
    H, W = vis.face.shape
    px, z = project(points, cam, W, H)
    inside = (
        np.isfinite(px).all(axis=1)
        & (px[:, 0] >= 0)
        & (px[:, 0] < W)
        & (px[:, 1] >= 0)
        & (px[:, 1] < H)
    )
    col = np.clip(np.nan_to_num(px[:, 0]), 0, W - 1).astype(np.int64)
    row = np.clip(np.nan_to_num(px[:, 1]), 0, H - 1).astype(np.int64)
    seen = vis.depth[row, col]
    return inside & (z <= seen + tol)


def _check_view(view) -> tuple[float, float]:
    try:
        elev, azim = (float(x) for x in view)
    except (TypeError, ValueError) as err:
        raise InputError(f"view must be (elevation, azimuth) in degrees, got {view!r}") from err
    if not (np.isfinite(elev) and np.isfinite(azim)):
        raise InputError(f"view angles must be finite, got {view!r}")
    return elev, azim


def _check_vectors(vectors, n_vertices: int) -> np.ndarray:
    vec = np.asarray(vectors)
    if (
        vec.shape != (n_vertices, 3)
        or not np.issubdtype(vec.dtype, np.number)
        or np.iscomplexobj(vec)
    ):
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
    if (
        e.ndim != 2
        or e.shape[1] != 2
        or not np.issubdtype(e.dtype, np.integer)
        or ((e < 0) | (e >= n_vertices)).any()
    ):
        raise InputError(
            f"edges must be integer vertex pairs [E, 2] in [0, {n_vertices}), got shape {e.shape}"
        )
    return e

"""Figures: tiled panels with labels (:func:`figure`, :func:`render_grid`) and turntables.

Layout only, with NumPy and PIL (text); every PNG is written atomically through :mod:`jmeshtex.io`.
"""

from __future__ import annotations

import io as _io
import os
import pathlib
from collections.abc import Sequence

import numpy as np

from .._errors import InputError
from ..io import atomic_write, save_png
from ._camera import orbit_cameras
from ._render import image01, render_views
from ._render_mesh import title_strip

_STRIP = 20  # title strip above each tile, pixels


def as_rgb(image, name: str) -> np.ndarray:
    """An image ``[H, W]`` / ``[H, W, 3|4]`` (uint8 or float in [0, 1]) as uint8 RGB ``[H, W, 3]``.

    RGBA images are composited over white.
    """
    img = np.asarray(image)
    if img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3 and min(img.shape[:2]) >= 1:
        return img
    f = image01(img, name)
    if f.shape[2] == 4:
        f = f[..., :3] * f[..., 3:] + (1.0 - f[..., 3:])
    return np.round(f * 255.0).astype(np.uint8)


def render_grid(
    images: Sequence[np.ndarray],
    path: str | os.PathLike | None = None,
    *,
    titles: Sequence[str] | None = None,
    columns: int | None = None,
) -> np.ndarray:
    """Tile several images into one panel (row-major), each with an optional title above it.

    Args:
      images: ``N`` images ``[H, W]``, ``[H, W, 3]`` or ``[H, W, 4]`` (uint8, or float in [0, 1];
        RGBA over white); sizes may differ (each cell is as large as the largest image, the image
        centred in it).
      path: where to write the panel as a PNG (atomically); ``None``: only return it.
      titles: ``N`` strings (or None) shown above the images.
      columns: images per row; default ``ceil(sqrt(N))``.

    Returns:
      ``[rows·(h + title strip), columns·w, 3]`` uint8 RGB panel (title strips are 20 px).

    Example:
      >>> tiles = [np.zeros((20, 30, 3), np.uint8), np.ones((20, 30))]
      >>> render_grid(tiles, titles=["black", "white"]).shape  # 2 columns, 20 px title strips
      (40, 60, 3)
      >>> render_grid(tiles, columns=1).shape
      (40, 30, 3)
    """
    if len(images) == 0:
        raise InputError("render_grid needs at least one image")
    tiles = [as_rgb(img, f"images[{i}]") for i, img in enumerate(images)]
    if titles is not None and len(titles) != len(tiles):
        raise InputError(
            f"got {len(titles)} titles for {len(tiles)} images: pass one title per image"
        )
    n = len(tiles)
    cols = int(columns) if columns is not None else int(np.ceil(np.sqrt(n)))
    if cols < 1:
        raise InputError(f"columns must be >= 1, got {columns}")
    rows = -(-n // cols)
    cell_w = max(t.shape[1] for t in tiles)
    cell_h = max(t.shape[0] for t in tiles)
    strip = 0 if titles is None else _STRIP
    panel = np.full((rows * (cell_h + strip), cols * cell_w, 3), 255, np.uint8)
    for i, tile in enumerate(tiles):
        r, c = divmod(i, cols)
        h, w = tile.shape[:2]
        top = r * (cell_h + strip)
        if strip and titles[i]:
            panel[top : top + strip, c * cell_w : (c + 1) * cell_w] = title_strip(
                str(titles[i]), cell_w, strip
            )
        y = top + strip + (cell_h - h) // 2
        x = c * cell_w + (cell_w - w) // 2
        panel[y : y + h, x : x + w] = tile
    if path is not None:
        save_png(panel, path, parents=True)
    return panel


def figure(
    panels: Sequence[tuple[str, np.ndarray]],
    *,
    columns: int | None = None,
    title: str | None = None,
    path: str | os.PathLike | None = None,
) -> np.ndarray:
    """The labelled-panel figure every CLI, demo, notebook and benchmark writes.

    Panels (e.g. exemplar | result(s) | baselines) are tiled row-major under their labels, with an
    optional title strip across the top.

    Args:
      panels: ``(label, image)`` pairs; images ``[H, W]``, ``[H, W, 3|4]``, uint8 or float in [0, 1].
      columns: panels per row; default all in one row up to 4, else ``ceil(sqrt(N))``.
      title: text across the top (28 px strip).
      path: where to write the figure as a PNG (atomically); ``None``: only return it.

    Returns:
      ``[H, W, 3]`` uint8 RGB figure.

    Raises:
      InputError: no panels, a panel that is not a ``(label, image)`` pair, a bad image.

    Example:
      >>> a, b = np.zeros((32, 32, 3), np.uint8), np.ones((32, 32, 3))
      >>> figure([("exemplar", a), ("result", b)], title="demo").shape  # 28 + 20 + 32 rows
      (80, 64, 3)
    """
    items = list(panels)
    if not items:
        raise InputError("figure needs at least one (label, image) panel")
    for i, item in enumerate(items):
        if not (isinstance(item, (tuple, list)) and len(item) == 2 and isinstance(item[0], str)):
            raise InputError(
                f"panels[{i}] must be a (label, image) pair, got {type(item).__name__}"
            )
    cols = columns if columns is not None else (len(items) if len(items) <= 4 else None)
    grid = render_grid(
        [img for _, img in items], titles=[label for label, _ in items], columns=cols
    )
    if title is not None:
        grid = np.concatenate([title_strip(str(title), grid.shape[1], 28), grid], axis=0)
    if path is not None:
        save_png(grid, path, parents=True)
    return grid


def turntable(
    mesh,
    path: str | os.PathLike | None = None,
    *,
    n: int = 8,
    elevation: float = 20.0,
    up: str | Sequence[float] = "z",
    size: tuple[int, int] = (256, 256),
    gif: bool = False,
    frame_ms: int = 250,
    **options,
) -> np.ndarray:
    """``n`` views around the mesh at one elevation: a PNG strip and, optionally, an animated GIF.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or ``(vertices, faces)``.
      path: the PNG strip to write (atomically); with ``gif=True`` also ``path`` with suffix
        ``.gif``. ``None``: only return the strip.
      n: number of views (azimuths ``0, 360/n, ...`` about ``up``).
      elevation: camera elevation in degrees.
      up: world up axis (``"y"`` for most OBJ files).
      size: ``(width, height)`` per view.
      gif: also write an animated GIF (looping, ``frame_ms`` per frame).
      frame_ms: GIF frame duration in milliseconds.
      **options: colour and shading options of :func:`jmeshtex.render.render`.

    Returns:
      ``[height, n · width, 3]`` uint8 strip.

    Example:
      >>> from jmeshtex.data import torus
      >>> turntable(torus(12, 6), n=4, size=(32, 32)).shape
      (32, 128, 3)
    """
    if int(n) < 1:
        raise InputError(f"turntable needs n >= 1 views, got {n}")
    cams = orbit_cameras(mesh, azimuths=int(n), elevations=(float(elevation),), up=up, size=size)
    views = render_views(mesh, cams, **options)
    rgb = [as_rgb(v, "view") for v in views]
    strip = np.concatenate(rgb, axis=1)
    if path is not None:
        path = pathlib.Path(path)
        save_png(strip, path, parents=True)
        if gif:
            from PIL import Image

            frames = [Image.fromarray(v) for v in rgb]
            buf = _io.BytesIO()
            frames[0].save(
                buf,
                format="GIF",
                save_all=True,
                append_images=frames[1:],
                duration=int(frame_ms),
                loop=0,
            )
            atomic_write(path.with_suffix(".gif"), buf.getvalue())
    elif gif:
        raise InputError("turntable(gif=True) needs a path to write the GIF to")
    return strip

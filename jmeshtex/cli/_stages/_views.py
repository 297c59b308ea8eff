"""The views every demo stage draws: one camera of the standard rig, smooth-shaded by the renderer.

Each stage lays its panels out with :func:`jmeshtex.render.figure` (exemplar | result(s) |
baselines); :func:`view` renders one panel from :func:`jmeshtex.render.orbit_cameras`, so stages,
the README figures and the evaluation protocol share one rig.
"""

from __future__ import annotations

import os
import pathlib
from collections.abc import Callable

import numpy as np

PANEL = (300, 280)  # (width, height) of one panel

#: a stage's progress hook: called with a short status line (the demo shows it on its bar)
Progress = Callable[[str], None] | None


def view(
    mesh,
    *,
    azimuth: float = -60.0,
    elevation: float = 25.0,
    size: tuple[int, int] = PANEL,
    up: str = "z",
    **options,
) -> np.ndarray:
    """``[H, W, 3]`` uint8 render of ``mesh`` from one camera of the standard rig.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` (its own texture or colours are drawn unless ``options``
        give a colour source) or ``(vertices, faces)``.
      azimuth, elevation: degrees about / above ``up`` (:func:`~jmeshtex.render.orbit_cameras`).
      size: ``(width, height)``.
      up: world up axis.
      **options: shading options of :func:`jmeshtex.render.render`; ``vertex_colors`` or ``uv``
        with ``texture`` colour the mesh instead of its own colours.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> view(icosphere(1), size=(40, 30)).shape
      (30, 40, 3)
    """
    from ..._mesh import Mesh, as_mesh
    from ...render import orbit_cameras, render

    colours = {k: options.pop(k) for k in ("vertex_colors", "uv", "texture") if k in options}
    if colours:
        m = as_mesh(mesh)
        mesh = Mesh(m.vertices, m.faces, **colours)
    camera = orbit_cameras(
        mesh, azimuths=(float(azimuth),), elevations=(float(elevation),), up=up, size=size
    )[0]
    return render(mesh, camera, **options)


def say(progress: Progress, text: str) -> None:
    """Report ``text`` to a stage's progress hook (no-op without one)."""
    if progress is not None:
        progress(text)


def folder(out_dir: str | os.PathLike) -> pathlib.Path:
    """A stage's output folder, created (with its parents) if missing."""
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return out

"""Spot, Keenan Crane's textured cow, embedded (public domain; see ``spot_README.txt``).

Stored in ``spot.npz``: the triangulated mesh (2,930 vertices, 5,856 faces, y up), its per-corner
UV atlas and its 1024² texture as 8-bit colours; converted once from the author's
``spot_triangulated.obj`` and ``spot_texture.png`` (positions to float32, a change below 6e-8).
The FLDM model shipped with the package was trained on Spot, and ``jmeshtex demo`` samples it here.
"""

from __future__ import annotations

import functools
import pathlib

import numpy as np

from .._mesh import Mesh

_FILE = pathlib.Path(__file__).with_name("spot.npz")


@functools.cache
def _arrays() -> dict[str, np.ndarray]:
    with np.load(_FILE) as z:
        return {k: z[k] for k in z.files}


def spot() -> Mesh:
    """Spot with its UV atlas and texture (``[1024, 1024, 3]`` float32 in [0, 1]), y up.

    Example:
      >>> m = spot()
      >>> m.vertices.shape, m.faces.shape, m.uv.shape, m.texture.shape
      ((2930, 3), (5856, 3), (5856, 3, 2), (1024, 1024, 3))
    """
    a = _arrays()
    return Mesh(
        a["vertices"].astype(np.float64),
        a["faces"].astype(np.int64),
        uv=a["uv"].astype(np.float64),
        texture=a["texture"].astype(np.float32) / 255.0,
        name="spot",
    )

"""The host precomputation of a mesh CNN: texel atlas, level-0 exp-map taps and the pooling pyramid."""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np

from .._mesh import Mesh, as_mesh
from ..geometry import tracer_geometry
from ._atlas import FRAME_SMOOTHING, TextureAtlas, texture_atlas
from ._neighborhood import texel_taps
from ._pyramid import BACKOFF, TexelPyramid, texel_pyramid


class Surface(NamedTuple):
    """The precomputed surface of a mesh CNN: texel atlas and pooling pyramid (host arrays).

    Attributes:
      atlas: :class:`~jmeshtex.surfacecnn.core.TextureAtlas`.
      pyramid: :class:`~jmeshtex.surfacecnn.core.TexelPyramid`.
      seconds: ``{"atlas": s, "taps": s, "pyramid": s}`` host time of each stage.
    """

    atlas: TextureAtlas
    pyramid: TexelPyramid
    seconds: dict


def prepare_surface(
    mesh: Mesh | tuple,
    *,
    size: int,
    levels: int,
    boundary: str = "opposite",
    rotation: float | np.ndarray = 0.0,
    frames: str = "global",
    frame_vector=(1.0, 0.0, 0.0),
    frame_smoothing: float = FRAME_SMOOTHING,
    backoff: tuple[float, ...] = BACKOFF,
    couple: bool = True,
) -> Surface:
    """Atlas, level-0 taps and the pooling pyramid of a mesh (the whole host precomputation).

    Args:
      mesh: a :class:`~jmeshtex.Mesh` (consistently oriented, manifold); its ``uv`` (``[F, 3, 2]``)
        lays out the texture, and a mesh without UVs (or a ``(vertices, faces)`` pair) is unwrapped
        with xatlas.
      size: texture resolution (``size × size`` texels).
      levels: pooling levels (:func:`~jmeshtex.surfacecnn.core.required_levels`).
      boundary: failed-walk rule (:func:`~jmeshtex.surfacecnn.core.texel_taps`; default the reference's
        ``"opposite"``, as :class:`~jmeshtex.surfacecnn.Config`).
      rotation: tap-frame rotation (radians, scalar or per texel).
      frames, frame_vector, frame_smoothing: the tangent frames
        (:func:`~jmeshtex.surfacecnn.core.texture_atlas`).
      backoff: overshoot back-off fractions (:func:`~jmeshtex.surfacecnn.core.texel_pyramid`).
      couple: every texel read by another texel's taps (:func:`~jmeshtex.surfacecnn.core.texel_taps`;
        default True).

    Returns:
      :class:`Surface`.

    Example:
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> s = prepare_surface(Mesh(v, f, uv=v[f][..., :2]), size=8, levels=2)
      >>> s.atlas.num_texels, [len(r) for r in s.pyramid.representative]
      (64, [64, 16, 4])
    """
    mesh = as_mesh(mesh)
    vertices, faces = mesh.vertices, mesh.faces
    t0 = time.perf_counter()
    geometry = tracer_geometry(vertices, faces)
    atlas = texture_atlas(
        vertices,
        faces,
        mesh.uv,
        size=size,
        frames=frames,
        frame_vector=frame_vector,
        frame_smoothing=frame_smoothing,
        geometry=geometry,
    )
    t1 = time.perf_counter()
    taps = texel_taps(
        vertices,
        faces,
        atlas,
        boundary=boundary,
        rotation=rotation,
        couple=couple,
        geometry=geometry,
    )
    t2 = time.perf_counter()
    pyramid = texel_pyramid(
        vertices,
        faces,
        atlas,
        levels=levels,
        boundary=boundary,
        rotation=rotation,
        backoff=backoff,
        taps=taps,
        geometry=geometry,
    )
    t3 = time.perf_counter()
    return Surface(atlas, pyramid, {"atlas": t1 - t0, "taps": t2 - t1, "pyramid": t3 - t2})

"""A synthesis result on disk: a folder with the texture, the textured mesh, renders and ``result.npz``.

``result.npz`` holds everything :func:`load` needs (texture, colours, loss curve, the mesh's arrays,
the stats as JSON) at full precision; the PNGs and the OBJ are for people and other tools.
"""

from __future__ import annotations

import json
import os
import pathlib

import numpy as np

from .._mesh import Mesh
from ._image import as_rgb
from ._synthesis import SynthesisResult

RESULT_FILE = "result.npz"
_MESH_ARRAYS = ("vertices", "faces", "uv", "vertex_colors", "split_faces", "split_to_merged")


def _plain(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return value


def save(
    result: SynthesisResult,
    path: str | os.PathLike,
    *,
    exemplar: np.ndarray | None = None,
    title: str = "surface CNN",
    render_size: tuple[int, int] = (420, 400),
    views_azimuths: int = 4,
) -> dict:
    """Write a synthesis result to a folder (created if needed); :func:`load` reads it back.

    Files in ``path``: ``result.npz`` (the arrays :func:`load` reads); ``texture.png`` (UV layout);
    ``textured.obj`` (+ ``textured.mtl``, ``textured.png``); ``render_front.png``,
    ``render_back.png``, ``surfacecnn.png`` (exemplar and both views side by side); ``views.png``
    (``views_azimuths`` views around the object from :func:`jmeshtex.render.orbit_cameras`);
    ``summary.json`` (timings, sizes, the loss curve). Every file is written atomically.

    Args:
      result: from :func:`~jmeshtex.surfacecnn.synthesize` or :func:`~jmeshtex.surfacecnn.stylize`.
      path: the output folder.
      exemplar: ``[H, W, 3]`` image shown first in ``surfacecnn.png`` (optional).
      title: title of the renders.
      render_size: ``(width, height)`` of each render in pixels.
      views_azimuths: number of orbit views in ``views.png``.

    Returns:
      The summary dict (also in ``summary.json``), with the paths written under ``"files"``.

    Example:
      >>> import tempfile, jax
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn import Config, synthesize
      >>> v, f = grid(2)
      >>> r = synthesize(Mesh(v, f, uv=v[f][..., :2]), np.full((8, 8, 3), 0.5), Config(size=8, steps=2),
      ...                key=jax.random.key(0), layers=("relu1_1",), progress=False)
      >>> sorted(p.rsplit("/", 1)[-1] for p in save(r, tempfile.mkdtemp())["files"])[:3]
      ['render_back.png', 'render_front.png', 'result.npz']
    """
    from .. import render
    from ..io import atomic_save_npz, atomic_write, save_mesh, save_png

    out = pathlib.Path(path)
    out.mkdir(parents=True, exist_ok=True)
    m = result.mesh
    stats = {k: _plain(v) for k, v in result.stats.items()}
    arrays = {
        "texture": np.asarray(result.texture, np.float32),
        "colors": np.asarray(result.colors, np.float32),
        "losses": np.asarray(result.losses, np.float64),
        "final_loss": np.asarray(result.final_loss),
        "meta": np.asarray(json.dumps({"stats": stats, "name": m.name})),
    }
    arrays.update(
        {f"mesh_{k}": np.asarray(getattr(m, k)) for k in _MESH_ARRAYS if getattr(m, k) is not None}
    )
    atomic_save_npz(out / RESULT_FILE, arrays)
    save_png(result.texture, out / "texture.png")
    save_mesh(m.replace(name="textured"), out / "textured.obj")
    views = []
    for name, view in (("render_front.png", (20.0, -60.0)), ("render_back.png", (20.0, 120.0))):
        image = render.render_mesh(
            m.replace(texture=result.texture),
            view=view,
            size=render_size,
            title=f"{title} ({name[7:-4]})",
        )
        save_png(image, out / name)
        views.append(image)
    panels, titles = list(views), [None, None]
    if exemplar is not None:
        panels.insert(0, as_rgb(exemplar, "exemplar"))
        titles.insert(0, "exemplar")
    panels.append(result.texture)
    titles.append("texture (UV layout)")
    height = max(
        np.shape(v)[0] for v in views
    )  # small images enlarged (nearest, integer factor) to the renders'
    panels = [
        np.repeat(
            np.repeat(pn, max(1, height // np.shape(pn)[0]), 0),
            max(1, height // np.shape(pn)[0]),
            1,
        )
        for pn in panels
    ]
    save_png(render.render_grid(panels, titles=titles, columns=len(panels)), out / "surfacecnn.png")
    cameras = render.orbit_cameras(m, azimuths=views_azimuths, elevations=(20.0,), size=(256, 256))
    orbit = render.render_views(m.replace(texture=result.texture), cameras)
    render.figure(
        [(f"azimuth {360 * i / views_azimuths:.0f}°", img) for i, img in enumerate(orbit)],
        columns=views_azimuths,
        title=title,
        path=out / "views.png",
    )
    files = [
        str(out / n)
        for n in (
            RESULT_FILE,
            "texture.png",
            "textured.obj",
            "render_front.png",
            "render_back.png",
            "surfacecnn.png",
            "views.png",
            "summary.json",
        )
    ]
    summary = {
        **{k: (float(v) if isinstance(v, float) else v) for k, v in stats.items()},
        "losses": [float(x) for x in result.losses],
        "files": files,
    }
    atomic_write(out / "summary.json", (json.dumps(summary, indent=2) + "\n").encode())
    return summary


def load(path: str | os.PathLike) -> SynthesisResult:
    """Read a result written by :func:`save` (from its ``result.npz``).

    Args:
      path: the folder given to :func:`save`.

    Returns:
      :class:`~jmeshtex.surfacecnn.SynthesisResult` with the saved texture, colours, losses, mesh
      (UVs and texture included) and stats; ``surface`` is None (rebuild it with
      :func:`~jmeshtex.surfacecnn.prepare_surface` if needed).

    Raises:
      MeshIOError: the folder holds no readable ``result.npz``.

    Example:
      >>> import tempfile, jax
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn import Config, synthesize
      >>> v, f = grid(2)
      >>> r = synthesize(Mesh(v, f, uv=v[f][..., :2]), np.full((8, 8, 3), 0.5), Config(size=8, steps=2),
      ...                key=jax.random.key(0), layers=("relu1_1",), progress=False)
      >>> folder = tempfile.mkdtemp()
      >>> _ = save(r, folder)
      >>> bool(np.array_equal(load(folder).texture, r.texture))
      True
    """
    from .._errors import MeshIOError
    from ..io import load_npz

    data = load_npz(pathlib.Path(path) / RESULT_FILE, "surface-CNN result")
    try:
        meta = json.loads(str(data["meta"]))
        mesh = Mesh(
            **{k: data[f"mesh_{k}"] for k in _MESH_ARRAYS if f"mesh_{k}" in data},
            texture=data["texture"],
            name=meta["name"],
        )
        return SynthesisResult(
            texture=data["texture"],
            colors=data["colors"],
            mesh=mesh,
            losses=data["losses"],
            final_loss=float(data["final_loss"]),
            surface=None,
            stats=meta["stats"],
        )
    except (KeyError, TypeError, ValueError) as err:
        raise MeshIOError(
            f"{pathlib.Path(path) / RESULT_FILE} is not a surface-CNN result ({err})"
        ) from err

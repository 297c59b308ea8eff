"""A synthesis result on disk: a folder with ``result.npz``, the texture and the textured mesh.

``result.npz`` holds everything :func:`load` needs (texture, colours, loss curve, the mesh's arrays,
the stats as JSON) at full precision; the texture PNG and the OBJ are for people and other tools.
Data only: renders are made by the CLI (:mod:`jmeshtex.render`).
"""

from __future__ import annotations

import json
import os
import pathlib

import numpy as np

from .._mesh import Mesh
from ._synthesis import SynthesisResult

RESULT_FILE = "result.npz"
_MESH_ARRAYS = ("vertices", "faces", "uv", "vertex_colors", "split_faces", "split_to_merged")


def _plain(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return value


def save(result: SynthesisResult, path: str | os.PathLike) -> pathlib.Path:
    """Write a synthesis result's data to a folder (created if needed); :func:`load` reads it back.

    Files in ``path``: ``result.npz`` (the arrays :func:`load` reads); ``texture.png`` (the texture
    in the UV layout); ``textured.obj`` (+ ``textured.mtl``, ``textured.png``); ``summary.json``
    (timings, sizes, the loss curve). Every file is written atomically. Renders are not data: the
    CLI (``jmeshtex surfacecnn synthesize``) and :mod:`jmeshtex.render` make them.

    Args:
      result: from :func:`~jmeshtex.surfacecnn.synthesize` or :func:`~jmeshtex.surfacecnn.stylize`.
      path: the output folder.

    Returns:
      The folder (as every method's ``save``); ``summary.json`` in it lists the files written
      under ``"files"``.

    Raises:
      InputError: ``result`` is not a :class:`~jmeshtex.surfacecnn.SynthesisResult`.

    Example:
      >>> import tempfile, jax
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.surfacecnn import Config, synthesize
      >>> v, f = grid(2)
      >>> r = synthesize(Mesh(v, f, uv=v[f][..., :2]), np.full((8, 8, 3), 0.5), Config(size=8, steps=2),
      ...                key=jax.random.key(0), layers=("relu1_1",), progress=False)
      >>> sorted(p.name for p in save(r, tempfile.mkdtemp()).iterdir())
      ['result.npz', 'summary.json', 'texture.png', 'textured.mtl', 'textured.obj', 'textured.png']
    """
    from .._errors import InputError
    from ..io import atomic_save_npz, atomic_write, save_mesh, save_png

    if not isinstance(result, SynthesisResult):
        raise InputError(
            f"save(result, path): expected a jmeshtex.surfacecnn.SynthesisResult first, "
            f"got {type(result).__name__}"
        )
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
    files = [str(out / n) for n in (RESULT_FILE, "texture.png", "textured.obj", "summary.json")]
    summary = {
        **{k: (float(v) if isinstance(v, float) else v) for k, v in stats.items()},
        "losses": [float(x) for x in result.losses],
        "files": files,
    }
    atomic_write(out / "summary.json", (json.dumps(summary, indent=2) + "\n").encode())
    return out


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

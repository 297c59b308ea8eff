"""A trained DGTS hierarchy (:class:`Model`) and its files (:func:`save`, :func:`load`).

A model folder is written with :class:`jmeshtex.io.Checkpoints` (orbax; atomic: an interrupted save
leaves no half-written model): the parameter arrays as one pytree, the config and the number of
levels as its JSON record. (Training checkpoints, :func:`~jmeshtex.dgts.train`'s ``checkpoint_dir``,
use the same mechanism with the optimiser state added; they are not model folders.)
"""

from __future__ import annotations

import dataclasses
import functools
import os
import pathlib
from typing import Any

import jax
import numpy as np

from .._errors import MeshIOError
from ..io import Checkpoints
from ..ops import FaceConvStackParams
from ._config import Config
from ._networks import init_level

#: the ``kind`` recorded with a model folder
MODEL_KIND = "jmeshtex.dgts.Model"


@functools.partial(
    jax.tree_util.register_dataclass,
    data_fields=["generators", "discriminators", "z_star"],
    meta_fields=["config"],
)
@dataclasses.dataclass(frozen=True, eq=False)
class Model:
    """A trained (or partly trained) DGTS hierarchy: the parameters bundled with their config.

    A pytree: the parameters and ``z_star`` are its leaves, ``config`` is static.

    Attributes:
      config: the :class:`~jmeshtex.dgts.Config` it was trained with (widths, activation, noise
        amplitude, scale factor: everything :func:`~jmeshtex.dgts.transfer` needs).
      generators: one :class:`~jmeshtex.ops.FaceConvStackParams` per trained level, coarsest first.
      discriminators: the matching critics (kept to warm-start the next level).
      z_star: ``[V_0, 3]`` float32 fixed reconstruction noise of the coarsest level.

    Example:
      >>> import jax.numpy as jnp
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> g = init_level(c, 0, generator=True, key=jax.random.key(0))
      >>> d = init_level(c, 0, generator=False, key=jax.random.key(1))
      >>> m = Model(c, (g,), (d,), np.zeros((12, 3), np.float32))
      >>> m.num_levels, len(jax.tree.leaves(m))
      (1, 9)
    """

    config: Config
    generators: tuple[FaceConvStackParams, ...]
    discriminators: tuple[FaceConvStackParams, ...]
    z_star: np.ndarray

    @property
    def num_levels(self) -> int:
        """Number of trained levels."""
        return len(self.generators)

    def replace(self, **changes: Any) -> Model:
        """A copy with some fields replaced."""
        return dataclasses.replace(self, **changes)


def model_state(model: Model) -> dict:
    """The array pytree stored for ``model``."""
    return {
        "generators": tuple(model.generators),
        "discriminators": tuple(model.discriminators),
        "z_star": np.asarray(model.z_star, np.float32),
    }


def model_like(config: Config, levels: int, num_vertices: int) -> dict:
    """The structure, shapes and dtypes of :func:`model_state` for ``levels`` levels (for restoring)."""
    key = jax.random.key(0)
    return {
        "generators": tuple(init_level(config, i, generator=True, key=key) for i in range(levels)),
        "discriminators": tuple(
            init_level(config, i, generator=False, key=key) for i in range(levels)
        ),
        "z_star": np.zeros((num_vertices, 3), np.float32),
    }


def save(model: Model, path: str | os.PathLike) -> pathlib.Path:
    """Write ``model`` into the folder ``path``, atomically (read it back with :func:`load`).

    Args:
      model: a :class:`Model` (``train(...).model``).
      path: the folder; created if needed, a model already there is replaced.

    Returns:
      The folder.

    Example:
      >>> import tempfile
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> g = init_level(c, 0, generator=True, key=jax.random.key(0))
      >>> d = init_level(c, 0, generator=False, key=jax.random.key(1))
      >>> folder = save(Model(c, (g,), (d,), np.zeros((12, 3), np.float32)), tempfile.mkdtemp())
      >>> load(folder).num_levels
      1
    """
    folder = pathlib.Path(path)
    meta = {
        "kind": MODEL_KIND,
        "config": model.config.to_dict(),
        "levels": model.num_levels,
        "num_vertices": int(np.shape(model.z_star)[0]),
    }
    with Checkpoints(folder, keep=1) as ckpt:
        ckpt.save(model.num_levels, model_state(model), meta=meta)
    return folder


def load(path: str | os.PathLike) -> Model:
    """Read a :class:`Model` from a folder written by :func:`save`.

    Args:
      path: the folder.

    Returns:
      The :class:`Model`.

    Raises:
      MeshIOError: the folder holds no DGTS model, or its files are damaged.

    Example:
      >>> import tempfile
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(2))
      >>> ds = tuple(init_level(c, i, generator=False, key=jax.random.key(i)) for i in range(2))
      >>> folder = save(Model(c, gs, ds, np.zeros((12, 3), np.float32)), tempfile.mkdtemp())
      >>> model = load(folder)
      >>> model.num_levels, model.config == c
      (2, True)
    """
    folder = pathlib.Path(path)
    with Checkpoints(folder, keep=1) as ckpt:
        if ckpt.latest_step() is None:
            raise MeshIOError(
                f"{folder} holds no DGTS model: write one with jmeshtex.dgts.save "
                "(or `jmeshtex dgts train`)"
            )
        meta = ckpt.read_meta()
        if meta.get("kind") != MODEL_KIND:
            raise MeshIOError(
                f"{folder} holds a checkpoint of {meta.get('kind')!r}, not a DGTS model "
                "(a training checkpoint_dir is not a model: save train(...).model)"
            )
        config = Config.from_dict(meta["config"])
        state, _ = ckpt.restore(model_like(config, int(meta["levels"]), int(meta["num_vertices"])))
    return Model(
        config,
        tuple(state["generators"]),
        tuple(state["discriminators"]),
        np.asarray(state["z_star"], np.float32),
    )

"""A trained DGTS hierarchy (:class:`Model`) and its files (:func:`save`, :func:`load`).

A model folder holds one ``model.npz`` in the model format of :func:`jmeshtex.io.save_model`
(atomic: an interrupted save leaves the previous model): the parameter arrays by key path and the
config. (Training checkpoints, :func:`~jmeshtex.dgts.train`'s ``checkpoint_dir``, are
:class:`jmeshtex.io.Checkpoints` folders with the optimiser state; they are not model folders.)
"""

from __future__ import annotations

import dataclasses
import functools
import os
import pathlib
from collections.abc import Sequence
from typing import Any

import jax
import numpy as np

from .._errors import CorruptModelError, InputError
from .._model_folder import MODEL_FILE, save_model_folder
from ..io import load_model
from ..ops import FaceConvStackParams
from ._config import Config
from ._networks import init_level

#: the ``kind`` recorded in a model file
MODEL_KIND = "jmeshtex.dgts.Model"
#: the layout of the arrays in the file; 2: every config field stored (a version-1 file is
#: converted once by ``studies/convert_to_format_2.py``)
FORMAT_VERSION = 2
_WHAT = "DGTS model"


@functools.partial(
    jax.tree_util.register_dataclass,
    data_fields=["generators", "discriminators", "z_star", "z_star_finer"],
    meta_fields=["config"],
)
@dataclasses.dataclass(frozen=True, eq=False)
class Model:
    """A trained (or partly trained) DGTS hierarchy: the parameters bundled with their config.

    A pytree: the parameters and the fixed noise are its leaves, ``config`` is static.

    Attributes:
      config: the :class:`~jmeshtex.dgts.Config` it was trained with (widths, activation, noise
        amplitude, scale factor: everything :func:`~jmeshtex.dgts.transfer` needs).
      generators: one :class:`~jmeshtex.ops.FaceConvStackParams` per trained level, coarsest first.
      discriminators: the matching critics (kept to warm-start the next level).
      z_star: ``[V_0, 3]`` float32 fixed reconstruction noise of the coarsest level.
      z_star_finer: the fixed reconstruction noise of levels ``1 … config.experimental.fixed_noise_levels − 1``
        (``[V_l, 3]`` float32 each, as far as the training meshes went); empty by default.

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
    z_star_finer: tuple[np.ndarray, ...] = ()

    @property
    def num_levels(self) -> int:
        """Number of trained levels."""
        return len(self.generators)

    def reconstruction_noise(self, sizes: Sequence[int]) -> list[np.ndarray]:
        """The training reconstruction's noise on levels of ``sizes`` vertices: ``z*`` at level 0,
        :attr:`z_star_finer` up to ``config.experimental.fixed_noise_levels − 1``, zero above.

        Raises:
          InputError: ``sizes[0]`` is not ``z*``'s vertex count (not the training template), or a
            level's fixed noise is missing or of another size.

        Example:
          >>> m = Model(Config(), (), (), np.ones((12, 3), np.float32))
          >>> [float(z.sum()) for z in m.reconstruction_noise([12, 42])]
          [36.0, 0.0]
        """
        z = np.asarray(self.z_star, np.float32)
        if z.shape != (sizes[0], 3):
            raise InputError(
                f"the template has {sizes[0]} vertices but the model's z* has {z.shape[0]} rows: "
                "pass the training template (TrainingMeshes.template with faces[0])"
            )
        noise = [z]
        for level, size in enumerate(sizes[1:], start=1):
            if level >= self.config.experimental.fixed_noise_levels:
                noise.append(np.zeros((size, 3), np.float32))
                continue
            fixed = self.z_star_finer[level - 1] if level <= len(self.z_star_finer) else None
            if fixed is None or np.shape(fixed) != (size, 3):
                raise InputError(
                    f"the model reconstructs level {level} from fixed noise "
                    f"(fixed_noise_levels={self.config.experimental.fixed_noise_levels}) but holds "
                    f"{'none' if fixed is None else np.shape(fixed)} for its {size} vertices: "
                    "pass the training template, or a model saved by this jmeshtex"
                )
            noise.append(np.asarray(fixed, np.float32))
        return noise

    def replace(self, **changes: Any) -> Model:
        """A copy with some fields replaced."""
        return dataclasses.replace(self, **changes)


def model_state(model: Model) -> dict:
    """The array pytree stored for ``model``."""
    return {
        "generators": tuple(model.generators),
        "discriminators": tuple(model.discriminators),
        "z_star": np.asarray(model.z_star, np.float32),
        "z_star_finer": tuple(np.asarray(z, np.float32) for z in model.z_star_finer),
    }


def model_like(config: Config, levels: int, num_vertices: int, finer: Sequence[int] = ()) -> dict:
    """The structure, shapes and dtypes of :func:`model_state` for ``levels`` levels (for
    restoring); ``finer``: the vertex counts of ``z_star_finer``'s levels."""
    key = jax.random.key(0)
    return {
        "generators": tuple(init_level(config, i, generator=True, key=key) for i in range(levels)),
        "discriminators": tuple(
            init_level(config, i, generator=False, key=key) for i in range(levels)
        ),
        "z_star": np.zeros((num_vertices, 3), np.float32),
        "z_star_finer": tuple(np.zeros((n, 3), np.float32) for n in finer),
    }


def save(model: Model, path: str | os.PathLike) -> pathlib.Path:
    """Write ``model`` as ``model.npz`` into the folder ``path``, atomically (read with :func:`load`).

    The file is the one model format of :func:`jmeshtex.io.save_model`: the arrays of
    ``model_state(model)`` by key path, with the config.

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
    return save_model_folder(
        model,
        path,
        model_type=Model,
        kind=MODEL_KIND,
        arrays=lambda m: jax.tree.map(np.asarray, model_state(m)),
        format_version=FORMAT_VERSION,
    )


def load(path: str | os.PathLike) -> Model:
    """Read a :class:`Model` from a folder written by :func:`save` (or its ``model.npz``).

    Args:
      path: the folder, or the ``model.npz`` file in it.

    Returns:
      The :class:`Model`.

    Raises:
      CorruptModelError: the folder holds no DGTS model (a training ``checkpoint_dir`` or a
        model folder of the earlier orbax layout included), or its file is truncated, damaged or
        another method's.

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
    path = pathlib.Path(path)
    file = path if path.is_file() else path / MODEL_FILE
    if not file.is_file():
        if path.is_dir() and any(p.is_dir() and p.name.isdigit() for p in path.iterdir()):
            raise CorruptModelError(
                f"{path} holds no {MODEL_FILE}: it is a training checkpoint folder or a model "
                "folder of the earlier orbax layout, not a DGTS model this jmeshtex reads. Fix: "
                "save train(...).model with jmeshtex.dgts.save (or retrain with `jmeshtex dgts "
                "train`)"
            )
        raise CorruptModelError(
            f"{path} holds no DGTS model (no {MODEL_FILE}): write one with jmeshtex.dgts.save "
            "(or `jmeshtex dgts train`)"
        )
    stored = load_model(file, kind=MODEL_KIND, format_versions=(FORMAT_VERSION,), what=_WHAT)
    config = stored.config_as(Config)
    levels = {n.split("/")[1] for n in stored.arrays if n.startswith("generators/")}
    z_star = stored.arrays.get("z_star")
    if z_star is None or z_star.ndim != 2 or not levels:
        raise CorruptModelError(
            f"{file}: no generators or no z_star [V, 3] array: not a DGTS model"
        )
    finer = [
        int(stored.arrays[f"z_star_finer/{i}"].shape[0])
        for i in range(sum(n.startswith("z_star_finer/") for n in stored.arrays))
    ]
    like = jax.eval_shape(lambda: model_like(config, len(levels), int(z_star.shape[0]), finer))
    state = stored.restore(like)
    return Model(
        config,
        tuple(state["generators"]),
        tuple(state["discriminators"]),
        np.asarray(state["z_star"], np.float32),
        tuple(np.asarray(z, np.float32) for z in state["z_star_finer"]),
    )

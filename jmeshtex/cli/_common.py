"""What every ``jmeshtex`` subcommand shares: the same flags for the same meaning, one mesh-spec syntax.

- :func:`add_common`: ``--out`` (output folder), ``--seed`` (the PRNG seed the library's ``key=``
  is made from), ``--quiet`` (no progress bar).
- :func:`load_mesh_spec`: a mesh argument is a file (``.obj``/``.ply``/``.off``/``.glb``, with its
  UVs, texture and colours) or a procedural name from :mod:`jmeshtex.data`: ``icosahedron``,
  ``icosphere:N``, ``torus``, ``torus:NMAJOR:NMINOR``, ``grid:N``, ``bumpy-sphere[:N]``,
  ``striped-sphere[:N]``.
- :func:`compilation_cache`: JAX's persistent compilation cache, so a second run with the same
  sizes skips most compilation: ``$JMESHTEX_JAX_CACHE`` (a folder; ``0`` or empty turns it off), by
  default ``$XDG_CACHE_HOME/jmeshtex/jax`` (``~/.cache/jmeshtex/jax``).
"""

from __future__ import annotations

import argparse
import os
import pathlib
from collections.abc import Callable

from .._errors import InputError

#: the procedural names a mesh argument may take, and their default numbers
PROCEDURAL = {
    "icosahedron": (),
    "icosphere": (1,),
    "torus": (24, 12),
    "grid": (8,),
    "bumpy-sphere": (4,),
    "striped-sphere": (3,),
}


def add_common(
    p: argparse.ArgumentParser,
    *,
    out: str | None = "output folder",
    seed: bool = True,
    quiet: bool = True,
    out_required: bool = True,
) -> None:
    """Add the shared flags to a subcommand's parser.

    Args:
      p: the subcommand's parser.
      out: help text of ``--out`` (a folder unless the text says otherwise); None: no ``--out``.
      seed: add ``--seed`` (default 0).
      quiet: add ``--quiet``.
      out_required: whether ``--out`` must be given.

    Example:
      >>> p = argparse.ArgumentParser()
      >>> add_common(p)
      >>> a = p.parse_args(["--out", "x", "--quiet"])
      >>> a.out.name, a.seed, a.quiet
      ('x', 0, True)
    """
    if out is not None:
        p.add_argument("--out", type=pathlib.Path, required=out_required, metavar="PATH", help=out)
        p.add_argument(
            "--overwrite",
            action="store_true",
            help="write into an --out folder that holds another command's output or foreign files "
            "(inputs are never overwritten)",
        )
    if seed:
        p.add_argument("--seed", type=int, default=0, help="PRNG seed (default 0)")
    if quiet:
        p.add_argument("--quiet", action="store_true", help="no progress bar")


#: the values ``--up`` takes (the same as ``jmeshtex.render.UP_AXES``)
UP_CHOICES = ("x", "y", "z", "-x", "-y", "-z")


def add_up(p: argparse.ArgumentParser, *, default: str = "z") -> None:
    """Add ``--up``: the mesh's up axis for renders (pass it on as ``up=`` to :mod:`jmeshtex.render`).

    Most OBJ files are Y-up (``--up y``); jmeshtex's procedural meshes are Z-up (the default).

    Example:
      >>> p = argparse.ArgumentParser()
      >>> add_up(p)
      >>> p.parse_args(["--up", "y"]).up, p.parse_args([]).up
      ('y', 'z')
    """
    p.add_argument(
        "--up",
        default=default,
        choices=UP_CHOICES,
        metavar="AXIS",
        help=f"up axis of the mesh in renders: {'|'.join(UP_CHOICES)} (default {default}; "
        "most OBJ files are y)",
    )


def procedural_mesh(spec: str):
    """The :mod:`jmeshtex.data` mesh a procedural spec names, or None if ``spec`` names none.

    Example:
      >>> procedural_mesh("icosphere:2").num_vertices, procedural_mesh("teapot.obj") is None
      (162, True)
    """
    from .. import data

    name, *nums = spec.split(":")
    if name not in PROCEDURAL:
        return None
    try:
        numbers = [int(x) for x in nums] or list(PROCEDURAL[name])
    except ValueError as err:
        raise InputError(f"bad procedural mesh {spec!r}: whole numbers expected after ':'") from err
    builders: dict[str, Callable] = {
        "icosahedron": lambda: data.icosahedron(),
        "icosphere": lambda: data.icosphere(*numbers),
        "torus": lambda: data.torus(*numbers),
        "grid": lambda: data.grid(*numbers),
        "bumpy-sphere": lambda: data.bumpy_sphere(subdivisions=numbers[0]),
        "striped-sphere": lambda: data.striped_sphere(subdivisions=numbers[0]),
    }
    try:
        return builders[name]()
    except TypeError as err:
        raise InputError(f"bad procedural mesh {spec!r}: too many numbers after the name") from err


def load_mesh_spec(spec: str | os.PathLike, *, texture: str | os.PathLike | None = None):
    """A :class:`~jmeshtex.Mesh` from a file or a procedural name (module docstring).

    A file wins over a procedural name of the same spelling. Files load with
    :func:`jmeshtex.io.load_mesh` (UVs, texture, colours kept; polygons split with a warning).

    Raises:
      InputError: ``spec`` is neither an existing file nor a procedural name.
    """
    from ..io import load_mesh

    path = pathlib.Path(spec)
    if path.exists():
        return load_mesh(path, texture=texture)
    mesh = procedural_mesh(str(spec))
    if mesh is None:
        raise InputError(
            f"{str(spec)!r} is neither a mesh file nor one of the procedural names "
            f"{sorted(PROCEDURAL)} (e.g. icosphere:3)"
        )
    return mesh


def compilation_cache() -> pathlib.Path | None:
    """Turn on JAX's persistent compilation cache in the folder the module docstring names.

    Returns:
      The folder, or None when ``JMESHTEX_JAX_CACHE`` is ``0`` or empty.
    """
    import jax

    env = os.environ.get("JMESHTEX_JAX_CACHE")
    if env is not None and env.strip() in ("", "0"):
        return None
    if env is None:
        base = os.environ.get("XDG_CACHE_HOME") or pathlib.Path.home() / ".cache"
        folder = pathlib.Path(base) / "jmeshtex" / "jax"
    else:
        folder = pathlib.Path(env)
    folder.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
    return folder


def cached(func):
    """A subcommand handler that enables the compilation cache first."""

    def run(args):
        compilation_cache()
        return func(args)

    return run

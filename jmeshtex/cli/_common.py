"""What every ``jmeshtex`` subcommand shares: the same flags for the same meaning, one mesh-spec syntax.

- :func:`add_common`: ``--out`` (output folder, claimed by :mod:`jmeshtex.cli._output`: inputs are
  never overwritten, another command's folder needs ``--overwrite``), ``--seed`` (the PRNG seed the
  library's ``key=`` is made from, ``0 … 2**32 - 1``), ``--quiet`` (no progress bar).
- :func:`int_in` / :func:`float_in`: argparse types that refuse out-of-range or non-finite numbers
  at parse time; :func:`load_array`: a ``.npy`` argument (``--labels``, ``--mask``) or one typed
  error.
- :func:`load_mesh_spec`: a mesh argument is a file (``.obj``/``.ply``/``.off``/``.glb``, with its
  UVs, texture and colours) or a procedural name from :mod:`jmeshtex.data`: ``icosahedron``,
  ``icosphere:N``, ``torus``, ``torus:NMAJOR:NMINOR``, ``grid:N``, ``bumpy-sphere[:N]``,
  ``striped-sphere[:N]``; numbers below a shape's minimum or beyond :data:`MAX_SPEC_VERTICES`
  vertices are refused before anything is built.
- :func:`compilation_cache`: JAX's persistent compilation cache, so a second run with the same
  sizes skips most compilation: ``$JMESHTEX_JAX_CACHE`` (a folder; ``0`` or empty turns it off), by
  default ``$XDG_CACHE_HOME/jmeshtex/jax`` (``~/.cache/jmeshtex/jax``).
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import pathlib
from collections.abc import Callable

from .._errors import InputError

#: the most vertices a procedural mesh spec may ask for (an icosphere:8 has 655K; larger specs are
#: typos or attempts to exhaust memory, refused before anything is built)
MAX_SPEC_VERTICES = 2_000_000

#: the largest texture side (texels) a command may ask for: 4096^2 RGB float32 is 200 MB, and the
#: per-texel work of the methods grows from there
MAX_TEXTURE_SIZE = 4096

#: the most distinct labels a label map may hold (each label gets an embedding row)
MAX_LABELS = 4096

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
        p.add_argument("--seed", type=int_in(0, 2**32 - 1), default=0, help="PRNG seed (default 0)")
    if quiet:
        p.add_argument("--quiet", action="store_true", help="no progress bar")


def int_in(low: int | None = None, high: int | None = None):
    """An argparse ``type=`` for an integer in ``[low, high]``: refused at parse time otherwise.

    Example:
      >>> p = argparse.ArgumentParser()
      >>> _ = p.add_argument("--n", type=int_in(1))
      >>> p.parse_args(["--n", "3"]).n
      3
    """

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if (low is not None and value < low) or (high is not None and value > high):
            bounds = f">= {low}" if high is None else f"in [{low}, {high}]"
            raise argparse.ArgumentTypeError(f"{text} is out of range: must be {bounds}")
        return value

    parse.__name__ = "integer"
    return parse


def float_in(low: float | None = None, high: float | None = None, *, open_low: bool = False):
    """An argparse ``type=`` for a finite number in ``[low, high]`` (``(low, high]`` if open_low).

    Example:
      >>> p = argparse.ArgumentParser()
      >>> _ = p.add_argument("--eta", type=float_in(0.0, 1.0))
      >>> p.parse_args(["--eta", "0.5"]).eta
      0.5
    """

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{text} is not a finite number")
        below = low is not None and (value <= low if open_low else value < low)
        if below or (high is not None and value > high):
            lo = "-inf" if low is None else f"{low:g}"
            hi = "inf" if high is None else f"{high:g}"
            raise argparse.ArgumentTypeError(
                f"{text} is out of range: must be in {'(' if open_low else '['}{lo}, {hi}]"
            )
        return value

    parse.__name__ = "number"
    return parse


def add_method(
    sub: argparse._SubParsersAction, name: str, *, help: str, description: str
) -> argparse._SubParsersAction:
    """Add a method's command ``jmeshtex NAME`` and return the parsers of its actions
    (``jmeshtex NAME ACTION``; the chosen one lands in ``args.NAME_command``); without an action
    the command prints its help and exits with status 1.

    Example:
      >>> parser = argparse.ArgumentParser()
      >>> inner = add_method(parser.add_subparsers(dest="command"), "m", help="h", description="d")
      >>> _ = inner.add_parser("run")
      >>> parser.parse_args(["m", "run"]).m_command
      'run'
      >>> parser.parse_args(["m"]).func(None)  # doctest: +ELLIPSIS
      usage: ... m [-h] ACTION ...
      ...
      1
    """
    p = sub.add_parser(name, help=help, description=description)
    p.set_defaults(func=lambda args: (p.print_help(), 1)[1])
    return p.add_subparsers(dest=f"{name}_command", metavar="ACTION")


def add_up(p: argparse.ArgumentParser, *, default: str = "z") -> None:
    """Add ``--up``: the mesh's up axis for renders (pass it on as ``up=`` to :mod:`jmeshtex.render`).

    Most OBJ files are Y-up (``--up y``); jmeshtex's procedural meshes are Z-up (the default).

    Example:
      >>> p = argparse.ArgumentParser()
      >>> add_up(p)
      >>> p.parse_args(["--up", "y"]).up, p.parse_args([]).up
      ('y', 'z')
    """
    from ..geometry import UP_AXES  # here: the other flags need no geometry

    p.add_argument(
        "--up",
        default=default,
        choices=UP_AXES,
        metavar="AXIS",
        help=f"up axis of the mesh in renders: {'|'.join(UP_AXES)} (default {default}; "
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
    if len(numbers) > len(PROCEDURAL[name]):
        if not PROCEDURAL[name]:
            raise InputError(
                f"bad procedural mesh {spec!r}: {name} takes no number (for a subdivided one use "
                f"icosphere:N)"
            )
        raise InputError(f"bad procedural mesh {spec!r}: too many numbers after the name")
    _check_spec_size(spec, name, numbers)
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
    except (TypeError, ValueError) as err:
        raise InputError(f"bad procedural mesh {spec!r}: {err}") from err


def _check_spec_size(spec: str, name: str, numbers: list[int]) -> None:
    """Refuse procedural numbers that build nothing valid or more than :data:`MAX_SPEC_VERTICES`."""
    smallest = {"torus": 3, "grid": 1}.get(name, 0)
    if any(n < smallest for n in numbers):
        raise InputError(
            f"bad procedural mesh {spec!r}: {name} needs numbers >= {smallest} after ':'"
        )
    if name == "torus":
        vertices = numbers[0] * (numbers[1] if len(numbers) > 1 else PROCEDURAL["torus"][1])
    elif name == "grid":
        vertices = (numbers[0] + 1) ** 2
    elif name == "icosahedron":
        vertices = 12
    else:  # subdivided icosahedra: 10 * 4^n + 2 vertices
        vertices = 10 * 4 ** min(numbers[0], 64) + 2
    if vertices > MAX_SPEC_VERTICES:
        raise InputError(
            f"procedural mesh {spec!r} would have ~{vertices:.3g} vertices, more than the "
            f"{MAX_SPEC_VERTICES:,} a mesh spec may ask for: use smaller numbers, or a mesh file"
        )


def load_mesh_spec(spec: str | os.PathLike, *, texture: str | os.PathLike | None = None):
    """A :class:`~jmeshtex.Mesh` from a file or a procedural name (module docstring).

    A file wins over a procedural name of the same spelling. Files load with
    :func:`jmeshtex.io.load_mesh` (UVs, texture, colours kept; polygons split with a warning).

    Raises:
      InputError: ``spec`` is neither an existing file nor a procedural name.
    """
    from ..io import load_mesh

    path = pathlib.Path(spec)
    if path.exists() or path.is_symlink():
        return load_mesh(path, texture=texture)
    mesh = procedural_mesh(str(spec))
    if mesh is None:
        raise InputError(
            f"{str(spec)!r} is neither a mesh file nor one of the procedural names "
            f"{sorted(PROCEDURAL)} (e.g. icosphere:3)"
        )
    if texture is not None:  # never ignored silently
        if mesh.uv is None:
            raise InputError(
                f"--texture {texture}: the procedural mesh {str(spec)!r} has no UVs to map an "
                "image with. Fix: give a mesh file with UVs, or leave --texture out"
            )
        from ..io import load_texture

        mesh = mesh.replace(texture=load_texture(texture))
    return mesh


def check_checkpoints(folder: str | os.PathLike) -> None:
    """Refuse, before any work, a checkpoint folder a command could not use (a link, a file, or a
    folder that was in ``--out`` before the command claimed it): the typed error of
    :class:`~jmeshtex.io.Checkpoints`, at once instead of at the first save."""
    from ..io import Checkpoints

    Checkpoints(folder)


def spec_for_record(spec: str | os.PathLike | None) -> str | None:
    """A mesh/file argument as a record should store it: an existing file as its absolute path
    (so the record works from any folder), a procedural name or None unchanged.

    Example:
      >>> spec_for_record("icosphere:2"), spec_for_record(None)
      ('icosphere:2', None)
    """
    if spec is None:
        return None
    path = pathlib.Path(spec)
    return str(path.absolute()) if path.exists() else str(spec)


def for_render(mesh):
    """``mesh`` as a render shows it: UVs without a texture image (an OBJ without its material)
    are dropped, so the shape is drawn instead of the renderer refusing a texture it lacks.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> for_render(icosphere(1)).uv is None
      True
    """
    if getattr(mesh, "uv", None) is not None and getattr(mesh, "texture", None) is None:
        return mesh.replace(uv=None)
    return mesh


def load_array(path: str | os.PathLike, what: str):
    """A NumPy array from a ``.npy`` file (no pickles), or one typed error naming the file.

    Raises:
      MeshIOError: missing, unreadable, or not a single array (an ``.npz`` archive, a pickle).

    Example:
      >>> import tempfile, numpy as np
      >>> path = pathlib.Path(tempfile.mkdtemp()) / "labels.npy"
      >>> np.save(path, np.arange(3))
      >>> load_array(path, "--labels").tolist()
      [0, 1, 2]
    """
    import numpy as np

    from .._errors import MeshIOError
    from ..io import check_input_file

    check_input_file(path, what)
    try:
        array = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise MeshIOError(f"cannot read {what} {path}: no such file") from None
    except (OSError, ValueError, EOFError) as err:
        raise MeshIOError(f"cannot read {what} {path}: {err} (a .npy array expected)") from err
    if not isinstance(array, np.ndarray):
        with contextlib.suppress(Exception):
            array.close()
        raise MeshIOError(f"cannot read {what} {path}: an .npz archive, not one .npy array")
    return array


def load_labels(path: str | os.PathLike, what: str = "--labels"):
    """A per-vertex label map: a non-empty 1-D ``.npy`` of whole numbers in ``[0, MAX_LABELS)``.

    Raises:
      MeshIOError: the file cannot be read as one array (:func:`load_array`).
      InputError: empty, not 1-D, not whole numbers (NaN, 0.5), negative, or too many labels.

    Example:
      >>> import tempfile, numpy as np
      >>> path = pathlib.Path(tempfile.mkdtemp()) / "labels.npy"
      >>> np.save(path, np.array([0, 1, 1]))
      >>> load_labels(path).tolist()
      [0, 1, 1]
    """
    import numpy as np

    array = load_array(path, what)
    if array.ndim != 1 or array.size == 0:
        raise InputError(
            f"{what} {path}: a non-empty 1-D array of one label per vertex expected, got shape "
            f"{array.shape}"
        )
    if array.dtype.kind == "b" or array.dtype.kind not in "iuf":
        raise InputError(f"{what} {path}: whole-number labels expected, got dtype {array.dtype}")
    if array.dtype.kind == "f":
        if not np.isfinite(array).all() or not np.all(array == np.round(array)):
            raise InputError(
                f"{what} {path}: labels must be whole numbers; the float array holds NaN, inf or "
                "fractions. Fix: save integer labels (np.save(path, labels.astype(np.int64)))"
            )
    low, high = float(array.min()), float(array.max())
    if low < 0 or high >= MAX_LABELS:
        raise InputError(
            f"{what} {path}: labels must lie in [0, {MAX_LABELS - 1}] (one class per number), "
            f"found {low:g} to {high:g}. Fix: renumber the classes 0, 1, 2, ..."
        )
    return array.astype(np.int64)


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
    try:
        folder.mkdir(parents=True, exist_ok=True)
        if not folder.is_dir() or not os.access(folder, os.W_OK | os.X_OK):
            raise NotADirectoryError(
                "not a writable folder" if folder.is_dir() else "exists and is not a folder"
            )
    except OSError as err:
        if env is None:  # the default place is unusable: run without the cache
            return None
        reason = err.strerror or str(err)
        raise InputError(
            f"JMESHTEX_JAX_CACHE={env}: cannot use it as the compilation cache ({reason}). Fix: "
            "point it to a writable folder, or set JMESHTEX_JAX_CACHE=0 to turn the cache off"
        ) from err
    jax.config.update("jax_compilation_cache_dir", str(folder))
    # a size limit turns on JAX's LRU eviction, which reads and writes entries under a file lock
    # (filelock): runs at the same time share the folder without reading a half-written entry
    jax.config.update("jax_compilation_cache_max_size", 4 << 30)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
    return folder


def cached(func):
    """A subcommand handler that enables the compilation cache first."""

    def run(args):
        compilation_cache()
        return func(args)

    return run

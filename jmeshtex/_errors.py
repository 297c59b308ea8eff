"""The jmeshtex exception hierarchy.

Every error a user can provoke with bad input is a subclass of :class:`JmeshtexError`, names the
problem, and where it can the offending indices and the fix. Catch ``JmeshtexError`` to handle all of
them; the subclasses also derive from the matching built-in (``ValueError``, ``OSError``) so code that
already catches those keeps working.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


class JmeshtexError(Exception):
    """Base class of every error jmeshtex raises on purpose."""


class InputError(JmeshtexError, ValueError):
    """An argument has the wrong shape, dtype, range or combination (not a mesh defect)."""


class FaceBudgetError(InputError):
    """The output of a transfer would exceed the face budget (``max_faces``) even from the last level."""


class ConfigError(JmeshtexError, ValueError):
    """A configuration value is invalid or inconsistent."""


class TrainingDivergedError(JmeshtexError, FloatingPointError):
    """Training produced a non-finite loss or parameter; ``step`` is the step where it was seen.

    Nothing non-finite is saved or returned: lower the learning rate or check the data's scale."""

    def __init__(self, message: str, *, step: int):
        super().__init__(message)
        self.step = step


class MissingExtraError(JmeshtexError, ImportError):
    """A jmeshtex package was imported without the optional dependencies of its extra."""


class MeshIOError(JmeshtexError, OSError):
    """A file cannot be read or written: a mesh or texture here, a model file or a checkpoint in
    the subclasses (:class:`CorruptModelError`, :class:`CheckpointError`), so ``except MeshIOError``
    catches every file error and the subclasses say which file failed."""


class CheckpointError(MeshIOError):
    """A checkpoint folder cannot be used: no intact step in it, a step that cannot be read or
    written, a state that does not match the run, or a path that is not a checkpoint folder."""


class CheckpointMismatchError(CheckpointError):
    """A checkpoint folder holds a different run (config or data differ) and cannot be resumed."""


class CorruptModelError(MeshIOError):
    """A saved model cannot be read: missing, truncated, not a model file, another method's model,
    or a format version this jmeshtex does not read. The message names the file and what is wrong."""


class MeshError(JmeshtexError, ValueError):
    """A mesh is invalid. ``indices`` holds the offending vertex/face/edge indices (may be empty)."""

    what: str = "invalid mesh"
    fix: str = ""

    def __init__(self, message: str | None = None, *, indices: Sequence | np.ndarray = ()):
        self.indices = np.asarray(indices)
        if message is None:
            message = self.what
        shown = _format_indices(self.indices)
        if shown:
            message = f"{message} {shown}"
        if self.fix:
            message = f"{message}. Fix: {self.fix}"
        super().__init__(message)


def _format_indices(indices: np.ndarray, limit: int = 10) -> str:
    if indices.size == 0:
        return ""
    flat = indices.reshape(len(indices), -1) if indices.ndim > 1 else indices
    items = [
        str(tuple(int(v) for v in row)) if np.ndim(row) else str(int(row)) for row in flat[:limit]
    ]
    more = f", ... ({len(flat) - limit} more)" if len(flat) > limit else ""
    return f"(count {len(flat)}: {', '.join(items)}{more})"


class EmptyMeshError(MeshError):
    what = "the mesh has no vertices or no faces"


class NonTriangleFaceError(MeshError):
    what = "faces must be triangles, shape [F, 3]"
    fix = "triangulate the mesh first (e.g. trimesh loads polygons triangulated)"


class FaceIndexError(MeshError):
    what = "face indices out of range or negative at faces"


class NonFiniteVertexError(MeshError):
    what = "vertex coordinates are NaN or infinite at vertices"
    fix = "remove or fix those vertices"


#: the start of the fix of every error that ``prepare_mesh(repair=True)`` repairs
_REPAIR = "repair first with jmeshtex.geometry.prepare_mesh(mesh, repair=True), "


class DegenerateFaceError(MeshError):
    what = "zero-area (degenerate) faces"
    fix = _REPAIR + "which drops them, or remesh"


class DuplicateFaceError(MeshError):
    what = "duplicate faces (same three vertices)"
    fix = _REPAIR + "which drops the duplicates"


class NonManifoldEdgeError(MeshError):
    what = "non-manifold edges (shared by more than two faces), as vertex pairs"
    fix = "split the mesh at those edges or remove the extra faces"


class NonManifoldVertexError(MeshError):
    what = "non-manifold (bow-tie) vertices whose faces form several fans"
    fix = _REPAIR + "which splits each such vertex into one copy per fan"


class InconsistentOrientationError(MeshError):
    what = "inconsistent face orientation: edges traversed in the same direction by two faces"
    fix = _REPAIR + "which re-orients faces consistently per component"


class MeshScaleError(MeshError):
    """A mesh's size or placement is outside what float32 geometry and the UV unwrapper handle:
    mean edge length too small or too large, or the mesh far from the origin for its size."""

    what = "the mesh's scale or placement is out of range"
    fix = (
        "centre and rescale it, e.g. mesh.replace(vertices=(v - v.mean(0)) / "
        "jmeshtex.geometry.mean_edge_length(v, f)) for v, f = mesh"
    )


class DecimationError(MeshError):
    """A mesh cannot be decimated to the requested level (too small, or collapses ran out)."""

    what = "the mesh cannot be decimated further"
    fix = "ask for fewer levels, lower min_vertices, or use a finer mesh"


class LogScaleWarning(UserWarning):
    """A neighbourhood's log maps are far from unit scale, where field-convolution filters see them.

    Raised by :func:`jmeshtex.check_log_scale` (on concrete, un-jitted neighbourhoods without a
    recorded ``log_unit``); build with ``scale="mean_edge"`` or call
    :func:`jmeshtex.scale_log_maps`.
    """


class MeshRepairWarning(UserWarning):
    """A mesh was changed on load or validation (unreferenced / duplicate vertices, repairs)."""


class OutputLockedError(MeshIOError):
    """Another jmeshtex process is writing into the same output folder (its lock file is held)."""


class CheckpointSkippedWarning(UserWarning):
    """A checkpoint step folder could not be read (empty, corrupt or foreign) and was skipped: resume
    falls back to the newest valid step. The message names the folder and what is wrong."""

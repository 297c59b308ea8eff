"""Exact discrete isometries for tests: fold a flat sheet along mesh lines, swing a hinged piece.

Both rotate whole pieces of a mesh rigidly about an axis through the vertices where the pieces
meet, so every triangle moves rigidly: every edge length, corner angle and face area -- and hence
every intrinsic quantity (log maps, transport, geodesic distances within the surface) -- is
preserved exactly, up to float rounding (~1e-16 relative). The embedding in 3D changes (normals,
chords between vertices across the fold), which is what intrinsic-invariance tests need.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import InputError
from .._types import Bool, Float, Int


def hinge(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    *,
    moving: Bool[np.ndarray, " V"],
    axis_point: Sequence[float],
    axis_direction: Sequence[float],
    angle: float,
) -> Float[np.ndarray, "V 3"]:
    """Rotate a rigid piece of a mesh about a hinge axis (an exact isometry of the surface).

    .. math:: x' = c + R_{\\hat d}(\\varphi)\\,(x - c) \\quad \\text{for moving } x

    (Rodrigues' rotation by ``angle`` about the axis through ``axis_point`` along ``axis_direction``,
    right-hand rule). The piece is attached to the rest only through vertices on the axis: every
    face must have all its vertices moving or all fixed, apart from vertices lying on the axis.

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` triangles.
      moving: ``[V]`` bool, the vertices of the rigid piece (vertices on the axis may be in it or
        not; they do not move either way).
      axis_point: a point on the hinge axis, 3 numbers.
      axis_direction: direction of the axis, 3 numbers (normalised here).
      angle: rotation angle in radians.

    Returns:
      ``[V, 3]`` new positions; edge lengths equal the old ones to rounding.

    Raises:
      InputError: shapes, a zero axis, or a face joining the piece to the rest away from the axis.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> out = hinge(v, f, moving=v[:, 0] > 0.5, axis_point=[0.5, 0, 0], axis_direction=[0, -1, 0],
      ...             angle=np.pi / 2)
      >>> out[2].round(12).tolist()  # (1, 0, 0) swings up to (1/2, 0, 1/2)
      [0.5, 0.0, 0.5]
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError(f"vertices must have shape [V, 3], got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise InputError(f"faces must have shape [F, 3], got {f.shape}")
    moving = np.asarray(moving)
    if moving.shape != (len(v),) or moving.dtype != bool:
        raise InputError(
            f"moving must be a bool array of shape [{len(v)}], got {moving.dtype} {moving.shape}"
        )
    c = np.asarray(axis_point, dtype=np.float64).reshape(-1)
    d = np.asarray(axis_direction, dtype=np.float64).reshape(-1)
    if (
        c.shape != (3,)
        or d.shape != (3,)
        or not np.all(np.isfinite(c))
        or not np.all(np.isfinite(d))
    ):
        raise InputError("axis_point and axis_direction must be 3 finite numbers each")
    norm = float(np.linalg.norm(d))
    if norm == 0.0:
        raise InputError("axis_direction must not be zero")
    d = d / norm

    scale = max(float(np.ptp(v, axis=0).max()), 1.0)
    rel = v - c
    off_axis = np.linalg.norm(rel - np.outer(rel @ d, d), axis=1) > 1e-9 * scale
    side = np.where(off_axis, np.where(moving, 1, -1), 0)[f]  # +1 moving, -1 fixed, 0 on the axis
    torn = np.nonzero(np.any(side > 0, axis=1) & np.any(side < 0, axis=1))[0]
    if torn.size:
        raise InputError(
            f"{torn.size} faces join the moving piece to the rest away from the axis (first: "
            f"{torn[:5].tolist()}); a hinge must run along mesh edges through the shared vertices"
        )
    out = v.copy()
    cos, sin = np.cos(angle), np.sin(angle)
    r = rel[moving]
    out[moving] = c + r * cos + np.cross(d, r) * sin + np.outer(r @ d, d) * (1.0 - cos)
    return out


def fold_sheet(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    *,
    lines: Sequence,
    angles: Sequence[float],
) -> Float[np.ndarray, "V 3"]:
    """Fold a flat triangulated sheet along mesh lines (an exact isometry of the surface).

    The sheet must lie in a plane ``z = const`` (e.g. :func:`jmeshtex.data.grid`). Each line splits
    the plane; the part on its positive side is rotated rigidly about the line by its angle
    (positive lifts it towards +z). Lines are given in the sheet's (x, y) coordinates as

    - ``("x", c)``: the line ``x = c``, folding the part ``x > c`` (a grid column line);
    - ``("y", c)``: the line ``y = c``, folding the part ``y > c`` (a grid row line);
    - ``((px, py), (nx, ny))``: the line through p with normal n, folding the part where
      ``n·(x - p) > 0``.

    Several lines must not cross inside the sheet: their moving parts must be nested or disjoint
    (parallel rows or columns, say). Folds are applied innermost first, so an outer fold carries the
    already folded inner part along rigidly. No triangle may straddle a line (the line must run
    along mesh edges), so every triangle moves rigidly: distances within the surface, and every
    intrinsic quantity, are preserved exactly (to rounding).

    Args:
      vertices: ``[V, 3]`` flat sheet, constant z.
      faces: ``[F, 3]`` triangles.
      lines: fold lines as above.
      angles: one angle (radians) per line.

    Returns:
      ``[V, 3]`` folded positions.

    Raises:
      InputError: sheet not flat, a line not along mesh edges, crossing lines, bad arguments.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import grid
      >>> v, f = grid(4)
      >>> out = fold_sheet(v, f, lines=[("x", 0.5)], angles=[np.pi / 2])
      >>> out[4].round(12).tolist()  # the corner (1, 0, 0) now stands above the fold line
      [0.5, 0.0, 0.5]
    """
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError(f"vertices must have shape [V, 3], got {v.shape}")
    lines = list(lines)
    angles = [float(a) for a in np.atleast_1d(np.asarray(angles, dtype=np.float64))]
    if len(lines) != len(angles):
        raise InputError(f"give one angle per line: {len(lines)} lines, {len(angles)} angles")
    scale = max(float(np.ptp(v, axis=0).max()), 1.0)
    z0 = float(v[0, 2]) if len(v) else 0.0
    if np.any(np.abs(v[:, 2] - z0) > 1e-12 * scale):
        raise InputError(
            "fold_sheet needs a flat sheet in a plane z = const (e.g. jmeshtex.data.grid)"
        )

    parsed = [_parse_line(line) for line in lines]
    sides = [(v[:, :2] - p) @ nrm for p, nrm in parsed]
    movers = [s > 1e-9 * scale for s in sides]
    f = np.asarray(faces, dtype=np.int64)
    for k, s in enumerate(sides):
        sign = np.where(np.abs(s) <= 1e-9 * scale, 0, np.sign(s))[f]
        bad = np.nonzero(np.any(sign > 0, axis=1) & np.any(sign < 0, axis=1))[0]
        if bad.size:
            raise InputError(
                f"fold line {lines[k]!r} crosses {bad.size} faces (first: {bad[:5].tolist()}); "
                "fold along mesh edges, e.g. a grid row or column"
            )
    for a in range(len(movers)):
        for b in range(a + 1, len(movers)):
            ma, mb = movers[a], movers[b]
            both = ma & mb
            if both.any() and not (np.array_equal(both, ma) or np.array_equal(both, mb)):
                raise InputError(f"fold lines {lines[a]!r} and {lines[b]!r} cross inside the sheet")

    out = v
    for k in sorted(range(len(parsed)), key=lambda k: int(movers[k].sum())):
        p, nrm = parsed[k]
        point = np.array([p[0], p[1], z0])
        direction = np.array([nrm[1], -nrm[0], 0.0])  # n × z: positive angles lift the part up
        out = hinge(
            out, f, moving=movers[k], axis_point=point, axis_direction=direction, angle=angles[k]
        )
    return out


def _parse_line(line) -> tuple[np.ndarray, np.ndarray]:
    """``(point [2], unit normal [2])`` of a fold line given as ("x", c), ("y", c) or (p, n)."""
    if isinstance(line, (tuple, list)) and len(line) == 2 and isinstance(line[0], str):
        axis, value = line
        if axis not in ("x", "y"):
            raise InputError(f"a fold line ('axis', value) needs axis 'x' or 'y', got {axis!r}")
        normal = np.array([1.0, 0.0]) if axis == "x" else np.array([0.0, 1.0])
        return normal * float(value), normal
    try:
        p, nrm = (np.asarray(x, dtype=np.float64).reshape(2) for x in line)
    except (TypeError, ValueError) as err:
        raise InputError(
            f"a fold line is ('x', c), ('y', c) or ((px, py), (nx, ny)); got {line!r}"
        ) from err
    length = float(np.linalg.norm(nrm))
    if not np.isfinite(length) or length == 0.0 or not np.all(np.isfinite(p)):
        raise InputError(f"fold line {line!r} needs a finite point and a non-zero normal")
    return p, nrm / length

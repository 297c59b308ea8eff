"""Hypothesis strategies for meshes: valid ones of every shape, and bad ones, one rule at a time.

:func:`valid_meshes` draws closed (icosphere, torus) or open (flat grid, Delaunay height field)
meshes, smoothly deformed, rigidly moved, scaled and relabelled, all of which pass
:func:`jmeshtex.geometry.validate_mesh`. :func:`bad_meshes` draws ``(vertices, faces)`` that break
exactly one validation rule; ``BAD_MESH_KINDS`` maps each kind to the typed error it must
raise.

Hypothesis draws the kind, the sizes and an integer seed; the geometry comes from a NumPy
generator seeded with it, so every example is reproducible and shrinks towards small meshes.
"""

from __future__ import annotations

import os
import pathlib

import numpy as np
from hypothesis import strategies as st

from .._errors import (
    DegenerateFaceError,
    DuplicateFaceError,
    EmptyMeshError,
    FaceIndexError,
    InconsistentOrientationError,
    InputError,
    MeshError,
    NonFiniteVertexError,
    NonManifoldEdgeError,
    NonManifoldVertexError,
    NonTriangleFaceError,
)
from .._mesh import Mesh

VALID_KINDS = ("icosphere", "torus", "grid", "delaunay")
_CLOSED_KINDS = ("icosphere", "torus")

BAD_MESH_KINDS: dict[str, type[MeshError]] = {
    "non_triangle": NonTriangleFaceError,
    "index_out_of_range": FaceIndexError,
    "negative_index": FaceIndexError,
    "non_finite": NonFiniteVertexError,
    "empty": EmptyMeshError,
    "degenerate_face": DegenerateFaceError,
    "duplicate_face": DuplicateFaceError,
    "non_manifold_edge": NonManifoldEdgeError,
    "inconsistent_orientation": InconsistentOrientationError,
    "non_manifold_vertex": NonManifoldVertexError,
}
"""Each bad-mesh kind of :func:`bad_meshes` and the error :func:`~jmeshtex.geometry.validate_mesh`
raises for it, in the order the checks run."""


def _size_options(kind: str, lo: int, hi: int) -> list[tuple]:
    """Parameter tuples of ``kind`` whose vertex count lies in ``[lo, hi]``."""
    if kind == "icosphere":
        opts = [(s,) for s in range(4) if lo <= 10 * 4**s + 2 <= hi]
    elif kind == "torus":
        opts = [(a, b) for a in range(3, 25) for b in range(3, 13) if lo <= a * b <= hi]
    elif kind == "grid":
        opts = [(a, b) for a in range(1, 20) for b in range(1, 20) if lo <= (a + 1) * (b + 1) <= hi]
    else:  # delaunay: a x b jittered interior points plus the square's 4 corners
        opts = [
            (a, b)
            for a in range(0, 16)
            for b in range(0, 16)
            if (a == 0) == (b == 0) and lo <= a * b + 4 <= hi
        ]
    return sorted(opts, key=lambda p: (np.prod(p), p))  # smallest first: hypothesis shrinks to them


def _delaunay_sheet(a: int, b: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    from scipy.spatial import Delaunay

    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    i, j = np.meshgrid(np.arange(a), np.arange(b), indexing="ij")
    jitter = 0.15 + 0.7 * rng.random((a * b, 2))  # keeps points off the square's sides
    inner = np.stack(
        [(i.ravel() + jitter[:, 0]) / max(a, 1), (j.ravel() + jitter[:, 1]) / max(b, 1)], 1
    )
    xy = np.concatenate([corners, inner])
    faces = Delaunay(xy).simplices.astype(np.int64)
    e1, e2 = xy[faces[:, 1]] - xy[faces[:, 0]], xy[faces[:, 2]] - xy[faces[:, 0]]
    clockwise = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    faces[clockwise] = faces[clockwise][:, [0, 2, 1]]
    k = rng.normal(size=(3, 2)) * 3.0
    phase = rng.uniform(0, 2 * np.pi, 3)
    height = 0.2 * np.sin(xy @ k.T + phase).sum(axis=1)
    return np.concatenate([xy, height[:, None]], axis=1), faces


def _smooth_deformation(vertices: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``x + Σ_k a_k sin(w_k·x + φ_k)`` with ``Σ |a_k||w_k| ≤ 1/2``: a diffeomorphism of R³.

    Its Jacobian is ``I + P`` with ``‖P‖ ≤ 1/2``, so it is injective, keeps orientation and shrinks
    no area by more than 4×: a valid mesh stays valid, closed ones stay outward.
    """
    extent = np.ptp(vertices, axis=0).max() or 1.0
    m = 3
    w = rng.normal(size=(m, 3))
    w *= rng.uniform(0.5, 3.0, (m, 1)) / (np.linalg.norm(w, axis=1, keepdims=True) * extent)
    a = rng.normal(size=(m, 3))
    a *= (0.5 / m) / (
        np.linalg.norm(a, axis=1, keepdims=True) * np.linalg.norm(w, axis=1, keepdims=True)
    )
    a *= rng.uniform(0.0, 1.0, (m, 1))
    phase = rng.uniform(0, 2 * np.pi, m)
    return vertices + np.sin(vertices @ w.T + phase) @ a


def _rigid_motion(vertices: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]  # proper rotation: orientation is kept
    scale = 10.0 ** rng.uniform(-1, 1)
    return scale * (vertices @ q.T + rng.uniform(-1, 1, 3))


def _relabel(vertices: np.ndarray, faces: np.ndarray, rng: np.random.Generator):
    perm = rng.permutation(len(vertices))
    inverse = np.empty_like(perm)
    inverse[perm] = np.arange(len(perm))
    faces = inverse[faces][rng.permutation(len(faces))]
    shift = rng.integers(0, 3, len(faces))
    faces = np.take_along_axis(faces, (np.arange(3)[None, :] + shift[:, None]) % 3, axis=1)
    return vertices[perm], faces


def valid_meshes(
    *,
    kinds: tuple[str, ...] = VALID_KINDS,
    closed: bool | None = None,
    min_vertices: int = 4,
    max_vertices: int = 200,
    deform: bool = True,
    relabel: bool = True,
) -> st.SearchStrategy[Mesh]:
    """Strategy of valid meshes (:func:`~jmeshtex.geometry.validate_mesh` passes on every one).

    Kinds: ``"icosphere"`` (closed, genus 0), ``"torus"`` (closed, genus 1), ``"grid"`` (flat open
    sheet, either diagonal pattern) and ``"delaunay"`` (Delaunay triangulation of jittered random
    points in the unit square, lifted to a smooth height field). Each is then smoothly deformed
    (a diffeomorphism, see ``_smooth_deformation``), rotated, scaled by 0.1–10, translated and
    its vertices, faces and face corners permuted (orientation kept).

    Args:
      kinds: which kinds to draw from.
      closed: True for closed kinds only, False for open ones only, None for both.
      min_vertices, max_vertices: vertex count range (icospheres come in 12, 42, 162, 642).
      deform: apply the smooth deformation and rigid motion.
      relabel: permute vertices, faces and corners.

    Returns:
      A strategy of :class:`~jmeshtex.Mesh` (``name`` is the kind).

    Raises:
      InputError: no kind has a size in the range.

    Example:
      >>> from hypothesis import given, settings
      >>> from jmeshtex.geometry import validate_mesh
      >>> @settings(max_examples=5, derandomize=True, database=None)
      ... @given(valid_meshes(max_vertices=50))
      ... def check(mesh):
      ...     validate_mesh(mesh.vertices, mesh.faces)
      >>> check()
    """
    unknown = set(kinds) - set(VALID_KINDS)
    if unknown:
        raise InputError(f"unknown mesh kinds {sorted(unknown)}; choose from {VALID_KINDS}")
    chosen = [k for k in kinds if closed is None or (k in _CLOSED_KINDS) == closed]
    options = {k: _size_options(k, min_vertices, max_vertices) for k in chosen}
    options = {k: v for k, v in options.items() if v}
    if not options:
        raise InputError(
            f"no mesh of kinds {kinds} (closed={closed}) has between {min_vertices} and "
            f"{max_vertices} vertices"
        )

    @st.composite
    def draw_mesh(draw) -> Mesh:
        from ..data import grid, icosphere, torus

        kind = draw(st.sampled_from(sorted(options, key=VALID_KINDS.index)))
        params = draw(st.sampled_from(options[kind]))
        rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
        if kind == "icosphere":
            v, f = icosphere(*params)
        elif kind == "torus":
            v, f = torus(*params, minor_radius=float(rng.uniform(0.2, 0.45)))
        elif kind == "grid":
            v, f = grid(
                *params,
                size=tuple(rng.uniform(0.5, 2.0, 2)),
                diagonals=str(rng.choice(["alternate", "uniform"])),
            )
        else:
            v, f = _delaunay_sheet(*params, rng)
        if deform:
            v = _rigid_motion(_smooth_deformation(v, rng), rng)
        if relabel:
            v, f = _relabel(v, f, rng)
        return Mesh(
            np.ascontiguousarray(v, dtype=np.float64),
            np.ascontiguousarray(f, dtype=np.int64),
            name=kind,
        )

    return draw_mesh()


# ----------------------------------------------------------------------------------------------
# bad meshes
# ----------------------------------------------------------------------------------------------


def _face_normal_and_size(v: np.ndarray, face: np.ndarray) -> tuple[np.ndarray, float]:
    n = np.cross(v[face[1]] - v[face[0]], v[face[2]] - v[face[0]])
    size = max(np.linalg.norm(v[face[1]] - v[face[0]]), np.linalg.norm(v[face[2]] - v[face[0]]))
    return n / np.linalg.norm(n), float(size)


def _mobius_strip(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A Möbius strip of ``n`` quads: manifold, but no consistent orientation exists."""
    theta = 2 * np.pi * np.arange(n) / n
    radial = np.stack([np.cos(theta), np.sin(theta), np.zeros(n)], 1)
    across = np.cos(theta / 2)[:, None] * radial + np.sin(theta / 2)[:, None] * np.array(
        [0.0, 0.0, 1.0]
    )
    width = rng.uniform(0.2, 0.4)
    v = np.concatenate([radial + width * across, radial - width * across])  # i: top, n + i: bottom
    i = np.arange(n)
    j = (i + 1) % n
    top_j = np.where(j == 0, n + j, j)  # crossing the seam swaps the two sides: the twist
    bot_j = np.where(j == 0, j, n + j)
    faces = np.concatenate([np.stack([i, n + i, top_j], 1), np.stack([n + i, bot_j, top_j], 1)])
    return v, faces


def bad_meshes(
    kind: str, *, max_vertices: int = 100
) -> st.SearchStrategy[tuple[np.ndarray, np.ndarray]]:
    """Strategy of ``(vertices, faces)`` that break exactly one validation rule.

    Built from :func:`valid_meshes` (so from every valid shape), changed just enough:

    - ``"non_triangle"``: faces with 1, 2, 4 or 5 columns, a flat index list, or a ragged list.
    - ``"index_out_of_range"`` / ``"negative_index"``: one or more corners set to ``≥ V`` / ``< 0``.
    - ``"non_finite"``: a coordinate set to NaN, +inf or −inf.
    - ``"empty"``: no faces (with or without vertices).
    - ``"degenerate_face"``: one corner moved exactly onto another corner of its face, or all three
      corners onto one point (topology untouched).
    - ``"duplicate_face"``: a face repeated, with its corners in any of the 6 orders.
    - ``"non_manifold_edge"``: one or two fin triangles (new apex vertices) on an existing edge, so
      it has three faces or more.
    - ``"inconsistent_orientation"``: a proper subset of faces flipped, or a Möbius strip (no
      consistent orientation exists, so repair fails too).
    - ``"non_manifold_vertex"``: a separate triangle attached at one existing vertex (a bow-tie).

    Args:
      kind: a key of ``BAD_MESH_KINDS``.
      max_vertices: size bound of the underlying valid meshes.

    Returns:
      A strategy of ``(vertices, faces)``; ``faces`` may be a list or an array of any shape.

    Example:
      >>> from hypothesis import given, settings
      >>> from jmeshtex.geometry import validate_mesh
      >>> @settings(max_examples=5, derandomize=True, database=None)
      ... @given(bad_meshes("duplicate_face", max_vertices=50))
      ... def check(mesh):
      ...     try:
      ...         validate_mesh(*mesh)
      ...     except BAD_MESH_KINDS["duplicate_face"]:
      ...         return
      ...     raise AssertionError("not rejected")
      >>> check()
    """
    if kind not in BAD_MESH_KINDS:
        raise InputError(f"unknown bad-mesh kind {kind!r}; choose from {list(BAD_MESH_KINDS)}")
    base = valid_meshes(max_vertices=max_vertices)
    breaker = _BREAKERS[kind]

    @st.composite
    def draw_bad(draw):
        mesh = draw(base)
        v, f = mesh.vertices.copy(), mesh.faces.copy()
        rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
        return breaker(draw, v, f, rng)

    return draw_bad()


# Each breaker takes hypothesis's ``draw``, a valid mesh's ``(vertices, faces)`` (copies it may
# change) and a seeded generator, and returns the mesh broken the way ``bad_meshes`` describes.


def _break_non_triangle(draw, v, f, rng):
    """Faces with 1, 2, 4 or 5 columns, a flat index list, or a ragged list."""
    V, F = len(v), len(f)
    variant = draw(st.sampled_from(["columns", "flat", "ragged"]))
    if variant == "columns":
        k = draw(st.sampled_from([1, 2, 4, 5]))
        extra = rng.integers(0, V, (F, max(k - 3, 0)))
        return v, np.concatenate([f, extra], axis=1)[:, :k]
    if variant == "flat":
        return v, f.ravel()
    rows = f.tolist()
    at = int(rng.integers(0, F))
    rows[at] = rows[at] + [int(rng.integers(0, V))]
    return v, rows


def _bad_indices(negative: bool):
    """The breaker setting one to three corners to ``>= V`` (or, ``negative``, to ``< 0``)."""

    def breaker(draw, v, f, rng):
        V, F = len(v), len(f)
        n_bad = draw(st.integers(1, min(3, F)))
        at = rng.choice(F, n_bad, replace=False)
        corner = rng.integers(0, 3, n_bad)
        if negative:
            f[at, corner] = -rng.integers(1, V + 1, n_bad)
        else:
            f[at, corner] = V + rng.integers(0, 10, n_bad)
        return v, f

    return breaker


def _break_non_finite(draw, v, f, rng):
    """A coordinate set to NaN, +inf or -inf."""
    value = draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    v[rng.integers(0, len(v)), rng.integers(0, 3)] = value
    return v, f


def _break_empty(draw, v, f, rng):
    """No faces, with or without the vertices."""
    keep_vertices = draw(st.booleans())
    return (v if keep_vertices else np.zeros((0, 3))), np.zeros((0, 3), np.int64)


def _break_degenerate_face(draw, v, f, rng):
    """One corner moved onto another of its face, or all three onto one point."""
    at = int(rng.integers(0, len(f)))
    a, b, c = f[at, rng.permutation(3)]
    if draw(st.booleans()):
        v[c] = v[a]  # two corners coincide
    else:
        v[b] = v[a]
        v[c] = v[a]  # the whole face collapses to a point
    return v, f


def _break_duplicate_face(draw, v, f, rng):
    """A face repeated, its corners in any of the 6 orders."""
    F = len(f)
    at = int(rng.integers(0, F))
    order = [list(p) for p in ((0, 1, 2), (1, 2, 0), (2, 0, 1), (0, 2, 1), (2, 1, 0), (1, 0, 2))]
    copy = f[at, draw(st.sampled_from(order))]
    return v, np.insert(f, int(rng.integers(0, F + 1)), copy, axis=0)


def _break_non_manifold_edge(draw, v, f, rng):
    """Fin triangles (new apex vertices) on an existing edge until it has three faces."""
    at = int(rng.integers(0, len(f)))
    k = int(rng.integers(0, 3))
    a, b = f[at, k], f[at, (k + 1) % 3]
    normal, size = _face_normal_and_size(v, f[at])
    shared = np.sum(np.any(f == a, axis=1) & np.any(f == b, axis=1))
    n_fins = 3 - int(shared)  # enough fins for three faces on the edge
    mid = 0.5 * (v[a] + v[b])
    apex = mid + size * np.array([1.0, -1.0][:n_fins])[:, None] * normal
    new = len(v) + np.arange(n_fins)
    fins = np.stack([np.full(n_fins, b), np.full(n_fins, a), new], 1)
    return np.concatenate([v, apex]), np.concatenate([f, fins])


def _break_orientation(draw, v, f, rng):
    """A proper subset of faces flipped, or a Möbius strip."""
    if draw(st.booleans()):
        return _mobius_strip(draw(st.integers(5, 16)), rng)
    F = len(f)
    n_flip = draw(st.integers(1, F - 1))
    at = rng.choice(F, n_flip, replace=False)
    f[at] = f[at][:, [0, 2, 1]]
    return v, f


def _break_non_manifold_vertex(draw, v, f, rng):
    """A separate triangle attached at one existing vertex (a bow-tie)."""
    V = len(v)
    a = int(f[rng.integers(0, len(f)), 0])
    normal, size = _face_normal_and_size(v, f[np.nonzero(np.any(f == a, axis=1))[0][0]])
    tangent = np.cross(normal, rng.normal(size=3))
    tangent /= np.linalg.norm(tangent)
    apexes = v[a] + size * np.stack([normal + tangent, normal - tangent])
    fin = np.array([[a, V, V + 1]])
    return np.concatenate([v, apexes]), np.concatenate([f, fin])


#: the breaker of each key of ``BAD_MESH_KINDS``
_BREAKERS = {
    "non_triangle": _break_non_triangle,
    "index_out_of_range": _bad_indices(negative=False),
    "negative_index": _bad_indices(negative=True),
    "non_finite": _break_non_finite,
    "empty": _break_empty,
    "degenerate_face": _break_degenerate_face,
    "duplicate_face": _break_duplicate_face,
    "non_manifold_edge": _break_non_manifold_edge,
    "inconsistent_orientation": _break_orientation,
    "non_manifold_vertex": _break_non_manifold_vertex,
}


BAD_MESH_FILES: tuple[str, ...] = (
    "two_coordinates.obj",
    "lying_header.ply",
    "garbage.obj",
    "empty.obj",
    "non_finite.obj",
    "no_triangles.off",
    "huge_no_uv.obj",
    "tiny_no_uv.obj",
    "far_off_centre_no_uv.obj",
)
"""The files :func:`write_bad_mesh_files` writes: crafted or numerically extreme mesh files that a
command must refuse with one typed error (the last three are valid meshes at scales that the UV
unwrapper cannot handle: 1e12, 1e-4 and a 1e8 offset)."""


def write_bad_mesh_files(folder: str | os.PathLike) -> dict[str, pathlib.Path]:
    """Write every ``BAD_MESH_FILES`` case into ``folder``; returns ``{name: path}``.

    Example:
      >>> import tempfile
      >>> paths = write_bad_mesh_files(tempfile.mkdtemp())
      >>> sorted(paths) == sorted(BAD_MESH_FILES)
      True
    """
    from ..data import icosphere

    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    v, f = icosphere(1)

    def obj(vertices: np.ndarray) -> str:
        lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices.tolist()]
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f.tolist()]
        return "\n".join(lines) + "\n"

    nan = v.copy()
    nan[3, 1] = np.nan
    head = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
    head += "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
    texts = {
        "two_coordinates.obj": "v 0 0\nv 1 0\nv 0 1\nf 1 2 3\n",
        "lying_header.ply": head + "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n",
        "empty.obj": "",
        "non_finite.obj": obj(nan),
        "no_triangles.off": "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n",
        "huge_no_uv.obj": obj(v * 1e12),
        "tiny_no_uv.obj": obj(v * 1e-4),
        "far_off_centre_no_uv.obj": obj(v + 1e8),
    }
    paths = {}
    for name in BAD_MESH_FILES:
        path = folder / name
        if name == "garbage.obj":
            path.write_bytes(np.random.default_rng(0).integers(0, 256, 4096, np.uint8).tobytes())
        else:
            path.write_text(texts[name])
        paths[name] = path
    return paths


BAD_ARGUMENTS: dict[str, tuple[str, ...]] = {
    "info torus:0:0": ("info", "torus:0:0"),
    "info icosphere:-1": ("info", "icosphere:-1"),
    "info icosphere:12 (size budget)": ("info", "icosphere:12"),
    "info grid:x": ("info", "grid:x"),
    "seed 2**70": ("dgts", "prepare", "--reference", "icosphere:1", "--seed", str(2**70)),
    "negative seed": ("meshmatch", "transfer", "--source", "torus", "--target", "torus", "--seed", "-1"),
    "fl train --stop-after -3": ("fl", "train", "--stop-after", "-3"),
    "surfacecnn --max-image-size 0": (
        "surfacecnn", "synthesize", "--mesh", "icosphere:1", "--exemplar", "x.png",
        "--max-image-size", "0",
    ),
    "fldm sample --eta nan": ("fldm", "sample", "--model", "m", "--eta", "nan"),
    "fldm sample --eta inf": ("fldm", "sample", "--model", "m", "--eta", "inf"),
    "meshmatch --fan-radius 1e9": (
        "meshmatch", "transfer", "--source", "torus", "--target", "torus", "--fan-radius", "1e9",
    ),
    "meshmatch --fan-radius nan": (
        "meshmatch", "transfer", "--source", "torus", "--target", "torus", "--fan-radius", "nan",
    ),
    "dgts prepare --levels 12": ("dgts", "prepare", "--reference", "icosphere:1", "--levels", "12"),
    "dgts prepare --levels 9 (face budget)": (
        "dgts", "prepare", "--reference", "icosphere:1", "--template", "icosphere:3",
        "--levels", "9",
    ),
    "verify --only bogus": ("verify", "--only", "bogus"),
    "procedural spec with too many numbers": ("info", "torus:24:12:1"),
    "fldm sample --n 0": ("fldm", "sample", "--model", "m", "--n", "0"),
    "fldm train --labels missing": (
        "fldm", "train", "--mesh", "striped-sphere:1", "--labels", "no-such-labels.npy",
    ),
    "meshmatch paint --mask missing": (
        "meshmatch", "paint", "--mesh", "striped-sphere:1", "--mask", "no-such-mask.npy",
    ),
}  # fmt: skip
"""Bad command-line arguments, by name: each must end in a non-zero exit with one error line and
no traceback, before any work (``--out`` is added by the caller where the command needs one)."""

"""Mesh repair on the host: :func:`prepare_mesh` and its :class:`RepairReport`.

:func:`prepare_mesh` turns user input into a :class:`~jmeshtex.Mesh` that every geometry builder
accepts. It always drops unreferenced vertices and merges exactly coincident ones (with a
:class:`~jmeshtex.MeshRepairWarning`); with ``repair=True`` it also drops degenerate and duplicate
faces, re-orients faces consistently and splits bow-tie vertices, and reports every change in a
:class:`RepairReport`. Whatever is left invalid raises the typed error of
:func:`~jmeshtex.geometry.validate_mesh`.

Coincident vertices are merged only on *exact* equality of their float64 coordinates
(``-0.0 == 0.0``): files that duplicate vertices along UV seams or per face copy the same numbers,
and any tolerance would be scale dependent and could weld distinct vertices of a fine mesh.
"""

import dataclasses
import warnings

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components as _graph_components

from .._errors import (
    EmptyMeshError,
    InconsistentOrientationError,
    InputError,
    MeshRepairWarning,
    NonManifoldEdgeError,
)
from .._mesh import Mesh
from .._mesh_arrays import (
    coerce_faces,
    coerce_vertices,
    coincident_vertex_map,
    corner_fans,
    edge_keys,
)
from ._validate import (
    AREA_TOL,
    _check_basic,
    _check_topology,
    _degenerate_faces,
    _duplicate_faces,
    _misoriented_edges,
    _nonmanifold_edges,
)

__all__ = ["RepairReport", "prepare_mesh"]


@dataclasses.dataclass(frozen=True, eq=False)
class RepairReport:
    """Everything :func:`prepare_mesh` changed, in the *input's* vertex and face indices.

    Attributes:
      unreferenced_vertices: ``[k]`` input vertices no face used (removed).
      merged_vertices: ``[k, 2]`` pairs (input vertex, input vertex it was merged into) of exactly
        coincident vertices.
      kept_apart_vertices: ``[k]`` input vertices that coincide with another one but were kept
        separate because merging would pinch the surface (information, not a change).
      dropped_degenerate_faces: ``[k]`` input faces of zero area (``repair=True``).
      dropped_duplicate_faces: ``[k]`` input faces that repeated an earlier face (``repair=True``).
      orphaned_vertices: ``[k]`` input vertices used only by dropped faces (removed).
      flipped_faces: ``[k]`` input faces whose orientation was reversed (``repair=True``).
      split_vertices: ``[k]`` input vertices split into one copy per fan (``repair=True``).
      vertex_index: ``[V_out]`` input vertex each output vertex comes from.
      face_index: ``[F_out]`` input face each output face comes from.
    """

    unreferenced_vertices: np.ndarray
    merged_vertices: np.ndarray
    kept_apart_vertices: np.ndarray
    dropped_degenerate_faces: np.ndarray
    dropped_duplicate_faces: np.ndarray
    orphaned_vertices: np.ndarray
    flipped_faces: np.ndarray
    split_vertices: np.ndarray
    vertex_index: np.ndarray
    face_index: np.ndarray

    @property
    def changed(self) -> bool:
        """True if the output differs from the input in anything but array copies."""
        return any(
            len(getattr(self, name))
            for name in (
                "unreferenced_vertices",
                "merged_vertices",
                "dropped_degenerate_faces",
                "dropped_duplicate_faces",
                "orphaned_vertices",
                "flipped_faces",
                "split_vertices",
            )
        )

    def __str__(self) -> str:
        lines = []
        items = [
            ("removed unreferenced vertices", self.unreferenced_vertices),
            ("merged coincident vertices (vertex, into)", self.merged_vertices),
            ("dropped degenerate faces", self.dropped_degenerate_faces),
            ("dropped duplicate faces", self.dropped_duplicate_faces),
            ("removed vertices left without faces", self.orphaned_vertices),
            ("flipped faces to a consistent orientation", self.flipped_faces),
            ("split bow-tie vertices, one copy per fan", self.split_vertices),
            ("kept coincident vertices apart (merging would pinch)", self.kept_apart_vertices),
        ]
        for label, arr in items:
            if len(arr):
                shown = [str(tuple(r)) if np.ndim(r) else str(int(r)) for r in arr[:8].tolist()]
                more = f", ... ({len(arr) - 8} more)" if len(arr) > 8 else ""
                lines.append(f"  {label}: {len(arr)} ({', '.join(shown)}{more})")
        head = f"RepairReport: {len(self.vertex_index)} vertices, {len(self.face_index)} faces" + (
            "" if self.changed else ", no changes"
        )
        return "\n".join([head, *lines])


def _coerce_mesh(mesh: Mesh | tuple) -> Mesh:
    if isinstance(mesh, Mesh):
        return mesh
    try:
        vertices, faces = mesh
    except (TypeError, ValueError):
        raise InputError(
            f"prepare_mesh expects a jmeshtex.Mesh or a (vertices, faces) pair, got {type(mesh).__name__}"
        ) from None
    return Mesh(vertices, faces)


def _check_attributes(mesh: Mesh, V: int, F: int) -> None:
    if mesh.uv is not None and np.shape(mesh.uv) != (F, 3, 2):
        raise InputError(
            f"Mesh.uv must have shape [F, 3, 2] = {(F, 3, 2)}, got {np.shape(mesh.uv)}"
        )
    if mesh.vertex_colors is not None:
        shape = np.shape(mesh.vertex_colors)
        if len(shape) != 2 or shape[0] != V:
            raise InputError(f"Mesh.vertex_colors must have shape [V, C] with V={V}, got {shape}")
    if (mesh.split_faces is None) != (mesh.split_to_merged is None):
        raise InputError("Mesh.split_faces and Mesh.split_to_merged must be given together")
    if mesh.split_faces is not None:
        sf = np.asarray(mesh.split_faces)
        s2m = np.asarray(mesh.split_to_merged)
        if sf.shape != (F, 3) or s2m.ndim != 1:
            raise InputError(
                f"Mesh.split_faces must be [F, 3] = {(F, 3)} and split_to_merged 1-D, got "
                f"{sf.shape} and {s2m.shape}"
            )
        if sf.size and (sf.min() < 0 or sf.max() >= len(s2m)):
            raise InputError("Mesh.split_faces index outside split_to_merged")
        if s2m.size and (s2m.min() < 0 or s2m.max() >= V):
            raise InputError("Mesh.split_to_merged maps outside the vertices")
        wrong = np.nonzero((s2m[sf] != np.asarray(mesh.faces)).any(axis=1))[0]
        if wrong.size:
            raise InputError(
                f"Mesh.split_to_merged[split_faces] must equal faces; differs at {wrong.size} faces "
                f"(first {wrong[:5].tolist()})"
            )


def _orientation_flips(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Faces to flip so every edge-connected component is consistently oriented (boolean ``[F]``).

    Propagating orientation over face adjacency (BFS) is done for all components at once on the
    orientation double cover: node ``(f, s)`` means "face f with flip s"; across an interior edge,
    faces traversing it in opposite directions link ``(f, s)–(g, s)``, in the same direction
    ``(f, s)–(g, 1-s)``. A component is orientable iff no ``(f, 0)`` and ``(f, 1)`` are connected;
    then each of its two sheets is a consistent orientation. Closed components take the sheet whose
    signed volume is positive (normals outward); open ones the sheet that flips fewer faces (ties
    keep the lowest face as it is).
    """
    F, V = len(faces), len(vertices)
    a, _, _, inverse, counts = edge_keys(faces, V)
    he = np.nonzero(counts[inverse] == 2)[0]
    he = he[np.argsort(inverse[he], kind="stable")]
    h1, h2 = he[0::2], he[1::2]
    f1, f2 = h1 // 3, h2 // 3
    same = a[h1] == a[h2]  # same direction: the faces need opposite flips
    rows = np.concatenate([f1, f1 + F])
    cols = np.concatenate([np.where(same, f2 + F, f2), np.where(same, f2, f2 + F)])
    graph = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(2 * F, 2 * F))
    _, label = _graph_components(graph, directed=False)
    up, down = label[:F], label[F:]
    if np.any(up == down):
        bad_faces = np.isin(up, up[up == down])
        edges = _misoriented_edges(faces[bad_faces], V)
        raise InconsistentOrientationError(
            "the surface is non-orientable (a Möbius-strip-like component): no consistent face "
            "orientation exists; misoriented edges",
            indices=edges,
        )
    sheet = np.minimum(up, down)
    flip = up != sheet
    _, comp = np.unique(sheet, return_inverse=True)
    comp = comp.reshape(-1)
    n_comp = comp.max() + 1
    size = np.bincount(comp, minlength=n_comp)
    n_flip = np.bincount(comp, weights=flip, minlength=n_comp)
    first_face = np.full(n_comp, F)
    np.minimum.at(first_face, comp, np.arange(F))
    invert = (2 * n_flip > size) | ((2 * n_flip == size) & flip[first_face])
    open_face = np.zeros(F, bool)
    open_face[np.nonzero(counts[inverse] == 1)[0] // 3] = True
    closed = np.bincount(comp, weights=open_face, minlength=n_comp) == 0
    if closed.any():
        oriented = np.where(flip[:, None], faces[:, [0, 2, 1]], faces)
        p = vertices - vertices[np.unique(faces)].mean(axis=0)
        p0, p1, p2 = (p[oriented[:, k]] for k in range(3))
        volume = np.bincount(
            comp, weights=np.einsum("ij,ij->i", p0, np.cross(p1, p2)), minlength=n_comp
        )
        invert = np.where(closed, volume < 0, invert)
    return flip ^ invert[comp]


def _split_bowties(
    faces: np.ndarray, num_vertices: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Give every extra fan of a vertex its own copy; returns (faces, copy_source, split)."""
    labels, fans = corner_fans(faces, num_vertices)
    split = np.nonzero(fans > 1)[0]
    if split.size == 0:
        return faces, np.zeros(0, np.int64), split
    vert = faces.ravel()
    n = labels.max() + 1
    first_corner = np.full(n, len(vert))
    np.minimum.at(first_corner, labels, np.arange(len(vert)))
    fan_vertex = np.zeros(n, np.int64)
    fan_vertex[labels] = vert
    order = np.lexsort((first_corner, fan_vertex))  # fans grouped by vertex, in corner order
    fv = fan_vertex[order]
    is_first = np.ones(n, bool)
    is_first[1:] = fv[1:] != fv[:-1]
    new_id = np.empty(n, np.int64)
    new_id[order[is_first]] = fv[is_first]
    extra = order[~is_first]
    new_id[extra] = num_vertices + np.arange(extra.size)
    return new_id[labels].reshape(faces.shape), fan_vertex[extra], split


class _Faces:
    """The faces under repair (in input vertex ids, bow-tie copies appended) and what follows
    each face: its input index, its stored-indexing corners and its per-corner ``uv``."""

    def __init__(self, cur: np.ndarray, stored: np.ndarray, uv: np.ndarray | None):
        self.cur, self.stored, self.uv = cur, stored, uv
        self.source = np.arange(len(cur))

    def keep(self, mask: np.ndarray) -> None:
        """Keep only the faces under ``mask``."""
        self.cur, self.source, self.stored = self.cur[mask], self.source[mask], self.stored[mask]
        self.uv = None if self.uv is None else self.uv[mask]

    def flip(self, flip: np.ndarray) -> None:
        """Reverse the corner order of the faces under ``flip``."""

        def swap(x):
            return np.where(flip.reshape((-1,) + (1,) * (x.ndim - 1)), x[:, [0, 2, 1]], x)

        self.cur, self.stored = swap(self.cur), swap(self.stored)
        self.uv = None if self.uv is None else swap(self.uv)


def _repair_faces(vertices: np.ndarray, faces: _Faces, area_tol: float):
    """Drop zero-area and repeated faces, orient the faces consistently and split bow-tie vertices
    (``prepare_mesh(repair=True)``), in place on ``faces``.

    Returns ``(dropped degenerate faces, dropped duplicate faces, flipped faces, split vertices,
    copy source)``, the first four in input indices; ``copy source``: the current vertex id each
    appended bow-tie copy was split from.
    """
    num_vertices = len(vertices)
    deg = _degenerate_faces(vertices, faces.cur, area_tol)
    dropped_deg = faces.source[deg]
    faces.keep(~deg)
    dup = _duplicate_faces(faces.cur)[:, 1]
    dropped_dup = faces.source[dup]
    mask = np.ones(len(faces.cur), bool)
    mask[dup] = False
    faces.keep(mask)
    if len(faces.cur) == 0:
        raise EmptyMeshError("no faces left after dropping degenerate and duplicate faces")
    edges = _nonmanifold_edges(faces.cur, num_vertices)
    if edges.size:
        raise NonManifoldEdgeError(indices=edges)
    flip = _orientation_flips(vertices, faces.cur)
    flipped = faces.source[flip]
    faces.flip(flip)
    faces.cur, copy_src, split = _split_bowties(faces.cur, num_vertices)
    return dropped_deg, dropped_dup, flipped, split, copy_src


def _stored_indexing(stored: np.ndarray, out_faces: np.ndarray, num_used: int, had_split: bool):
    """``(split_faces, split_to_merged)`` of the output: one stored vertex per (old stored vertex,
    new merged vertex) pair; ``(None, None)`` when there was none and no seam needs one."""
    pair_keys = stored.ravel() * num_used + out_faces.ravel()
    uniq, stored_faces = np.unique(pair_keys, return_inverse=True)
    stored_faces = stored_faces.reshape(out_faces.shape)
    split_to_merged = uniq % num_used
    if not had_split and len(uniq) == num_used:
        return None, None  # no seams: the plain indexing is the stored one
    return stored_faces, split_to_merged


def _warn_cleanup(report: RepairReport) -> None:
    """The :class:`~jmeshtex.MeshRepairWarning` of removed and merged vertices (none: silent),
    attributed to the caller of :func:`prepare_mesh`."""
    n_unref, n_merged = len(report.unreferenced_vertices), len(report.merged_vertices)
    if n_unref or n_merged:
        done = [f"removed {n_unref} unreferenced vertices"] if n_unref else []
        done += [f"merged {n_merged} exactly coincident vertices into others"] if n_merged else []
        warnings.warn(
            f"prepare_mesh: {' and '.join(done)}; the RepairReport lists them",
            MeshRepairWarning,
            stacklevel=3,
        )


def prepare_mesh(
    mesh: Mesh | tuple,
    *,
    repair: bool = False,
    area_tol: float = AREA_TOL,
) -> tuple[Mesh, RepairReport]:
    """Make a valid :class:`~jmeshtex.Mesh` from a Mesh or ``(vertices, faces)``; report changes.

    Always: vertices no face uses are removed and exactly coincident referenced vertices are merged
    (except where merging would pinch the surface: parts that touch at a point or along an edge
    are kept apart and listed in ``report.kept_apart_vertices``), with a
    :class:`~jmeshtex.MeshRepairWarning` saying how many.
    With ``repair=True`` also, in this order: zero-area faces and repeated faces are dropped (the
    first copy is kept), faces are re-oriented consistently per edge-connected component (closed
    components: normals outward, by signed volume; open ones: the orientation most faces already
    have), and every bow-tie vertex is split into one copy per fan. Whatever remains invalid raises
    the typed error of :func:`validate_mesh` (non-manifold edges and non-orientable surfaces cannot
    be repaired; without ``repair`` nothing beyond the vertex clean-up is).

    Per-corner ``uv`` follow their faces, ``vertex_colors`` their vertices (a merged vertex keeps
    the colour of its lowest input index), and ``split_faces`` / ``split_to_merged`` are rebuilt so
    that ``split_to_merged[split_faces] == faces`` still holds and the stored indexing is kept where
    nothing changed; when raw arrays with coincident vertices are merged, the input indexing becomes
    the stored one. The input is never modified in place.

    Args:
      mesh: a :class:`~jmeshtex.Mesh`, or a pair ``(vertices [V, 3], faces [F, 3])``.
      repair: also fix degenerate/duplicate faces, orientation and bow-tie vertices.
      area_tol: zero-area threshold, as in :func:`validate_mesh`.

    Returns:
      ``(mesh, report)``: the valid mesh (float64 vertices, int64 faces) and a
      :class:`RepairReport` in the input's indices.

    Raises:
      InputError: inconsistent Mesh fields (uv, colours, split maps).
      MeshError: the subclasses of :func:`validate_mesh` for what is left invalid.

    Example:
      >>> import numpy as np
      >>> v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
      >>> f = np.array([[0, 1, 2], [1, 2, 3]])  # the second face is flipped
      >>> m, report = prepare_mesh((v, f), repair=True)
      >>> m.faces.tolist(), report.flipped_faces.tolist()
      ([[0, 1, 2], [1, 3, 2]], [1])
    """
    mesh = _coerce_mesh(mesh)
    vertices = coerce_vertices(mesh.vertices)
    faces = coerce_faces(mesh.faces)
    V0, F0 = len(vertices), len(faces)
    _check_basic(vertices, faces)
    _check_attributes(mesh, V0, F0)

    referenced = np.zeros(V0, bool)
    referenced[faces.ravel()] = True
    rep, kept_apart = coincident_vertex_map(vertices, faces)
    merged_mask = rep != np.arange(V0)
    had_split = mesh.split_faces is not None
    current = _Faces(
        rep[faces],  # in input vertex ids (copies of split vertices appended)
        np.array(mesh.split_faces if had_split else faces, dtype=np.int64),
        None if mesh.uv is None else np.array(mesh.uv, dtype=np.float64),
    )
    src = np.arange(V0)  # input vertex of each current vertex id
    empty = np.zeros(0, np.int64)
    dropped_deg = dropped_dup = flipped_faces = split = empty
    if repair:
        dropped_deg, dropped_dup, flipped_faces, split, copy_src = _repair_faces(
            vertices, current, area_tol
        )
        src = np.concatenate([src, src[copy_src]])
    cur = current.cur
    _check_topology(vertices[src], cur, area_tol)  # in input ids, so errors name the user's indices

    used = np.unique(cur)
    new_id = np.full(len(src), -1)
    new_id[used] = np.arange(len(used))
    out_faces = new_id[cur]
    vertex_index = src[used]
    colors = None if mesh.vertex_colors is None else np.array(mesh.vertex_colors)[vertex_index]
    stored_faces, split_to_merged = _stored_indexing(
        current.stored, out_faces, len(used), had_split
    )

    still_referenced = np.zeros(V0, bool)
    still_referenced[src[used]] = True
    report = RepairReport(
        unreferenced_vertices=np.nonzero(~referenced)[0],
        merged_vertices=np.stack([np.nonzero(merged_mask)[0], rep[merged_mask]], axis=1),
        kept_apart_vertices=kept_apart,
        dropped_degenerate_faces=np.sort(dropped_deg),
        dropped_duplicate_faces=np.sort(dropped_dup),
        orphaned_vertices=np.nonzero(referenced & ~merged_mask & ~still_referenced)[0],
        flipped_faces=np.sort(flipped_faces),
        split_vertices=split,
        vertex_index=vertex_index,
        face_index=current.source,
    )
    _warn_cleanup(report)
    out = mesh.replace(
        vertices=vertices[vertex_index],
        faces=out_faces,
        uv=current.uv,
        vertex_colors=colors,
        split_faces=stored_faces,
        split_to_merged=split_to_merged,
    )
    return out, report

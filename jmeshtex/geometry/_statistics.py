"""Mesh summary statistics on the host: counts, topology, size and the validation verdict."""

import dataclasses
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components as _graph_components

from .._errors import InputError, JmeshtexError, MeshError, NonFiniteVertexError
from .._mesh import Mesh
from .._mesh_arrays import check_indices, coerce_faces, coerce_vertices, edge_keys
from ._adjacency import connected_components
from ._edges import unique_edges
from ._repair import _coerce_mesh
from ._validate import AREA_TOL, validate_mesh

__all__ = ["MeshStatistics", "mesh_statistics"]


@dataclasses.dataclass(frozen=True)
class MeshStatistics:
    """Summary of a mesh and its validation verdict (see :func:`mesh_statistics`).

    Topological fields are None when the arrays are too broken to count them (bad shape, indices
    or coordinates); ``genus`` is None unless the mesh is valid.

    Attributes:
      name: ``Mesh.name``.
      vertices, faces: row counts of ``Mesh.vertices`` / ``Mesh.faces``.
      stored_vertices: vertices in the stored (seam-split) indexing, or None if not split.
      edges: distinct undirected edges.
      unreferenced_vertices: vertices no face uses.
      coincident_vertices: referenced vertices whose coordinates equal another referenced vertex's.
      components: connected components (faces joined through shared vertices).
      boundary_edges: edges with a single face.
      boundary_loops: connected chains of boundary edges.
      euler_characteristic: ``V − E + F`` over referenced vertices.
      genus: total genus ``(2·components − boundary_loops − χ) / 2`` (holes are not handles).
      closed: no boundary edge.
      mean_edge_length: mean length of the distinct edges.
      bbox_min, bbox_max: axis-aligned bounding box of the vertices.
      has_uv, has_texture, has_vertex_colors: which attributes are present.
      texture_shape: ``(H, W, C)`` of the texture, or None.
      valid: :func:`validate_mesh` passes.
      error_type, error: the exception class name and message when it does not.
    """

    name: str
    vertices: int
    faces: int
    stored_vertices: int | None
    edges: int | None
    unreferenced_vertices: int | None
    coincident_vertices: int | None
    components: int | None
    boundary_edges: int | None
    boundary_loops: int | None
    euler_characteristic: int | None
    genus: int | None
    closed: bool | None
    mean_edge_length: float | None
    bbox_min: tuple[float, float, float] | None
    bbox_max: tuple[float, float, float] | None
    has_uv: bool
    has_texture: bool
    has_vertex_colors: bool
    texture_shape: tuple[int, ...] | None
    valid: bool
    error_type: str | None
    error: str | None

    def to_dict(self) -> dict[str, Any]:
        """A JSON-serialisable dict (tuples become lists)."""
        return {
            k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()
        }

    def __str__(self) -> str:
        verdict = "valid" if self.valid else f"INVALID ({self.error_type})"
        rows = [("verdict", verdict), ("vertices", self.vertices)]
        if self.stored_vertices is not None:
            rows.append(("stored vertices", f"{self.stored_vertices} (split along UV seams)"))
        rows += [
            ("faces", self.faces),
            ("edges", self.edges),
            ("components", self.components),
            ("boundary loops", self.boundary_loops),
            ("boundary edges", self.boundary_edges),
            ("euler characteristic", self.euler_characteristic),
            ("genus", self.genus),
            ("closed", self.closed),
            ("unreferenced vertices", self.unreferenced_vertices),
            ("coincident vertices", self.coincident_vertices),
            (
                "mean edge length",
                None if self.mean_edge_length is None else f"{self.mean_edge_length:.6g}",
            ),
            ("bbox min", _fmt_vec(self.bbox_min)),
            ("bbox max", _fmt_vec(self.bbox_max)),
            ("uv", self.has_uv),
            ("texture", "x".join(map(str, self.texture_shape)) if self.texture_shape else False),
            ("vertex colours", self.has_vertex_colors),
        ]
        width = max(len(k) for k, _ in rows)
        lines = [f"{self.name}"] + [f"  {k:<{width}}  {'-' if v is None else v}" for k, v in rows]
        if self.error:
            lines.append(f"  {'error':<{width}}  {self.error}")
        return "\n".join(lines)


def _fmt_vec(v) -> str | None:
    return None if v is None else "(" + ", ".join(f"{x:.6g}" for x in v) + ")"


def mesh_statistics(mesh: Mesh | tuple, *, area_tol: float = AREA_TOL) -> MeshStatistics:
    """Counts, topology, size and the validation verdict of a mesh, for reports and ``jmeshtex info``.

    The genus comes from the Euler characteristic: for an orientable manifold with ``c``
    components and ``b`` boundary loops, ``χ = V − E + F = 2c − 2g − b``, so
    ``g = (2c − b − χ) / 2`` summed over components; boundary loops are holes, not handles (a disc,
    a sphere and an annulus have genus 0, a torus 1, a torus with a hole cut out still 1). It is
    reported only for valid meshes, where the formula holds.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or ``(vertices, faces)``; not modified, never raises on a bad
        mesh (the verdict says what is wrong).
      area_tol: zero-area threshold for the verdict, as in :func:`validate_mesh`.

    Returns:
      :class:`MeshStatistics`.

    Example:
      >>> from jmeshtex.data import torus
      >>> s = mesh_statistics(torus(8, 6))
      >>> s.valid, s.components, s.genus, s.closed, s.euler_characteristic
      (True, 1, 1, True, 0)
    """
    mesh = _coerce_mesh(mesh)
    texture = None if mesh.texture is None else tuple(int(n) for n in np.shape(mesh.texture))
    common = dict(
        name=mesh.name,
        vertices=int(np.shape(mesh.vertices)[0]) if np.ndim(mesh.vertices) else 0,
        faces=int(np.shape(mesh.faces)[0]) if np.ndim(mesh.faces) else 0,
        stored_vertices=None if mesh.split_to_merged is None else int(len(mesh.split_to_merged)),
        has_uv=mesh.uv is not None,
        has_texture=mesh.texture is not None,
        has_vertex_colors=mesh.vertex_colors is not None,
        texture_shape=texture,
    )
    try:
        validate_mesh(mesh.vertices, mesh.faces, area_tol=area_tol)
        error = None
    except JmeshtexError as err:
        error = err
    verdict = dict(
        valid=error is None,
        error_type=None if error is None else type(error).__name__,
        error=None if error is None else str(error),
    )
    try:
        v = coerce_vertices(mesh.vertices)
        f = coerce_faces(mesh.faces)
        check_indices(f, len(v))
        if not np.isfinite(v).all():
            raise NonFiniteVertexError()
    except (InputError, MeshError):
        return MeshStatistics(**common, **dict.fromkeys(_MEASURED), **verdict)
    return MeshStatistics(**common, **_measure(v, f, valid=error is None), **verdict)


#: the fields of :class:`MeshStatistics` measured on the arrays (None when they cannot be read)
_MEASURED = (
    "edges",
    "unreferenced_vertices",
    "coincident_vertices",
    "components",
    "boundary_edges",
    "boundary_loops",
    "euler_characteristic",
    "genus",
    "closed",
    "mean_edge_length",
    "bbox_min",
    "bbox_max",
)


def _boundary_loops(a: np.ndarray, b: np.ndarray, num_vertices: int) -> int:
    """Number of boundary loops: connected components of the boundary edges ``(a, b)``."""
    if not a.size:
        return 0
    graph = sp.coo_matrix((np.ones(a.size), (a, b)), shape=(num_vertices, num_vertices))
    _, lab = _graph_components(graph, directed=False)
    return len(np.unique(lab[np.concatenate([a, b])]))


def _measure(v: np.ndarray, f: np.ndarray, *, valid: bool) -> dict[str, Any]:
    """The :data:`_MEASURED` fields of readable arrays (``v`` finite, ``f`` in range); the genus
    only when ``valid`` and the Euler characteristic gives a whole one."""
    V, F = len(v), len(f)
    referenced = np.zeros(V, bool)
    referenced[f.ravel()] = True
    edges = unique_edges(f, max(V, 1))
    edges = edges[edges[:, 0] != edges[:, 1]]  # a face with a repeated index has no edge there
    a, b, _, inverse, counts = edge_keys(f, max(V, 1))
    boundary = (a != b) & (counts[inverse] == 1)
    loops = _boundary_loops(a[boundary], b[boundary], V)
    n_comp = int(connected_components(f, V).max()) + 1 if F else 0
    chi = int(referenced.sum()) - len(edges) + F
    genus = None
    if valid and (2 * n_comp - loops - chi) % 2 == 0:
        genus = (2 * n_comp - loops - chi) // 2
    return dict(
        edges=len(edges),
        unreferenced_vertices=int((~referenced).sum()),
        coincident_vertices=_count_coincident(v, referenced),
        components=n_comp,
        boundary_edges=int(boundary.sum()),
        boundary_loops=loops,
        euler_characteristic=chi,
        genus=genus,
        closed=bool(F) and not boundary.any(),
        mean_edge_length=float(np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1).mean())
        if len(edges)
        else 0.0,
        bbox_min=tuple(float(x) for x in v.min(axis=0)) if V else None,
        bbox_max=tuple(float(x) for x in v.max(axis=0)) if V else None,
    )


def _count_coincident(vertices: np.ndarray, referenced: np.ndarray) -> int:
    """Number of referenced vertices that share their exact coordinates with another one."""
    p = vertices[referenced] + 0.0
    if len(p) == 0:
        return 0
    order = np.lexsort((p[:, 2], p[:, 1], p[:, 0]))
    ps = p[order]
    same = np.zeros(len(p), bool)
    eq = np.all(ps[1:] == ps[:-1], axis=1)
    same[1:] |= eq
    same[:-1] |= eq
    return int(same.sum())

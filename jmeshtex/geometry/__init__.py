"""Host-side geometry (NumPy + libigl/trimesh/scipy, not jitted).

Turns a triangle mesh into frozen, padded neighbourhood pytrees with static shapes that the pure
JAX operators in :mod:`jmeshtex.ops` consume. Conventions (docs/concepts.md): tangent vectors are complex
numbers in per-vertex frames; log maps and transport are intrinsic (edge lengths only).
"""

from .._errors import DecimationError as DecimationError
from .._extras import needs_geometry as _needs_geometry  # noqa: F401 (names a missing extra)
from .._neighborhoods import FaceNeighborhood as FaceNeighborhood
from .._neighborhoods import PoolingMap as PoolingMap
from .._neighborhoods import TangentFrames as TangentFrames
from .._neighborhoods import VertexNeighborhood as VertexNeighborhood
from .._neighborhoods import pad_to as pad_to
from .._neighborhoods import to_jax as to_jax
from ._adjacency import OneRings as OneRings
from ._adjacency import boundary_edges as boundary_edges
from ._adjacency import boundary_loops as boundary_loops
from ._adjacency import connected_components as connected_components
from ._adjacency import face_neighborhood as face_neighborhood
from ._adjacency import one_rings as one_rings
from ._axes import UP_AXES as UP_AXES
from ._axes import up_vector as up_vector
from ._direction_field import connection_laplacian as connection_laplacian
from ._direction_field import global_direction_field as global_direction_field
from ._direction_field import project_direction as project_direction
from ._direction_field import smoothest_direction_field as smoothest_direction_field
from ._edges import mean_edge_length as mean_edge_length
from ._edges import unique_edges as unique_edges
from ._frames import tangent_frames as tangent_frames
from ._frames import tangent_from_3d as tangent_from_3d
from ._frames import tangent_to_3d as tangent_to_3d
from ._hierarchy import MeshHierarchy as MeshHierarchy
from ._hierarchy import mesh_hierarchy as mesh_hierarchy
from ._hks import LaplacianEigenpairs as LaplacianEigenpairs
from ._hks import heat_kernel_signature as heat_kernel_signature
from ._hks import hks_times as hks_times
from ._hks import laplacian_eigenpairs as laplacian_eigenpairs
from ._intrinsic import corner_angles as corner_angles
from ._intrinsic import edge_lengths as edge_lengths
from ._intrinsic import face_areas as face_areas
from ._intrinsic import flat_faces as flat_faces
from ._intrinsic import vertex_areas as vertex_areas
from ._knn import geodesic_knn_neighborhood as geodesic_knn_neighborhood
from ._knn import knn_from_one_ring as knn_from_one_ring
from ._log_map import OneRingAngles as OneRingAngles
from ._log_map import one_ring_angles as one_ring_angles
from ._log_map import one_ring_neighborhood as one_ring_neighborhood
from ._normals import vertex_normals as vertex_normals
from ._raster import Raster as Raster
from ._raster import fill_unused_texels as fill_unused_texels
from ._raster import rasterize_uv as rasterize_uv
from ._remesh import remesh as remesh
from ._remesh import surface_correspondence as surface_correspondence
from ._repair import RepairReport as RepairReport
from ._repair import prepare_mesh as prepare_mesh
from ._sampling import SurfaceSamples as SurfaceSamples
from ._sampling import barycentric_interpolate as barycentric_interpolate
from ._sampling import sample_surface as sample_surface
from ._scale import check_mesh_scale as check_mesh_scale
from ._smoothing import taubin_smooth as taubin_smooth
from ._statistics import MeshStatistics as MeshStatistics
from ._statistics import mesh_statistics as mesh_statistics
from ._subdivision import Subdivision as Subdivision
from ._subdivision import rescale_to_mean_edge as rescale_to_mean_edge
from ._subdivision import subdivide_midpoint as subdivide_midpoint
from ._subdivision import subdivide_uv as subdivide_uv
from ._texture import bilinear_blend as bilinear_blend
from ._texture import bilinear_taps as bilinear_taps
from ._texture import sample_texture as sample_texture
from ._texture import uv_at as uv_at
from ._tracer import TraceResult as TraceResult
from ._tracer import TracerGeometry as TracerGeometry
from ._tracer import face_frame_to_world as face_frame_to_world
from ._tracer import trace_from_vertices as trace_from_vertices
from ._tracer import trace_geodesics as trace_geodesics
from ._tracer import tracer_geometry as tracer_geometry
from ._tracer import vertex_direction_to_face as vertex_direction_to_face
from ._validate import check_mesh_arrays as check_mesh_arrays
from ._validate import validate_mesh as validate_mesh

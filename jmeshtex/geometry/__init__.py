"""Host-side geometry (NumPy + libigl/trimesh/scipy, not jitted).

Turns a triangle mesh into frozen, padded neighbourhood pytrees with static shapes that the pure
JAX operators in :mod:`jmeshtex.ops` consume. Conventions (DESIGN.md): tangent vectors are complex
numbers in per-vertex frames; log maps and transport are intrinsic (edge lengths only).
"""

from ._adjacency import OneRings as OneRings
from ._adjacency import boundary_edges as boundary_edges
from ._adjacency import boundary_loops as boundary_loops
from ._adjacency import connected_components as connected_components
from ._adjacency import face_neighborhood as face_neighborhood
from ._adjacency import one_rings as one_rings
from ._types import FaceNeighborhood as FaceNeighborhood
from ._types import PoolingMap as PoolingMap
from ._types import TangentFrames as TangentFrames
from ._types import VertexNeighborhood as VertexNeighborhood
from ._types import pad_to as pad_to
from ._types import to_jax as to_jax
# -- public names added by each module below this line (one `from ._x import y as y` per name) --
from ._subdivision import Subdivision as Subdivision
from ._subdivision import mean_edge_length as mean_edge_length
from ._subdivision import rescale_to_mean_edge as rescale_to_mean_edge
from ._subdivision import subdivide_midpoint as subdivide_midpoint
from ._subdivision import subdivide_uv as subdivide_uv
from ._hks import LaplacianEigenpairs as LaplacianEigenpairs
from ._hks import heat_kernel_signature as heat_kernel_signature
from ._hks import hks_times as hks_times
from ._hks import laplacian_eigenpairs as laplacian_eigenpairs

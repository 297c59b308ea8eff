"""Mesh and texture files: load/save OBJ/PLY/OFF/GLB with UVs, textures and vertex colours."""

from .._mesh import Mesh as Mesh
# -- public names added by each module below this line --

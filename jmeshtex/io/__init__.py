"""Mesh and texture files: load/save OBJ/PLY/OFF/GLB with UVs, textures and vertex colours."""

from .._mesh import Mesh as Mesh
from ._atomic import atomic_save_npz as atomic_save_npz
from ._atomic import atomic_write as atomic_write
from ._atomic import load_npz as load_npz
from ._checkpoint import Checkpoints as Checkpoints
from ._load import load_mesh as load_mesh
from ._load import load_texture as load_texture
from ._save import save_mesh as save_mesh
from ._save import save_png as save_png

"""Files: load/save OBJ/PLY/OFF/GLB with UVs, textures and vertex colours; the one model file format of
every method (:func:`save_model` / :func:`load_model`); atomic writes; resumable checkpoints."""

from .._mesh import Mesh as Mesh
from ._atomic import atomic_save_npz as atomic_save_npz
from ._atomic import atomic_write as atomic_write
from ._atomic import load_npz as load_npz
from ._atomic import note_read as note_read
from ._atomic import protect as protect
from ._atomic import protect_reads as protect_reads
from ._atomic import unprotect_all as unprotect_all
from ._checkpoint import Checkpoints as Checkpoints
from ._load import load_mesh as load_mesh
from ._load import load_texture as load_texture
from ._load import referenced_files as referenced_files
from ._model_file import ModelFile as ModelFile
from ._model_file import load_model as load_model
from ._model_file import read_arrays as read_arrays
from ._model_file import save_model as save_model
from ._read import MAX_INPUT_BYTES as MAX_INPUT_BYTES
from ._read import MEMORY_BUDGET_BYTES as MEMORY_BUDGET_BYTES
from ._read import check_input_file as check_input_file
from ._read import check_memory as check_memory
from ._save import save_mesh as save_mesh
from ._save import save_png as save_png

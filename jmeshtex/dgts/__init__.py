"""DGTS: learn a geometric texture from one mesh and transfer it to any mesh (Hertz et al. 2020).

Pipeline: :func:`training_meshes` (multi-scale fitting of a template to the reference, §3.3) →
:func:`train` (hierarchical WGAN-GP, §3.4, resumable checkpoints) → :func:`transfer` /
:func:`interpolate` (any target mesh, open or closed, any genus, no re-meshing).
"""

from ._config import PrepareConfig as PrepareConfig
from ._config import TrainConfig as TrainConfig
from ._model import Discriminator as Discriminator
from ._model import Generator as Generator
from ._model import LevelGeometry as LevelGeometry
from ._model import discriminator as discriminator
from ._model import generate as generate
from ._model import generator_level as generator_level
from ._model import hierarchy_geometry as hierarchy_geometry
from ._model import init_level as init_level
from ._model import upsample as upsample
from ._multiscale import TrainingMeshes as TrainingMeshes
from ._multiscale import fit_level as fit_level
from ._multiscale import load_training_meshes as load_training_meshes
from ._multiscale import sample_points as sample_points
from ._multiscale import save_training_meshes as save_training_meshes
from ._multiscale import training_meshes as training_meshes
from ._train import DGTSModel as DGTSModel
from ._train import LevelReport as LevelReport
from ._train import gradient_penalty as gradient_penalty
from ._train import load_model as load_model
from ._train import train as train
from ._transfer import TransferResult as TransferResult
from ._transfer import interpolate as interpolate
from ._transfer import normal_heights as normal_heights
from ._transfer import transfer as transfer
from ._transfer import vertex_normals as vertex_normals

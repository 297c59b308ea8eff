"""jmeshtex: learning and transferring textures on triangle meshes with pure, jit-compiled JAX.

Layers (see the README): ``jmeshtex.io`` (files, checkpoints) → the padded-neighbourhood contract
(:class:`~jmeshtex.FaceNeighborhood`, :class:`~jmeshtex.VertexNeighborhood`, ... exported here) → ``jmeshtex.geometry``
(host-side NumPy geometry) → ``jmeshtex.ops`` (pure JAX operators) → ``jmeshtex.nn`` (thin flax
modules) → methods (``dgts``, ``fl``, ``fldm``, ``surfacecnn``, ``meshmatch``) → ``jmeshtex.cli``.
``jmeshtex.data`` holds procedural meshes, ``jmeshtex.testing`` the equivariance harness. The root
holds what every layer shares: :class:`Mesh` and :func:`as_mesh`, the typed errors, and
:class:`TrainResult`.
"""

from ._errors import CheckpointError as CheckpointError
from ._errors import CheckpointMismatchError as CheckpointMismatchError
from ._errors import CheckpointSkippedWarning as CheckpointSkippedWarning
from ._errors import ConfigError as ConfigError
from ._errors import CorruptModelError as CorruptModelError
from ._errors import DecimationError as DecimationError
from ._errors import DegenerateFaceError as DegenerateFaceError
from ._errors import DuplicateFaceError as DuplicateFaceError
from ._errors import EmptyMeshError as EmptyMeshError
from ._errors import FaceBudgetError as FaceBudgetError
from ._errors import FaceIndexError as FaceIndexError
from ._errors import InconsistentOrientationError as InconsistentOrientationError
from ._errors import InputError as InputError
from ._errors import JmeshtexError as JmeshtexError
from ._errors import LogScaleWarning as LogScaleWarning
from ._errors import MeshError as MeshError
from ._errors import MeshIOError as MeshIOError
from ._errors import MeshRepairWarning as MeshRepairWarning
from ._errors import MeshScaleError as MeshScaleError
from ._errors import MissingExtraError as MissingExtraError
from ._errors import NonFiniteVertexError as NonFiniteVertexError
from ._errors import NonManifoldEdgeError as NonManifoldEdgeError
from ._errors import NonManifoldVertexError as NonManifoldVertexError
from ._errors import NonTriangleFaceError as NonTriangleFaceError
from ._errors import OutputLockedError as OutputLockedError
from ._errors import TrainingDivergedError as TrainingDivergedError
from ._mesh import Mesh as Mesh
from ._mesh import as_mesh as as_mesh
from ._neighborhoods import FaceNeighborhood as FaceNeighborhood
from ._neighborhoods import PoolGroups as PoolGroups
from ._neighborhoods import PoolingMap as PoolingMap
from ._neighborhoods import TangentFrames as TangentFrames
from ._neighborhoods import TexelNeighborhood as TexelNeighborhood
from ._neighborhoods import VertexNeighborhood as VertexNeighborhood
from ._neighborhoods import check_log_scale as check_log_scale
from ._neighborhoods import pad_to as pad_to
from ._neighborhoods import scale_log_maps as scale_log_maps
from ._neighborhoods import to_jax as to_jax
from ._train_result import TrainResult as TrainResult

__version__ = "0.1.0"

"""Testing helpers: procedural meshes, hypothesis strategies and the equivariance harness."""

# -- public names added by each module below this line --
from ._equivariance import Convergence as Convergence
from ._equivariance import assert_equivariant as assert_equivariant
from ._equivariance import convergence as convergence
from ._equivariance import equivariance_error as equivariance_error
from ._equivariance import relative_error as relative_error
from ._fields import KINDS as KINDS
from ._fields import Field as Field
from ._registry import REGISTRY as REGISTRY
from ._registry import CheckResult as CheckResult
from ._registry import Entry as Entry
from ._registry import check as check
from ._registry import format_table as format_table
from ._registry import random_inputs as random_inputs
from ._registry import register as register
from ._registry import run_registry as run_registry
from ._state import MeshState as MeshState
from ._state import regauge_neighborhood as regauge_neighborhood
from ._transforms import CATALOGUE as CATALOGUE
from ._transforms import Realisation as Realisation
from ._transforms import Transform as Transform
from ._transforms import random_rotation as random_rotation
from ._field_strategies import features as features
from ._field_strategies import gauges as gauges
from ._field_strategies import rotations as rotations
from ._transforms import gauge_change as gauge_change
from ._transforms import rigid_motion as rigid_motion
from ._strategies import BAD_MESH_KINDS as BAD_MESH_KINDS
from ._strategies import bad_meshes as bad_meshes
from ._strategies import valid_meshes as valid_meshes
from ._isometries import fold_sheet as fold_sheet
from ._isometries import hinge as hinge
from ._registry import load_entries as load_entries

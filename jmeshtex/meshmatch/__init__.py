"""MeshMatch: non-parametric texture transfer between meshes with PatchMatch (Chen et al. 2012).

Geodesic fans (``R`` radii × ``A`` angles through the exponential map) and shape features (HKS,
``n · up``, optional correspondence affinities) describe every vertex; a coarse-to-fine, jit-compiled
PatchMatch finds for each target vertex the most similar source patch at the best of ``A``
rotations, and a Gaussian-weighted vote synthesises the target's colours.
"""

from ._config import MeshMatchConfig as MeshMatchConfig
from ._fans import GeodesicFans as GeodesicFans
from ._fans import correspondence_affinities as correspondence_affinities
from ._fans import fan_descriptor as fan_descriptor
from ._fans import filtered_fans as filtered_fans
from ._fans import geodesic_fans as geodesic_fans
from ._fans import hks_features as hks_features
from ._fans import sample_fans as sample_fans
from ._fans import shape_features as shape_features
from ._patchmatch import MeshMatchResult as MeshMatchResult
from ._patchmatch import fan_distance_bound as fan_distance_bound
from ._patchmatch import fan_spectrum as fan_spectrum
from ._patchmatch import meshmatch as meshmatch
from ._patchmatch import pad_level_arrays as pad_level_arrays
from ._patchmatch import prepare_side as prepare_side
from ._patchmatch import rotation_distances as rotation_distances
from ._transfer import TransferResult as TransferResult
from ._transfer import bake_texture as bake_texture
from ._transfer import detail_displacement as detail_displacement
from ._transfer import paint_by_example as paint_by_example
from ._transfer import transfer_displacement as transfer_displacement
from ._transfer import transfer_texture as transfer_texture
from ._transfer import vertex_colors_from_texture as vertex_colors_from_texture

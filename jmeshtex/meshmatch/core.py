"""MeshMatch building blocks: the fans, features and PatchMatch arrays behind
:func:`jmeshtex.meshmatch.meshmatch`, for building your own matcher or descriptor.

The method's contract (``Config``, the task verbs and their :class:`~jmeshtex.meshmatch.Transfer`,
``save`` / ``load``) lives one level up, in :mod:`jmeshtex.meshmatch`.

- The search budget and the paper's variants of it: :class:`Experimental` (``Config.experimental``).
- Geodesic fans: :func:`geodesic_fans` / :class:`GeodesicFans`, :func:`sample_fans`,
  :func:`filtered_fans`, :func:`fan_descriptor`, :func:`prefilter_steps`; the smoothing they use:
  :func:`smoother` / :class:`Smoother`, :func:`smooth`.
- Rotation search: :func:`fan_spectrum`, :func:`rotation_distances`, :func:`fan_distance_bound`.
- Shape features: :func:`shape_features`, :func:`hks_features`,
  :func:`correspondence_affinities`.
- The hierarchy as padded arrays: :func:`prepare_side` / :class:`Side`, :func:`pad_level_arrays` /
  :class:`LevelArrays`, :func:`level_groups`, :func:`scan_order`.
- Results: :func:`nnf_colors`; displacements: :func:`base_surface`, :func:`detail_displacement`.
"""

from ._config import Experimental as Experimental
from ._displacement import base_surface as base_surface
from ._displacement import detail_displacement as detail_displacement
from ._fans import GeodesicFans as GeodesicFans
from ._fans import Smoother as Smoother
from ._fans import fan_descriptor as fan_descriptor
from ._fans import filtered_fans as filtered_fans
from ._fans import geodesic_fans as geodesic_fans
from ._fans import prefilter_steps as prefilter_steps
from ._fans import sample_fans as sample_fans
from ._fans import smooth as smooth
from ._fans import smoother as smoother
from ._features import correspondence_affinities as correspondence_affinities
from ._features import hks_features as hks_features
from ._features import shape_features as shape_features
from ._match import nnf_colors as nnf_colors
from ._prepare import LevelArrays as LevelArrays
from ._prepare import Side as Side
from ._prepare import level_groups as level_groups
from ._prepare import pad_level_arrays as pad_level_arrays
from ._prepare import prepare_side as prepare_side
from ._prepare import scan_order as scan_order
from ._spectrum import fan_distance_bound as fan_distance_bound
from ._spectrum import fan_spectrum as fan_spectrum
from ._spectrum import rotation_distances as rotation_distances

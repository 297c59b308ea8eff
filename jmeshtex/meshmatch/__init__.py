"""MeshMatch: non-parametric texture transfer between meshes with PatchMatch (Chen et al. 2012).

Geodesic fans (``R`` radii × ``A`` angles through the exponential map) and shape features (HKS,
the whole normal and per-axis standardised positions by default, which assumes source and target
in a common pose; HKS and ``n · up`` with the pose-free :meth:`Config.intrinsic`; optional
correspondence affinities) describe every vertex; a coarse-to-fine, jit-compiled
PatchMatch finds for each target vertex the most similar source patch at the best of ``A``
rotations, and a Gaussian-weighted vote synthesises the target's colours. Nothing is trained:

    >>> import jax
    >>> from jmeshtex import meshmatch
    >>> from jmeshtex.data import striped_sphere, icosphere
    >>> config = meshmatch.Config(levels=1, steps=2, coarse_steps=4, hks_eigenpairs=8)
    >>> out = meshmatch.transfer(striped_sphere(subdivisions=2), icosphere(2),
    ...                                  key=jax.random.key(0), config=config)
    >>> out.mesh.vertex_colors.shape                  # then meshmatch.save(out, folder)
    (162, 3)

Task verbs (:func:`transfer`, :func:`paint_by_example`, :func:`transfer_displacement`) take
:class:`~jmeshtex.Mesh` inputs and ``key=`` and return a :class:`MeshMatchTransfer`, written and read
with :func:`save` / :func:`load`; :func:`meshmatch` is the matcher behind them, on any per-vertex
signal.
"""

from .._extras import needs_methods as _needs_methods  # noqa: F401 (names a missing extra)
from ..geometry import taubin_smooth as taubin_smooth
from ._config import Config as Config
from ._displacement import base_surface as base_surface
from ._displacement import detail_displacement as detail_displacement
from ._displacement import transfer_displacement as transfer_displacement
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
from ._io import load as load
from ._io import save as save
from ._match import MeshMatchResult as MeshMatchResult
from ._match import meshmatch as meshmatch
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
from ._transfer import MeshMatchTransfer as MeshMatchTransfer
from ._transfer import bake_texture as bake_texture
from ._transfer import paint_by_example as paint_by_example
from ._transfer import transfer as transfer
from ._transfer import vertex_colors_from_texture as vertex_colors_from_texture

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
:class:`~jmeshtex.Mesh` inputs and ``key=`` and return a :class:`Transfer`, written and read
with :func:`save` / :func:`load`; :func:`meshmatch` is the matcher behind them, on any per-vertex
signal; its building blocks (fans, features, the padded hierarchy) are in
:mod:`jmeshtex.meshmatch.core`.
"""

from .._extras import needs_methods as _needs_methods  # noqa: F401 (names a missing extra)
from . import core as core  # the building blocks
from ._config import Config as Config
from ._displacement import transfer_displacement as transfer_displacement
from ._io import load as load
from ._io import save as save
from ._match import Match as Match
from ._match import meshmatch as meshmatch
from ._transfer import Transfer as Transfer
from ._transfer import bake_texture as bake_texture
from ._transfer import paint_by_example as paint_by_example
from ._transfer import transfer as transfer
from ._transfer import vertex_colors_from_texture as vertex_colors_from_texture

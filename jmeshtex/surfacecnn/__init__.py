"""Surface-aware texture synthesis with a pre-trained 2D CNN run on the mesh (Kovács, Hermosilla &
Raidou, CGF 2024).

Every valid texel of a UV texture gets a 3×3 neighbourhood traced on the surface with the
exponential map and a pyramid of geodesic pooling groups; a pre-trained VGG
(:func:`jmeshtex.metrics.load_vgg16`, or a VGG-19 from :func:`jmeshtex.metrics.load_vgg19`) then
runs on the texture *on the mesh* (its 3×3 convolutions as texel convolutions with the same weights,
its 2×2 pools as grouped pools), and the texel colours are optimised until the Gram matrices of its
feature maps match those of a 2D exemplar. The texel frames follow the surface, not the UV charts
(a global vector projected on the surface, or the smoothest direction field), so an oriented
exemplar keeps its orientation across chart seams (:func:`~jmeshtex.surfacecnn.core.frame_seam_turn`,
:func:`~jmeshtex.surfacecnn.core.seam_ratio`); :func:`synthesize_uv` is the UV-space 2D baseline
(on a :func:`prepare_surface`). The atlas, taps, pyramid and loss are building blocks in
:mod:`jmeshtex.surfacecnn.core`. The method has no training stage::

    config = surfacecnn.Config(size=512, steps=500)
    result = surfacecnn.synthesize(mesh, exemplar, config, key=key)
    surfacecnn.save(result, "out/")
    result = surfacecnn.load("out/")
"""

from .._extras import needs_methods as _needs_methods  # noqa: F401 (names a missing extra)
from . import core as core  # the building blocks
from ._atlas import unwrap_uv as unwrap_uv
from ._config import Config as Config
from ._result_io import load as load
from ._result_io import save as save
from ._surface import Surface as Surface
from ._surface import prepare_surface as prepare_surface
from ._synthesis import SynthesisResult as SynthesisResult
from ._synthesis import stylize as stylize
from ._synthesis import synthesize as synthesize
from ._uv_synthesis import synthesize_uv as synthesize_uv

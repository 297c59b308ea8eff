"""Surface-aware texture synthesis with a pre-trained 2D CNN run on the mesh (Kovács, Hermosilla &
Raidou, CGF 2024).

Every valid texel of a UV texture gets a 3×3 neighbourhood traced on the surface with the
exponential map and a pyramid of geodesic pooling groups; a pre-trained VGG
(:func:`jmeshtex.metrics.load_vgg16`, or a VGG-19 from :func:`jmeshtex.metrics.load_vgg19`) then
runs on the texture *on the mesh* (its 3×3 convolutions as texel convolutions with the same weights,
its 2×2 pools as grouped pools), and the texel colours are optimised until the Gram matrices of its
feature maps match those of a 2D exemplar. The texel frames follow the surface, not the UV charts
(a global vector projected on the surface, or the smoothest direction field), so an oriented
exemplar keeps its orientation across chart seams (:func:`frame_seam_turn`, :func:`seam_ratio`);
:func:`synthesize_uv` is the UV-space 2D baseline. The method has no training stage::

    config = surfacecnn.Config(size=512, steps=500)
    result = surfacecnn.synthesize(mesh, exemplar, config, key=key)
    surfacecnn.save(result, "out/")
    result = surfacecnn.load("out/")
"""

from .._extras import needs_methods as _needs_methods  # noqa: F401 (names a missing extra)
from ._atlas import TextureAtlas as TextureAtlas
from ._atlas import image_to_texels as image_to_texels
from ._atlas import surface_tangents as surface_tangents
from ._atlas import texels_to_image as texels_to_image
from ._atlas import texture_atlas as texture_atlas
from ._atlas import unwrap_uv as unwrap_uv
from ._atlas import uv_face_tangents as uv_face_tangents
from ._atlas import vertex_directions as vertex_directions
from ._config import Config as Config
from ._loss import default_content_weight as default_content_weight
from ._loss import default_layers as default_layers
from ._loss import gram_targets as gram_targets
from ._loss import style_loss as style_loss
from ._loss import style_transfer_layers as style_transfer_layers
from ._loss import vgg_features_centre_padded as vgg_features_centre_padded
from ._neighborhood import TAP_DX as TAP_DX
from ._neighborhood import TAP_DY as TAP_DY
from ._neighborhood import TexelTaps as TexelTaps
from ._neighborhood import opposite_source as opposite_source
from ._neighborhood import texel_taps as texel_taps
from ._neighborhood import trace_taps as trace_taps
from ._neighborhood import uv_to_texels as uv_to_texels
from ._network import mesh_cnn_features as mesh_cnn_features
from ._network import required_levels as required_levels
from ._pyramid import BACKOFF as BACKOFF
from ._pyramid import TexelPyramid as TexelPyramid
from ._pyramid import texel_pyramid as texel_pyramid
from ._result_io import load as load
from ._result_io import save as save
from ._seams import chart_labels as chart_labels
from ._seams import frame_seam_turn as frame_seam_turn
from ._seams import seam_edges as seam_edges
from ._seams import seam_pairs as seam_pairs
from ._seams import seam_ratio as seam_ratio
from ._surface import Surface as Surface
from ._surface import prepare_surface as prepare_surface
from ._synthesis import SynthesisResult as SynthesisResult
from ._synthesis import network_weights as network_weights
from ._synthesis import stylize as stylize
from ._synthesis import synthesize as synthesize
from ._uv_synthesis import synthesize_uv as synthesize_uv

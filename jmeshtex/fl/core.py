"""FL-VAE building blocks: the pure parts of :mod:`jmeshtex.fl`, for building your own model,
loss or training loop.

The functions here take ``(params, config, arrays)`` and are jit/grad-safe, or build those arrays
on the host; the method's contract (``Config``, ``Model``, ``train`` / ``save`` / ``load``, the
encode/decode verbs) lives one level up, in :mod:`jmeshtex.fl`.

- Study switches beyond the shipped recipe: :class:`Experimental` (``Config.experimental``).
- Parameters: :func:`~jmeshtex.fl.init` (an untrained :class:`~jmeshtex.fl.Model`), :class:`Params`,
  :class:`EncoderParams`.
- Encoder: :func:`one_ring_samples` / :class:`OneRingSamples` (colours read in each vertex's
  one-ring), :func:`encode_samples`, :func:`encode_one_rings`; colours on a surface:
  :func:`surface_colors` / :class:`SurfaceColors`.
- Decoder: :func:`decode_points`, :func:`decode_barycentric`,
  :func:`decode_vertex_colors_from_latents`, :func:`decoder_features`.
- Loss: :func:`vae_loss`, :func:`kl_divergence`, :func:`kl_per_channel`, :func:`sample_latents`.
- Training: :func:`make_train_step`, :func:`optimizer`, :func:`mesh_batch`, and the data at a
  pixel density: :func:`training_meshes`, :func:`training_texture`, :func:`procedural_texture`
  (``PROCEDURAL_KINDS``), :func:`augmented_crop`, :func:`density_mesh`, :func:`planar_mesh`,
  :func:`planar_pool`, :func:`builtin_images` (``TRAINING_IMAGES``; ``HELD_OUT_IMAGES`` are for
  evaluation only).
- Evaluation: :func:`atlas_metrics`, :func:`side_by_side`; the per-vertex codecs that bound a
  reconstruction: :func:`p1_baselines` (:func:`p1_interpolate`, :func:`p1_least_squares`),
  scored with the best flat colour by :func:`baseline_metrics`.
"""

from ._baselines import baseline_metrics as baseline_metrics
from ._baselines import p1_baselines as p1_baselines
from ._baselines import p1_interpolate as p1_interpolate
from ._baselines import p1_least_squares as p1_least_squares
from ._codec import encode_one_rings as encode_one_rings
from ._colors import SurfaceColors as SurfaceColors
from ._colors import surface_colors as surface_colors
from ._config import Experimental as Experimental
from ._decoder import decoder_features as decoder_features
from ._encoder import EncoderParams as EncoderParams
from ._encoder import OneRingSamples as OneRingSamples
from ._encoder import one_ring_samples as one_ring_samples
from ._loss import kl_divergence as kl_divergence
from ._loss import kl_per_channel as kl_per_channel
from ._loss import sample_latents as sample_latents
from ._loss import vae_loss as vae_loss
from ._model import Params as Params
from ._model import decode_barycentric as decode_barycentric
from ._model import decode_points as decode_points
from ._model import decode_vertex_colors_from_latents as decode_vertex_colors_from_latents
from ._model import encode_samples as encode_samples
from ._planar import BUILTIN_IMAGES as BUILTIN_IMAGES
from ._planar import builtin_images as builtin_images
from ._planar import planar_mesh as planar_mesh
from ._planar import planar_pool as planar_pool
from ._reconstruct import atlas_metrics as atlas_metrics
from ._reconstruct import side_by_side as side_by_side
from ._textures import HELD_OUT_IMAGES as HELD_OUT_IMAGES
from ._textures import MATPLOTLIB_IMAGES as MATPLOTLIB_IMAGES
from ._textures import PROCEDURAL_KINDS as PROCEDURAL_KINDS
from ._textures import TRAINING_IMAGES as TRAINING_IMAGES
from ._textures import augmented_crop as augmented_crop
from ._textures import density_mesh as density_mesh
from ._textures import matplotlib_images as matplotlib_images
from ._textures import procedural_texture as procedural_texture
from ._textures import training_meshes as training_meshes
from ._textures import training_texture as training_texture
from ._train import batch_loss as batch_loss
from ._train import make_train_step as make_train_step
from ._train import mesh_batch as mesh_batch
from ._train import optimizer as optimizer

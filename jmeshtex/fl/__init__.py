"""Field Latents (Mitchel, Esteves, Makadia, CVPR 2024): textures as tangent-vector latents at vertices.

The FL-VAE reads a mesh's texture (or vertex colours) in each vertex's one-ring and encodes it as
``d`` complex numbers per vertex — tangent vectors in the per-vertex frames of
:func:`jmeshtex.geometry.one_ring_neighborhood` (x-axis = the first one-ring edge) — and decodes
such latents back into colours anywhere on the surface.

- Model: :class:`Config` (presets :meth:`Config.paper`, :meth:`Config.small`), :class:`Model`
  (parameters + config), :func:`init`, :func:`train` (on planar meshes laid over images; resumable;
  :func:`plot_losses`), :func:`save` / :func:`load` (:func:`load_extra`), :func:`load_pretrained`
  (the small model shipped in ``jmeshtex/fl/weights``).
- Meshes: :func:`encode` (→ :class:`FieldLatents`), :func:`decode_vertex_colors`,
  :func:`decode_texture`, :func:`decode_points_in_faces`, :func:`reconstruct` (texture → latents →
  atlas, with PSNR/DSSIM/LPIPS).
- Training data at a pixel density: :func:`training_meshes`, :func:`training_texture`
  (:func:`procedural_texture`, :func:`augmented_crop` of :func:`training_images`; never
  ``HELD_OUT_IMAGES``), :func:`density_mesh`.
- Pure parts (jit/grad-safe, ``(params, config, arrays)``): :func:`encode_samples`,
  :func:`decode_points`, :func:`decode_barycentric`, :func:`vae_loss`, :func:`kl_divergence`.

Example:
  >>> import jax, numpy as np
  >>> from jmeshtex import Mesh, fl
  >>> from jmeshtex.data import grid
  >>> v, f = grid(4)
  >>> mesh = Mesh(v, f, uv=v[f][..., :2], texture=np.full((16, 16, 3), 0.25, np.float32))
  >>> model = fl.load_pretrained()
  >>> latents = fl.encode(model, mesh, key=jax.random.key(0))
  >>> texture, valid = fl.decode_texture(model, mesh, latents, size=16)
  >>> latents.mu.shape, texture.shape
  ((25, 8), (16, 16, 3))

Field Latent Diffusion (:mod:`jmeshtex.fldm`) builds on these.
"""

from .._extras import needs_methods as _needs_methods  # noqa: F401 (names a missing extra)
from .._train_result import TrainResult as TrainResult
from ._codec import decode_points_in_faces as decode_points_in_faces
from ._codec import decode_texture as decode_texture
from ._codec import decode_vertex_colors as decode_vertex_colors
from ._codec import encode as encode
from ._codec import encode_one_rings as encode_one_rings
from ._colors import SurfaceColors as SurfaceColors
from ._colors import surface_colors as surface_colors
from ._config import Config as Config
from ._decoder import decoder_features as decoder_features
from ._encoder import EncoderParams as EncoderParams
from ._encoder import OneRingSamples as OneRingSamples
from ._encoder import one_ring_samples as one_ring_samples
from ._io import load as load
from ._io import load_extra as load_extra
from ._io import load_pretrained as load_pretrained
from ._io import save as save
from ._loss import kl_divergence as kl_divergence
from ._loss import sample_latents as sample_latents
from ._loss import vae_loss as vae_loss
from ._loss_curve import plot_losses as plot_losses
from ._model import FieldLatents as FieldLatents
from ._model import FLVAEParams as FLVAEParams
from ._model import Model as Model
from ._model import decode_barycentric as decode_barycentric
from ._model import decode_points as decode_points
from ._model import decode_vertex_colors_from_latents as decode_vertex_colors_from_latents
from ._model import encode_samples as encode_samples
from ._model import init as init
from ._planar import builtin_images as builtin_images
from ._planar import planar_mesh as planar_mesh
from ._planar import planar_pool as planar_pool
from ._reconstruct import Reconstruction as Reconstruction
from ._reconstruct import atlas_metrics as atlas_metrics
from ._reconstruct import reconstruct as reconstruct
from ._reconstruct import side_by_side as side_by_side
from ._textures import HELD_OUT_IMAGES as HELD_OUT_IMAGES
from ._textures import PROCEDURAL_KINDS as PROCEDURAL_KINDS
from ._textures import TRAINING_IMAGES as TRAINING_IMAGES
from ._textures import augmented_crop as augmented_crop
from ._textures import density_mesh as density_mesh
from ._textures import held_out_images as held_out_images
from ._textures import procedural_texture as procedural_texture
from ._textures import training_images as training_images
from ._textures import training_meshes as training_meshes
from ._textures import training_texture as training_texture
from ._train import make_train_step as make_train_step
from ._train import mesh_batch as mesh_batch
from ._train import optimizer as optimizer
from ._train import train as train

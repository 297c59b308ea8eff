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
- Images: :func:`training_images` (the images :func:`train` reads by default in its stream mode) and
  :func:`held_out_images` (for evaluation only).
- Building blocks (:mod:`jmeshtex.fl.core`): the pure, jit/grad-safe parts taking
  ``(params, config, arrays)`` (:func:`~jmeshtex.fl.core.encode_samples`,
  :func:`~jmeshtex.fl.core.decode_points`, :func:`~jmeshtex.fl.core.vae_loss`, ...), the training
  step and the training data at a pixel density (:func:`~jmeshtex.fl.core.training_meshes`).

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
from . import core as core  # the building blocks
from ._codec import decode_points_in_faces as decode_points_in_faces
from ._codec import decode_texture as decode_texture
from ._codec import decode_vertex_colors as decode_vertex_colors
from ._codec import encode as encode
from ._config import Config as Config
from ._io import load as load
from ._io import load_extra as load_extra
from ._io import load_pretrained as load_pretrained
from ._io import save as save
from ._loss_curve import plot_losses as plot_losses
from ._model import FieldLatents as FieldLatents
from ._model import Model as Model
from ._model import init as init
from ._reconstruct import Reconstruction as Reconstruction
from ._reconstruct import reconstruct as reconstruct
from ._textures import held_out_images as held_out_images
from ._textures import training_images as training_images
from ._train import train as train

"""Field Latent Diffusion (Mitchel, Esteves, Makadia, CVPR 2024, §5–6): a diffusion model on FL-VAE latents.

The denoiser is a U-Net of field convolutions over tangent-vector features (:mod:`jmeshtex.ops`),
trained on latents of many re-triangulated copies of one textured mesh (:func:`build_dataset`); the
samplers (DDPM, DDIM) generate new latents on any mesh, which :mod:`jmeshtex.fl` decodes to colours
(:func:`decode_samples`). Inpainting, label guidance and generative transfer reuse the same denoiser.

The method's shape is that of every jmeshtex method:

- :class:`Config` (frozen, validated, ``to_dict`` / ``from_dict``; presets ``paper``, ``cpu``, ``tiny``);
- :func:`build_dataset` (a :class:`~jmeshtex.Mesh` and an ``encode`` callable in, a :class:`Dataset` out);
- :func:`train` (resumable, returns a :class:`~jmeshtex.TrainResult` holding a :class:`Model`),
  :func:`save` / :func:`load`;
- the task verbs :func:`sample` and :func:`inpaint` (a mesh and ``key=`` in, :class:`Samples`
  out), and :func:`encode` (a textured mesh as the latents a model was trained on: what inpainting
  keeps, or the reference beside the samples).

The denoiser, the diffusion maths (schedules, DDPM/DDIM steps) and the training step are building
blocks in :mod:`jmeshtex.fldm.core`.

Example:
  >>> import jax
  >>> from jmeshtex import fldm
  >>> from jmeshtex.data import icosphere
  >>> config = fldm.Config.tiny(latent_channels=1, n_copies=2, copy_vertices=40, steps=2, bucket=32)
  >>> data = fldm.build_dataset(icosphere(1), config, encode=lambda m: m.vertices[:, :1] + 0j,
  ...                           key=jax.random.key(0), progress=False)
  >>> # fldm.train(data, config, key=key).model trains one; here the weights it starts from:
  >>> model = fldm.init(data, config, key=jax.random.key(1))
  >>> samples = fldm.sample(model, icosphere(1), key=jax.random.key(2), num_samples=2, steps=3)
  >>> samples.latents.shape
  (2, 42, 1)
"""

from .._extras import needs_methods as _needs_methods  # noqa: F401 (names a missing extra)
from .._train_result import TrainResult as TrainResult
from . import core as core  # the building blocks
from ._config import Config as Config
from ._data import Dataset as Dataset
from ._data import build_dataset as build_dataset
from ._data import encode as encode
from ._data import fl_vae_encoder as fl_vae_encoder
from ._masks import random_mask as random_mask
from ._model import Model as Model
from ._model import load as load
from ._model import save as save
from ._pretrained import load_pretrained as load_pretrained
from ._sample import Samples as Samples
from ._sample import decode_samples as decode_samples
from ._sample import inpaint as inpaint
from ._sample import render_samples as render_samples
from ._sample import sample as sample
from ._train import init as init
from ._train import train as train

"""Field Latent Diffusion building blocks: the denoiser, the diffusion maths and the training step
of :mod:`jmeshtex.fldm`, for building your own sampler, loss or training loop.

Everything here is a pure function over padded arrays (jit/grad/vmap-safe) or builds those arrays
on the host; the method's contract (``Config``, ``Model``, ``train`` / ``save`` / ``load``, the
verbs ``sample`` and ``inpaint``) lives one level up, in :mod:`jmeshtex.fldm`.

- Study switches beyond the paper: :class:`Experimental` (``Config.experimental``: the schedule
  shift, rematerialisation, collapsed channels, several encodings per copy, the checkpoint
  statistics, the invariant stream, phase synchronisation).
- Denoiser: :func:`init_denoiser`, :func:`denoise`, :func:`denoiser_geometry` /
  :class:`DenoiserGeometry` (the frozen neighbourhoods of one mesh), :func:`pad_geometry`,
  :func:`geometry_sizes`, :func:`sampling_geometry`; cost models :func:`denoiser_flops`,
  :func:`denoiser_activations`; the invariant stream's :func:`magnitude_context`.
- Diffusion (DDPM / DDIM): :func:`make_schedule` / :class:`Schedule` (``SCHEDULES``),
  :func:`q_sample`, :func:`prediction_target` (``PREDICTIONS``), :func:`epsilon_from_output`,
  :func:`epsilon_loss` (``LOSS_NAMES``), :func:`ddpm_step`, :func:`ddim_step`,
  :func:`timestep_sequence`, :func:`draw_sampling_noise`, :func:`sample_from_noise`,
  :class:`Inpaint`, :func:`latent_scale`.
- Training: :func:`~jmeshtex.fldm.init`, :func:`make_train_step`, :func:`optimizer`,
  :func:`learning_rate_schedule`, :func:`training_batch`, :func:`training_masks`,
  :func:`copy_mesh`, :func:`stack_copies`, :func:`channel_weights`, :func:`model_card`,
  :func:`data_digest` (what a checkpoint folder is keyed by).
- Coherent latents (beyond the paper): :func:`synchronize_phases` (flat rings' phases agreeing
  over the k-NN connection), :func:`ring_color_spread` (which rings are flat).
- Decoder-free statistics of latent fields: :func:`latent_statistics`,
  :func:`relative_phase_concentration`, :func:`pointwise_concentration`,
  :func:`pair_mean_phasors`, :func:`neighbour_energy_correlation`,
  :func:`transported_phase_coherence`, :func:`region_statistics`,
  :func:`energy_field_correlation`; baselines :func:`shuffle_latents`,
  :func:`random_channel_phases`.
"""

from ._blocks import magnitude_context as magnitude_context
from ._config import Experimental as Experimental
from ._data import copy_mesh as copy_mesh
from ._data import stack_copies as stack_copies
from ._denoiser import DenoiserGeometry as DenoiserGeometry
from ._denoiser import denoise as denoise
from ._denoiser import denoiser_activations as denoiser_activations
from ._denoiser import denoiser_flops as denoiser_flops
from ._denoiser import denoiser_geometry as denoiser_geometry
from ._denoiser import geometry_sizes as geometry_sizes
from ._denoiser import init_denoiser as init_denoiser
from ._denoiser import pad_geometry as pad_geometry
from ._diffusion import LOSS_NAMES as LOSS_NAMES
from ._diffusion import PREDICTIONS as PREDICTIONS
from ._diffusion import SCHEDULES as SCHEDULES
from ._diffusion import Inpaint as Inpaint
from ._diffusion import Schedule as Schedule
from ._diffusion import ddim_step as ddim_step
from ._diffusion import ddpm_step as ddpm_step
from ._diffusion import draw_sampling_noise as draw_sampling_noise
from ._diffusion import epsilon_from_output as epsilon_from_output
from ._diffusion import epsilon_loss as epsilon_loss
from ._diffusion import latent_scale as latent_scale
from ._diffusion import make_schedule as make_schedule
from ._diffusion import prediction_target as prediction_target
from ._diffusion import q_sample as q_sample
from ._diffusion import sample_from_noise as sample_from_noise
from ._diffusion import timestep_sequence as timestep_sequence
from ._model import model_card as model_card
from ._phase import ring_color_spread as ring_color_spread
from ._phase import synchronize_phases as synchronize_phases
from ._sample import sampling_geometry as sampling_geometry
from ._statistics import energy_field_correlation as energy_field_correlation
from ._statistics import latent_statistics as latent_statistics
from ._statistics import neighbour_energy_correlation as neighbour_energy_correlation
from ._statistics import pair_mean_phasors as pair_mean_phasors
from ._statistics import pointwise_concentration as pointwise_concentration
from ._statistics import random_channel_phases as random_channel_phases
from ._statistics import region_statistics as region_statistics
from ._statistics import relative_phase_concentration as relative_phase_concentration
from ._statistics import shuffle_latents as shuffle_latents
from ._statistics import transported_phase_coherence as transported_phase_coherence
from ._train import channel_weights as channel_weights
from ._train import data_digest as data_digest
from ._train import learning_rate_schedule as learning_rate_schedule
from ._train import make_train_step as make_train_step
from ._train import optimizer as optimizer
from ._train import training_batch as training_batch
from ._train import training_masks as training_masks

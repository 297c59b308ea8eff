"""Field Latent Diffusion (Mitchel, Esteves, Makadia, CVPR 2024, §5–6): a diffusion model on FL-VAE latents.

The denoiser is a U-Net of field convolutions over tangent-vector features (:mod:`jmeshtex.ops`),
trained on latents of many remeshed copies of one textured mesh (:func:`build_dataset`); the
samplers (DDPM, DDIM) generate new latents on any mesh, which :mod:`jmeshtex.fl` decodes to colours.
Inpainting, label guidance and generative transfer reuse the same denoiser.
"""

from ._config import FLDMConfig as FLDMConfig
from ._data import FLDMData as FLDMData
from ._data import build_dataset as build_dataset
from ._data import fl_vae_encoder as fl_vae_encoder
from ._denoiser import DenoiserGeometry as DenoiserGeometry
from ._denoiser import denoise as denoise
from ._denoiser import denoiser_geometry as denoiser_geometry
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
from ._sample import decode_samples as decode_samples
from ._sample import inpaint_fldm as inpaint_fldm
from ._sample import render_samples as render_samples
from ._sample import sample_fldm as sample_fldm
from ._sample import sampling_geometry as sampling_geometry
from ._train import FLDMModel as FLDMModel
from ._train import load_fldm as load_fldm
from ._train import save_fldm as save_fldm
from ._train import train_fldm as train_fldm

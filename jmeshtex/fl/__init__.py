"""Field Latents (Mitchel, Esteves, Makadia, CVPR 2024): textures as tangent-vector latents at vertices.

FL-VAE (issue 6): :func:`encode_mesh` reads a mesh's texture (or vertex colours) in each vertex's
one-ring and encodes it as ``d`` complex numbers per vertex — tangent vectors in the per-vertex frames
of :func:`jmeshtex.geometry.one_ring_neighborhood` (x-axis = the first one-ring edge) — and
:func:`decode_texture` / :func:`decode_vertex_colors` turn such latents back into colours.
:func:`load_pretrained` gives the small model shipped in ``jmeshtex/fl/weights``. Field Latent
Diffusion (issue 7) builds on these.
"""

from ._colors import SurfaceColors as SurfaceColors
from ._colors import surface_colors as surface_colors
from ._config import FLVAEConfig as FLVAEConfig
from ._decoder import decoder_features as decoder_features
from ._denoiser import DenoiserGeometry as DenoiserGeometry
from ._denoiser import denoise as denoise
from ._denoiser import denoiser_geometry as denoiser_geometry
from ._denoiser import init_denoiser as init_denoiser
from ._denoiser import pad_geometry as pad_geometry
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
from ._encoder import OneRingSamples as OneRingSamples
from ._encoder import one_ring_samples as one_ring_samples
from ._fldm_config import FLDMConfig as FLDMConfig
from ._fldm_data import FLDMData as FLDMData
from ._fldm_data import build_dataset as build_dataset
from ._fldm_data import fl_vae_encoder as fl_vae_encoder
from ._fldm_sample import decode_samples as decode_samples
from ._fldm_sample import inpaint_fldm as inpaint_fldm
from ._fldm_sample import render_samples as render_samples
from ._fldm_sample import sample_fldm as sample_fldm
from ._fldm_train import FLDMModel as FLDMModel
from ._fldm_train import load_fldm as load_fldm
from ._fldm_train import save_fldm as save_fldm
from ._fldm_train import train_fldm as train_fldm
from ._planar import builtin_images as builtin_images
from ._planar import planar_mesh as planar_mesh
from ._pretrain import PretrainResult as PretrainResult
from ._pretrain import pretrain as pretrain
from ._reconstruct import Reconstruction as Reconstruction
from ._reconstruct import atlas_metrics as atlas_metrics
from ._reconstruct import reconstruct as reconstruct
from ._reconstruct import side_by_side as side_by_side
from ._vae import FieldLatents as FieldLatents
from ._vae import FLVAEParams as FLVAEParams
from ._vae import decode_barycentric as decode_barycentric
from ._vae import decode_points as decode_points
from ._vae import decode_points_in_faces as decode_points_in_faces
from ._vae import decode_texture as decode_texture
from ._vae import decode_vertex_colors as decode_vertex_colors
from ._vae import encode_mesh as encode_mesh
from ._vae import encode_samples as encode_samples
from ._vae import init_fl_vae as init_fl_vae
from ._vae import kl_divergence as kl_divergence
from ._vae import load_fl_vae as load_fl_vae
from ._vae import load_pretrained as load_pretrained
from ._vae import sample_latents as sample_latents
from ._vae import save_fl_vae as save_fl_vae
from ._vae import vae_loss as vae_loss

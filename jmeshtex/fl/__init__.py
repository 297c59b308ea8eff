"""Field Latents (Mitchel, Esteves, Makadia, CVPR 2024): textures as tangent-vector latents at vertices.

FL-VAE: :func:`encode_mesh` reads a mesh's texture (or vertex colours) in each vertex's
one-ring and encodes it as ``d`` complex numbers per vertex — tangent vectors in the per-vertex frames
of :func:`jmeshtex.geometry.one_ring_neighborhood` (x-axis = the first one-ring edge) — and
:func:`decode_texture` / :func:`decode_vertex_colors` turn such latents back into colours.
:func:`load_pretrained` gives the small model shipped in ``jmeshtex/fl/weights``. Field Latent
Diffusion (:mod:`jmeshtex.fldm`) builds on these.
"""

from ._colors import SurfaceColors as SurfaceColors
from ._colors import surface_colors as surface_colors
from ._config import FLVAEConfig as FLVAEConfig
from ._decoder import decoder_features as decoder_features
from ._encoder import OneRingSamples as OneRingSamples
from ._encoder import one_ring_samples as one_ring_samples
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
from ._vae import decode_vertex_colors_from_latents as decode_vertex_colors_from_latents
from ._vae import encode_mesh as encode_mesh
from ._vae import encode_samples as encode_samples
from ._vae import init_fl_vae as init_fl_vae
from ._vae import kl_divergence as kl_divergence
from ._vae import load_fl_vae as load_fl_vae
from ._vae import load_pretrained as load_pretrained
from ._vae import sample_latents as sample_latents
from ._vae import save_fl_vae as save_fl_vae
from ._vae import vae_loss as vae_loss

"""DGTS building blocks: the pieces :func:`jmeshtex.dgts.train` and :func:`jmeshtex.dgts.transfer`
are made of, for building your own model, training loop or inference schedule.

Everything here is a pure function or a plain record over the arrays of one level of the hierarchy;
the method's contract (``Config``, ``Model``, ``train`` / ``save`` / ``load``, the task verbs) lives
one level up, in :mod:`jmeshtex.dgts`.

- Switches beyond the paper and the official parity switch: :class:`Experimental`
  (``Config.experimental``).
- Multi-scale fitting (§3.3): :func:`fit_level` (one level of the template fit),
  :func:`sample_points`.
- Networks (§3.4): :class:`Generator` / :class:`Discriminator` (one level's parameters),
  :func:`init_level`, :func:`generator_level`, :func:`discriminator`, :func:`generate` (the whole
  hierarchy), :func:`upsample`, :func:`hierarchy_geometry` / :class:`LevelGeometry` (the frozen face
  neighbourhoods of every level).
- Training: :func:`gradient_penalty` (WGAN-GP), ``LOSS_NAMES`` (the per-step loss series).
- Inference: :func:`plan_transfer` / :class:`TransferPlan` and :func:`run_plan` (the two halves of
  :func:`~jmeshtex.dgts.transfer`), :func:`choose_start_level`, :func:`matching_level`, :func:`output_faces`,
  :func:`normal_heights`.
- Official weights: :func:`official_level_params`, :func:`to_official_state_dict`.
- The texture measure (tessellation-independent, on the shared undisplaced base, lengths in
  periods): :func:`knob_scores` / :class:`KnobScores` (knobs per squared period, the patch
  distribution distance), :func:`texture_operators` / :class:`TextureOperators`,
  :func:`texture_heights`, :func:`detect_knobs`, :func:`knob_threshold`,
  :func:`patch_descriptors`, :func:`sliced_wasserstein`, :func:`texture_noise`.
- Older structure measures (per-mesh mean edges; diagnostics only): :func:`peak_statistics` / :class:`PeakStatistics`,
  :func:`height_autocorrelation` and :func:`height_autocorrelation_length`,
  :func:`reconstruction_errors`; against a procedural oracle: :func:`texture_scores` /
  :class:`TextureScores`, :func:`oracle_texture`, :func:`relief_heights`, :func:`density_error`,
  :func:`period_in_mean_edges`, :func:`matched_noise`.
"""

from ._baselines import scores_beside_baselines as scores_beside_baselines
from ._config import Experimental as Experimental
from ._multiscale import fit_level as fit_level
from ._multiscale import sample_points as sample_points
from ._networks import Discriminator as Discriminator
from ._networks import Generator as Generator
from ._networks import LevelGeometry as LevelGeometry
from ._networks import discriminator as discriminator
from ._networks import generate as generate
from ._networks import generator_level as generator_level
from ._networks import hierarchy_geometry as hierarchy_geometry
from ._networks import init_level as init_level
from ._networks import upsample as upsample
from ._official import official_level_params as official_level_params
from ._official import to_official_state_dict as to_official_state_dict
from ._quality import PeakStatistics as PeakStatistics
from ._quality import TextureScores as TextureScores
from ._quality import density_error as density_error
from ._quality import height_autocorrelation as height_autocorrelation
from ._quality import height_autocorrelation_length as height_autocorrelation_length
from ._quality import matched_noise as matched_noise
from ._quality import oracle_texture as oracle_texture
from ._quality import peak_statistics as peak_statistics
from ._quality import period_in_mean_edges as period_in_mean_edges
from ._quality import reconstruction_errors as reconstruction_errors
from ._quality import relief_heights as relief_heights
from ._quality import texture_scores as texture_scores
from ._texture_measure import KnobScores as KnobScores
from ._texture_measure import TextureOperators as TextureOperators
from ._texture_measure import detect_knobs as detect_knobs
from ._texture_measure import knob_scores as knob_scores
from ._texture_measure import knob_threshold as knob_threshold
from ._texture_measure import patch_descriptors as patch_descriptors
from ._texture_measure import sliced_wasserstein as sliced_wasserstein
from ._texture_measure import texture_heights as texture_heights
from ._texture_measure import texture_noise as texture_noise
from ._texture_measure import texture_operators as texture_operators
from ._train import LOSS_NAMES as LOSS_NAMES
from ._train import gradient_penalty as gradient_penalty
from ._transfer import TransferPlan as TransferPlan
from ._transfer import choose_start_level as choose_start_level
from ._transfer import matching_level as matching_level
from ._transfer import normal_heights as normal_heights
from ._transfer import output_faces as output_faces
from ._transfer import plan_transfer as plan_transfer
from ._transfer import run_plan as run_plan

"""Configuration of DGTS (Hertz et al. 2020): every choice of the pipeline is a field here.

Two dataclasses, both frozen and JSON round-trippable (:meth:`to_dict` / :meth:`from_dict`):

- :class:`PrepareConfig`: building the multi-scale training meshes (paper §3.3); defaults follow the
  reference code's ``GtOptions`` (Adam lr 1e-4, Chamfer weights 0.4 / 0.6, normal weights 0.1,
  edge-length spread 5e-3, local equilateral term 5e-4, uniform-Laplacian "gravity" 1e-2,
  ``3000·(l + 1)`` samples at level ``l``) except the optimiser schedule: the reference alternates 3
  regulariser steps with 2 Chamfer steps for 3000 iterations at lr 1e-4 (15000 small steps); we take
  1000 steps on the weighted sum at learning rate 5e-3, which moves vertices as far in far less time.
  Decision (kept on purpose): for small steps, alternating blocks of steps on two losses follows the
  gradient flow of their step-count-weighted sum (a splitting scheme, error O(lr)), so the joint
  step reaches the same kind of fit; the one real difference is that Adam then normalises each
  loss's gradient on its own, which re-weights the reference's terms away from their nominal
  weights. The fitted meshes are only the GAN's training data and the fit is tested directly
  (distance to the reference surface, mean edge per level), so the nominal weights are used as given.
- :class:`Config`: the hierarchical WGAN-GP (paper §3.4); defaults follow the paper and the
  reference ``TrainOption`` (7 layers, widths 32 → 128, Adam learning rate 5e-4, betas (0.5, 0.99),
  learning rate halved every 500 steps, 2 discriminator and 3 generator updates per step, γ = 5,
  gradient-penalty weight 0.1, noise amplitude 0.1 mean edges, 2000 steps per level).

Neither holds a seed: randomness comes from the ``key`` argument of :func:`~jmeshtex.dgts.training_meshes`
and :func:`~jmeshtex.dgts.train`.
"""

from __future__ import annotations

import dataclasses

from .._config import ConfigBase, cross_rule, rule


@dataclasses.dataclass(frozen=True)
class PrepareConfig(ConfigBase):
    """How the multi-scale training meshes are fitted (DGTS §3.3, reference ``GtOptions``).

    At level ``l`` the template (subdivided ``l`` times, mean edge ≈ 1 in the level's frame) is fitted
    to the reference by Adam on

    .. math:: w_{st} d(S \\to T) + w_{ts} d(T \\to S) + w_{n,st} \\nu(S \\to T) + w_{n,ts}
       \\nu(T \\to S) + w_e\\,\\mathrm{std}(|e|) + w_\\ell\\, \\overline{\\textstyle\\sum_k \\hat\\ell_k
       \\log \\hat\\ell_k} + w_g\\, \\overline{|v - \\bar v_{\\mathcal N(v)}|_1}

    (Chamfer terms on ``samples_per_level·(l+1)`` area-uniform samples, normal terms ``-n·n'``,
    edge-length spread, negative entropy of each face's normalised edge lengths, uniform Laplacian).

    Attributes:
      levels: number of levels (meshes) to produce, ≥ 1 (5: the paper's depth; its finest levels
        have ~20K–80K faces, i.e. a template of 80–320 faces).
      steps: Adam steps per level.
      learning_rate: Adam learning rate.
      samples_per_level: surface samples at level 0; level ``l`` uses ``(l + 1)`` times as many.
      weight_s2t, weight_t2s: Chamfer weights, template → reference and reference → template.
      weight_normal_s2t, weight_normal_t2s: normal-agreement weights.
      weight_edge_std: weight of the standard deviation of all edge lengths.
      weight_edge_local: weight of the per-face equilateral (edge-entropy) term.
      weight_laplacian: weight of the uniform-Laplacian smoothness ("gravity") term.
      squared_chamfer: squared distances (False: plain distances, as the reference).
      scale_factor: rescaling between levels (edges halve under subdivision; 2 restores them).
      schedule: ``"joint"`` (default: ``steps`` Adam steps on the weighted sum) or ``"official"``
        (the reference ``GroundTruthGenerator.optimize``: ``steps`` iterations, each
        ``regularizer_steps`` Adam steps on the regularisers then ``chamfer_steps`` on the Chamfer
        and normal terms, one Adam state; nearest neighbours by a KD-tree on the host,
        ``scipy.spatial.cKDTree``). :meth:`official` gives the reference's counts and rate.
      regularizer_steps, chamfer_steps: the official schedule's steps per iteration (3, 2).

    Example:
      >>> PrepareConfig(levels=2, steps=50).samples_per_level
      3000
      >>> o = PrepareConfig.official()
      >>> o.schedule, o.steps, o.learning_rate, o.regularizer_steps, o.chamfer_steps
      ('official', 3000, 0.0001, 3, 2)
    """

    levels: int = 5
    steps: int = 1000
    learning_rate: float = 5e-3
    samples_per_level: int = 3000
    weight_s2t: float = 0.4
    weight_t2s: float = 0.6
    weight_normal_s2t: float = 0.1
    weight_normal_t2s: float = 0.1
    weight_edge_std: float = 5e-3
    weight_edge_local: float = 5e-4
    weight_laplacian: float = 1e-2
    squared_chamfer: bool = False
    scale_factor: float = 2.0
    schedule: str = "joint"
    regularizer_steps: int = 3
    chamfer_steps: int = 2

    _RULES = (
        rule("levels samples_per_level", lambda x: x >= 1, ">= 1"),
        rule("schedule", lambda x: x in ("joint", "official"), "'joint' or 'official'"),
        rule("regularizer_steps chamfer_steps", lambda x: x >= 0, ">= 0"),
        rule(
            "steps weight_s2t weight_t2s weight_normal_s2t weight_normal_t2s weight_edge_std weight_edge_local "
            "weight_laplacian",
            lambda x: x >= 0,
            ">= 0",
        ),
        rule("learning_rate scale_factor", lambda x: x > 0, "> 0"),
    )

    @classmethod
    def official(cls, **changes) -> PrepareConfig:
        """The reference code's fitting (``GtOptions``): the official schedule, 3000 iterations of 3
        regulariser + 2 Chamfer Adam steps at learning rate 1e-4, ``changes`` applied on top."""
        return cls(**{"schedule": "official", "steps": 3000, "learning_rate": 1e-4, **changes})

    @classmethod
    def tiny(cls, **changes) -> PrepareConfig:
        """Two levels fitted in seconds (150 steps, 800 samples): tests, the demo and notebooks.

        Example:
          >>> PrepareConfig.tiny().levels, PrepareConfig.tiny(levels=3).levels
          (2, 3)
        """
        return cls(**{"levels": 2, "steps": 150, "samples_per_level": 800, **changes})


#: :attr:`Config.fake_inputs` choices
FAKE_INPUTS = ("sampled", "reconstructed")


@dataclasses.dataclass(frozen=True)
class Experimental(ConfigBase):
    """DGTS switches beyond the paper, and the official code's parity switch: ``Config.experimental``.

    The defaults are the reference code's; the studies (``docs/results.md``, DGTS) and
    :func:`~jmeshtex.dgts.from_official_state_dict` set them. Their names are unique across
    :class:`~jmeshtex.dgts.Config`, so ``Config(official_axes=True)`` and ``config.replace(fake_inputs=...)`` reach
    them, and a model file stores them among the config's own fields.

    Attributes:
      fixed_noise_levels: the reconstruction's noise is fixed (drawn once, kept in the model) at
        levels ``0 … fixed_noise_levels − 1`` and zero above. The reference: 1 (``z*`` at the
        coarsest level only). Beyond the paper: when the coarsest levels carry no texture
        (``training_meshes(coarse_levels=K)``), ``K + 1`` makes the first textured level
        reconstruct its layout from noise of its own, so its generator learns to lay the texture
        out from noise rather than to key it to the template's triangles.
      fake_inputs: what the frozen levels ``0 … L−1`` make the critic's fakes of level ``L`` from:
        ``"sampled"`` (the reference's: fresh noise at every level, so level ``L`` sees coarse
        shapes it cannot correct) or ``"reconstructed"`` (the reconstruction's noise below ``L``
        and fresh noise at level ``L`` only: the critic judges the
        detail level ``L`` adds to the training mesh's own coarse shape, as a transfer feeds it a
        real target; beyond the paper).
      official_axes: True: the generator's in-plane displacement coefficient is along ``x × n``
        (the official code's axis) instead of jmeshtex's ``n × x``; set by
        :func:`~jmeshtex.dgts.from_official_state_dict` so official weights run unchanged
        (:attr:`~jmeshtex.dgts.Config.y_sign`).

    Example:
      >>> Config(fake_inputs="reconstructed").experimental.fake_inputs
      'reconstructed'
    """

    fixed_noise_levels: int = 1
    fake_inputs: str = "sampled"
    official_axes: bool = False

    _RULES = (
        rule("fixed_noise_levels", lambda x: x >= 1, ">= 1"),
        rule("fake_inputs", lambda x: x in FAKE_INPUTS, f"one of {FAKE_INPUTS}"),
    )


@dataclasses.dataclass(frozen=True)
class Config(ConfigBase):
    """The hierarchical WGAN-GP of DGTS (§3.4) with the reference code's defaults.

    Widths: layer ``i`` (1 ≤ i ≤ num_layers − 2) of level ``l`` has
    ``max(min(start_features·2^l, max_features) // 2^(i−1), min_features)`` channels; the first layer
    embeds the 4 edge features, the last emits 3 displacement coefficients (generator) or 1 score
    (discriminator). A level whose widths equal the previous level's starts from its weights.

    Attributes:
      num_layers: layers per network, counting the input (reference: 7, so 6 weight layers).
      start_features, min_features, max_features: the width schedule above (32, 32, 128).
      noise_amplitude: std of the Gaussian vertex noise, in mean edges of the level (0.1).
      scale_factor: rescaling after each subdivision (2: the mean edge stays ≈ 1).
      learning_rate: Adam learning rate (5e-4), for both networks.
      beta1, beta2: Adam betas (0.5, 0.99).
      learning_rate_decay: factor applied to the learning rate every ``learning_rate_decay_every``
        steps (0.5 every 500).
      learning_rate_decay_every: steps between decays.
      discriminator_steps, generator_steps: critic and generator updates per step (2, 3).
      reconstruction_weight: γ, weight of the vertex MSE of the reconstruction (5).
      penalty_weight: weight of the gradient penalty (0.1, as the reference code; the paper's
        WGAN-GP default would be 10).
      reconstruction_start: first level using the fixed noise z* for the reconstruction; below it
        the reconstruction uses fresh noise (the reference uses 1).
      steps: training steps per level (2000); one step is ``discriminator_steps`` critic updates
        followed by ``generator_steps`` generator updates.
      negative_slope: leaky-ReLU slope (0.2).
      eps: instance-norm regulariser (1e-5).
      shared_levels: levels ``0 … shared_levels − 1`` are padded (masked faces and vertices, which
        change no output) to the size of level ``shared_levels − 1``, so that, when their widths
        agree, they run one compiled training step instead of one each (0 or 1: no padding). Worth
        it for small, equal-width configurations (tests, demo), where compilation dominates.
      experimental: the switches beyond the paper and the parity switch
        (:class:`~jmeshtex.dgts.core.Experimental`: the fixed noise's levels, the critic's fakes,
        the official in-plane axis); each may also be given by its own name to the constructor,
        ``replace``, ``from_dict`` and :meth:`tiny`, and a model file stores them among
        the fields above.
      checkpoint_every: with ``train(checkpoint_dir=)``, also checkpoint every this many steps
        within a level (rounded up to a multiple of ``CHUNK``); None: only after each level. A
        resumed run may change it.

    Example:
      >>> c = Config(steps=300, learning_rate=1e-3)
      >>> Config.from_dict(c.to_dict()) == c, c.level_features(0, generator=False)[-1]
      (True, 1)
    """

    num_layers: int = 7
    start_features: int = 32
    min_features: int = 32
    max_features: int = 128
    noise_amplitude: float = 0.1
    scale_factor: float = 2.0
    learning_rate: float = 5e-4
    beta1: float = 0.5
    beta2: float = 0.99
    learning_rate_decay: float = 0.5
    learning_rate_decay_every: int = 500
    discriminator_steps: int = 2
    generator_steps: int = 3
    reconstruction_weight: float = 5.0
    penalty_weight: float = 0.1
    reconstruction_start: int = 1
    steps: int = 2000
    negative_slope: float = 0.2
    eps: float = 1e-5
    shared_levels: int = 0
    checkpoint_every: int | None = None
    experimental: Experimental = Experimental()

    #: what a resumed run may change (:meth:`~jmeshtex.ConfigBase.fingerprint`)
    _RESUMABLE = frozenset({"checkpoint_every"})

    _RULES = (
        rule("num_layers", lambda x: x >= 3, ">= 3 (input, one hidden, output)"),
        rule(
            "start_features min_features learning_rate_decay_every generator_steps",
            lambda x: x >= 1,
            ">= 1",
        ),
        rule(
            "noise_amplitude discriminator_steps steps reconstruction_weight penalty_weight shared_levels",
            lambda x: x >= 0,
            ">= 0",
        ),
        rule("learning_rate scale_factor", lambda x: x > 0, "> 0"),
        rule("beta1 beta2", lambda x: 0 <= x < 1, "in [0, 1)"),
        rule("learning_rate_decay", lambda x: 0 < x <= 1, "in (0, 1]"),
        rule("reconstruction_start", lambda x: x >= 0, ">= 0"),
        rule("negative_slope", lambda x: 0 <= x < 1, "in [0, 1)"),
        rule("eps", lambda x: x > 0, "> 0"),
        rule("checkpoint_every", lambda x: x is None or x >= 1, ">= 1 or None"),
        cross_rule(
            lambda c: c.min_features <= c.max_features,
            "need min_features <= max_features, got {c.min_features}, {c.max_features}",
        ),
    )

    @classmethod
    def tiny(cls, **changes) -> Config:
        """A network that trains in seconds on a CPU: tests, the demo and notebooks.

        Four layers of width 16 at every level and ``shared_levels=2``, so both levels of a
        :meth:`PrepareConfig.tiny` hierarchy run one compiled training step; 120 steps.

        Example:
          >>> c = Config.tiny()
          >>> c.level_features(0, generator=True), c.steps, c.shared_levels
          ((16, 16, 3), 120, 2)
        """
        base = dict(
            num_layers=4,
            start_features=16,
            min_features=16,
            max_features=16,
            steps=120,
            learning_rate_decay_every=100,
            shared_levels=2,
        )
        return cls(**{**base, **changes})

    @property
    def y_sign(self) -> float:
        """The sign of the in-plane displacement coefficient (−1 with :attr:`~jmeshtex.dgts.core.Experimental.official_axes`, else 1).

        Example:
          >>> Config().y_sign, Config(official_axes=True).y_sign
          (1.0, -1.0)
        """
        return -1.0 if self.experimental.official_axes else 1.0

    def level_features(self, level: int, *, generator: bool) -> tuple[int, ...]:
        """Output widths of the weight layers at ``level`` (embedding first, 3 or 1 last).

        Example:
          >>> Config().level_features(0, generator=True)
          (32, 32, 32, 32, 32, 3)
          >>> Config().level_features(2, generator=False)
          (128, 64, 32, 32, 32, 1)
        """
        hidden = [
            max(
                min(self.start_features * 2**level, self.max_features) // 2 ** (i - 1),
                self.min_features,
            )
            for i in range(1, self.num_layers - 1)
        ]
        return (*hidden, 3 if generator else 1)

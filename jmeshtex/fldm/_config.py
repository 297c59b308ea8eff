"""Configuration of Field Latent Diffusion (Mitchel, Esteves, Makadia, CVPR 2024, §5–6, supp. §8.2).

One frozen, JSON round-trippable dataclass :class:`Config` holds the denoiser's architecture, the
diffusion schedule, the training data (re-triangulated copies) and the optimiser. Presets:

- :meth:`Config.paper`: the paper's denoiser as the released labelled configuration
  (google-research ``mesh_diffusion/sin_mesh_ddm/configs/default.py`` and
  ``default_train_labeled.py``): 96 / 192 channels, 2 + 4 + 4 FCResNet blocks, ``hdim`` 16,
  two-hidden-layer filters, ``mlp_layers`` 2, ``k_conv`` 8, ε-prediction, cosine noise schedule,
  L1 loss, the released noise scale (one σ = √2·mean|μ| per real noise component), batch 16, Adam 5e-4 with 1000 warm-up steps and cosine decay to
  1e-5 over 200K steps; 500 copies of ~30K vertices, T = 1000;
- :meth:`Config.cpu`: the ``tiny`` denoiser on a 10,000-step budget (sized by measurement);
- :meth:`Config.tiny`: tests, demos and notebooks (16 / 32 channels, 1 + 1 + 1 blocks, few copies).

``knn`` counts the vertex itself: the reference keeps the first ``k_conv = 8`` columns of a
nearest-neighbour list built by its unpublished preprocessing, and a sorted nearest-neighbour list
starts with the vertex itself (distance 0), so ``knn = 8`` here is the vertex and its 7 nearest
neighbours (an assumption; the released code does not show the list's construction).
"""

from __future__ import annotations

import dataclasses

from .._config import ConfigBase, cross_rule, is_int, rule
from ._diffusion import PREDICTIONS, SCHEDULES, Schedule, make_schedule

LOSSES = ("l2", "l1")
SCALINGS = ("per_channel", "global", "released")
PHASE_SYNC = ("none", "flat", "all")


@dataclasses.dataclass(frozen=True)
class Experimental(ConfigBase):
    """The study switches of an FLDM run, beyond the paper: ``Config.experimental``.

    Their defaults are the paper's denoiser and data; the studies (``docs/results.md``) and the
    :meth:`~jmeshtex.fldm.Config.cpu` preset set them. Their names are unique across :class:`~jmeshtex.fldm.Config`, so
    ``Config.tiny(invariants=True)``, ``config.replace(schedule_shift=2.0)`` and a command line's
    ``--set phase_sync=flat`` (or ``--set experimental.phase_sync=flat``) reach them, and a model
    file or checkpoint stores them among the config's own fields.

    Attributes:
      schedule_shift: divide the schedule's signal-to-noise ratio by its square
        (:func:`~jmeshtex.fldm.core.make_schedule`, beyond the paper); 1: the plain schedule.
      remat: recompute each FCResNet block's activations in the backward pass instead of keeping
        them (gradient checkpointing, :func:`flax.linen.remat`), for roughly one more forward pass
        of compute; the numbers agree to float32 round-off. It trims the activations kept between
        blocks, not the peak inside one field convolution: at the paper's size (30K vertices,
        batch 1) XLA's CPU memory analysis gives 11.6 GiB with or without it.
      collapsed_channels: what to do with channels whose raw mean power is below
        ``collapsed_below`` × the strongest channel's: ``"keep"``; ``"downweight"`` (their loss
        weight is that power ratio); ``"drop"`` (their latents are zeroed in training, so the
        model learns to generate zeros there).
      collapsed_below: the power ratio under which a channel counts as collapsed.
      encodings_per_copy: FL-VAE encodings kept per copy, each with a fresh one-ring sampling
        (an augmentation of the phase noise; each training draw picks one at random).
      stats_samples: DDIM samples drawn at every checkpoint for the decoder-free statistics
        (:func:`~jmeshtex.fldm.core.latent_statistics`) logged with it; 0: none.
      stats_ddim_steps: DDIM steps of those samples.
      invariants: an invariant stream, beyond the paper: every block's embedding (the filter input
        of its second field convolution) also sees, per vertex and channel, the block input's
        normalised power and its mean over the k-NN neighbourhood
        (:func:`~jmeshtex.fldm.core.magnitude_context`). On flat rings the FL-VAE's latents have
        a common phase per vertex that is sampling noise (``phase_sync="none"``), so the field
        convolutions' sums over neighbours cancel there and the layout of magnitudes (where a
        texture's patches live) has no other way in. False (default, the paper's denoiser).
      phase_sync: coherent latents, beyond the paper (:func:`~jmeshtex.fldm.core.synchronize_phases`):
        ``"none"`` (the encoder's phases, the paper's); ``"flat"`` (every encoding's flat rings,
        :func:`~jmeshtex.fldm.core.ring_color_spread` below ``flat_spread``, turned to agree with
        their neighbours after transport; textured rings keep their phase; for the log decoder);
        ``"all"`` (every ring; for the barycentric decoder, which reads no phase).
      flat_spread: the RGB RMS colour spread under which a ring counts as flat (``phase_sync="flat"``).

    Example:
      >>> Config.tiny(phase_sync="flat").experimental.phase_sync
      'flat'
    """

    schedule_shift: float = 1.0
    remat: bool = False
    collapsed_channels: str = "keep"
    collapsed_below: float = 0.05
    encodings_per_copy: int = 1
    stats_samples: int = 0
    stats_ddim_steps: int = 25
    invariants: bool = False
    phase_sync: str = "none"
    flat_spread: float = 0.02

    _RULES = (
        rule("schedule_shift", lambda x: x > 0, "> 0"),
        rule(
            "collapsed_channels",
            lambda x: x in ("keep", "downweight", "drop"),
            "'keep', 'downweight' or 'drop'",
        ),
        rule("collapsed_below", lambda x: 0 <= x < 1, "in [0, 1)"),
        rule("encodings_per_copy stats_ddim_steps", lambda x: is_int(x, 1), "a positive integer"),
        rule("stats_samples", lambda x: is_int(x, 0), "an integer >= 0"),
        rule("phase_sync", lambda x: x in PHASE_SYNC, f"one of {PHASE_SYNC}"),
        rule("flat_spread", lambda x: 0 <= x < 2, "in [0, 2)"),
    )


@dataclasses.dataclass(frozen=True)
class Config(ConfigBase):
    """Every choice of an FLDM run.

    Attributes:
      latent_channels: ``d``, complex latent channels per vertex (the FL-VAE's).
      widths: channels at the fine and the coarse level of the U-Net (paper: 96, 192).
      blocks: FCResNet blocks ``(down, middle, up)`` (paper: 2, 4, 4).
      hdim: filter responses per input channel of each field convolution (filter MLP width).
      mlp_layers: (norm → vector neuron) layers before each field convolution (reference: 1 by
        default, 2 in the released labelled configuration).
      filter_layers: hidden layers of the filter MLPs, 1 or 2 (reference: 2).
      knn: neighbourhood size of the field convolutions (slots including the vertex itself).
      activation: filter nonlinearity, ``"silu"`` (paper) or ``"relu"`` (faster on CPU).
      time_features: width of the sinusoidal timestep embedding.
      num_labels: label classes for label-guided generation (0: unconditional).
      mask_conditioning: inpainting conditioned on the mask (§6.4): the denoiser also sees the
        inpainting mask as a per-vertex filter input (beside the timestep and labels, like the
        reference's ``FieldConvEmb``) and the known latents, masked, as ``d`` extra tangent input
        channels; training draws a random mask per copy and step (:func:`~jmeshtex.fldm.random_mask`:
        half-space cuts, a quarter of them empty so that plain sampling is learned too) and
        measures the loss on the generated region only. Sampling still replaces the kept region
        (eq. 14), so it stays exact. False (default): the plain denoiser; inpainting by
        replacement alone.
      schedule: ``"linear"`` or ``"cosine"``.
      prediction: what the denoiser outputs: ``"epsilon"`` (paper, eq. 10) or ``"v"``
        (:func:`~jmeshtex.fldm.core.prediction_target`; the CPU preset's: a small denoiser trained on the ε-loss
        over-shoots the latents' magnitude several times when sampled).
      diffusion_steps: diffusion steps ``T`` of the noise schedule.
      learning_rate: Adam peak learning rate.
      lr_schedule: ``"cosine"`` (linear warm-up from 0 over ``warmup_steps``, then cosine decay
        to ``end_learning_rate`` at ``steps``; the reference's) or ``"constant"``.
      warmup_steps: warm-up steps of the cosine schedule (capped at ``steps // 2``).
      end_learning_rate: final learning rate of the cosine schedule.
      ema_decay: decay of an exponential moving average of the weights kept during training and
        returned as the model (0: no EMA, the trained weights themselves).
      batch_size: mesh copies per step (split over devices).
      steps: optimiser steps of :func:`~jmeshtex.fldm.train`.
      checkpoint_every: steps between checkpoints.
      n_copies: re-triangulated copies of the input mesh.
      copy_vertices: vertices per copy (0: the input's count).
      pool_ratio: coarse / fine vertex ratio of the U-Net's one downsampling.
      bucket: vertex counts are padded up to a multiple of this (limits recompiles).
      loss: the training loss: ``"l2"`` (the paper's eq. 10: mean squared modulus of the error)
        or ``"l1"`` (the released ``get_l1_loss``: mean modulus of the error).
      latent_scaling: ``"per_channel"`` (every channel to unit mean power, eq. 38–39),
        ``"global"`` (one σ for all channels to unit mean power: collapsed channels stay small;
        one σ as released, but the released code does not reach unit power) or ``"released"``
        (the released ``train.py``'s noise scale, ``σ = √2·mean|μ|`` per real noise component
        on the raw latents: :func:`~jmeshtex.fldm.core.latent_scale` with ``released=True``;
        noise power 2.6× the data's on the shipped FL-VAE's Spot latents; ``Config.paper``'s).
        On Spot's synchronised latents at 3K vertices ``"per_channel"`` learns faster over the
        first 2,000 steps (``docs/results.md``, "Noise scale"), so the other presets keep it.
      accumulate: micro-batches per optimiser step (gradient accumulation; ``batch_size`` must
        be a multiple); 1: the whole batch at once.
      experimental: the study switches beyond the paper (:class:`~jmeshtex.fldm.core.Experimental`);
        each may also be given by its own name to ``replace``, ``from_dict`` and the presets
        (``Config.tiny(invariants=True)``), and a model file stores them among the fields above.

    Randomness (copies, initialisation, training noise) comes from the ``key`` of
    :func:`~jmeshtex.fldm.build_dataset` and :func:`~jmeshtex.fldm.train`, not from the config.

    Example:
      >>> c = Config.tiny()
      >>> Config.from_dict(c.to_dict()) == c
      True
    """

    latent_channels: int = 4
    widths: tuple[int, int] = (96, 192)
    blocks: tuple[int, int, int] = (2, 4, 4)
    hdim: int = 16
    mlp_layers: int = 2
    filter_layers: int = 2
    knn: int = 8
    activation: str = "silu"
    time_features: int = 32
    num_labels: int = 0
    mask_conditioning: bool = False
    schedule: str = "linear"
    prediction: str = "epsilon"
    diffusion_steps: int = 1000
    learning_rate: float = 5e-4
    lr_schedule: str = "cosine"
    warmup_steps: int = 1000
    end_learning_rate: float = 1e-5
    ema_decay: float = 0.0
    batch_size: int = 4
    steps: int = 20000
    checkpoint_every: int = 500
    n_copies: int = 500
    copy_vertices: int = 30000
    pool_ratio: float = 0.25
    bucket: int = 256
    loss: str = "l2"
    latent_scaling: str = "per_channel"
    accumulate: int = 1
    experimental: Experimental = Experimental()

    _MESSAGE = "{name} must be {must}, got {value!r}"
    #: what a resumed run may change: step counts, checkpoint cadence, the checkpoint statistics'
    #: sampling and rematerialisation (memory against time, same numbers)
    _RESUMABLE = frozenset(
        {"steps", "checkpoint_every", "remat", "stats_samples", "stats_ddim_steps"}
    )
    _RULES = (
        rule(
            "latent_channels hdim knn time_features diffusion_steps batch_size steps checkpoint_every n_copies "
            "bucket",
            lambda x: is_int(x, 1),
            "a positive integer",
        ),
        rule(
            "widths",
            lambda w: len(w) == 2 and all(is_int(x, 1) for x in w),
            "two positive integers (fine, coarse)",
        ),
        rule(
            "blocks",
            lambda b: len(b) == 3 and all(is_int(x, 1) for x in b),
            "three positive integers (down, middle, up)",
        ),
        rule("activation", lambda x: x in ("silu", "relu"), "'silu' or 'relu'"),
        rule("mlp_layers", lambda x: is_int(x, 1), "a positive integer"),
        rule("filter_layers", lambda x: x in (1, 2), "1 or 2"),
        rule("lr_schedule", lambda x: x in ("cosine", "constant"), "'cosine' or 'constant'"),
        rule("warmup_steps", lambda x: is_int(x, 0), "an integer >= 0"),
        rule("end_learning_rate", lambda x: x >= 0, ">= 0"),
        rule("ema_decay", lambda x: 0 <= x < 1, "in [0, 1)"),
        rule("schedule", lambda x: x in SCHEDULES, f"one of {SCHEDULES}"),
        rule("prediction", lambda x: x in PREDICTIONS, f"one of {PREDICTIONS}"),
        rule("num_labels", lambda x: is_int(x, 0), ">= 0"),
        rule(
            "copy_vertices",
            lambda x: is_int(x) and (x == 0 or x >= 16),
            "0 (keep the input's count) or >= 16",
        ),
        rule("pool_ratio", lambda x: 0.05 <= x <= 0.75, "in [0.05, 0.75]"),
        rule("learning_rate", lambda x: x > 0, "> 0"),
        rule("loss", lambda x: x in LOSSES, f"one of {LOSSES}"),
        rule("latent_scaling", lambda x: x in SCALINGS, f"one of {SCALINGS}"),
        rule("accumulate", lambda x: is_int(x, 1), "a positive integer"),
        rule("mask_conditioning", lambda x: isinstance(x, bool), "True or False"),
        rule("diffusion_steps", lambda x: x >= 2, ">= 2", message="{name} must be {must}"),
        cross_rule(
            lambda c: c.batch_size % c.accumulate == 0,
            "batch_size ({c.batch_size}) must be a multiple of accumulate ({c.accumulate}); "
            "each micro-batch holds batch_size // accumulate copies",
        ),
    )

    @classmethod
    def paper(cls, **changes) -> Config:
        """The released labelled configuration (module docstring).

        Cosine noise schedule, batch 16 (4 micro-batches of 4 copies, gradient accumulation),
        200K steps, the released L1 loss and the released noise scale (``σ = √2·mean|μ|`` per
        real component, ``latent_scaling="released"``); ``loss="l2"`` gives the paper's eq. 10
        and ``latent_scaling="per_channel"`` eq. 38–39 per channel. Not as released: the FRN
        gain is real here (the paper's eq. 20 and the released norm: complex).

        Example:
          >>> c = Config.paper()
          >>> c.widths, c.blocks, c.hdim, c.filter_layers, c.mlp_layers, c.knn, c.prediction
          ((96, 192), (2, 4, 4), 16, 2, 2, 8, 'epsilon')
          >>> c.schedule, c.batch_size, c.accumulate, c.steps, c.loss, c.latent_scaling
          ('cosine', 16, 4, 200000, 'l1', 'released')
        """
        base = dict(
            schedule="cosine",
            batch_size=16,
            accumulate=4,
            steps=200000,
            loss="l1",
            latent_scaling="released",
        )
        return cls.from_dict({**base, **changes})

    @classmethod
    def cpu(cls, **changes) -> Config:
        """A CPU preset sized by measurement (``docs/results.md``).

        The :meth:`tiny` denoiser (16/32 channels, one-hidden-layer ReLU filters) with three blocks
        at the coarse level (1+3+1: the paper's deeper middle, where each field convolution reaches
        twice as far as at the fine level), v-prediction, the cosine noise schedule, Adam 2e-3 with
        200 warm-up steps and cosine decay to 1e-5 over 10,000 steps, batch 2, an EMA of the
        weights (0.999), 16 copies of 10,000 vertices
        with 4 FL-VAE encodings each, 2 DDIM-25 samples for the statistics at every checkpoint
        (every 500 steps), and the invariant stream (``invariants``, beyond the paper): on Spot it
        took the samples' neighbour correlation of ``|z|²`` from 0.01 to 0.19 by step 1,500 where
        the same preset without it stayed at 0.01–0.02 to step 2,500 (``fldm_spot_control.md``).
        The deeper middle costs 1.4× the CPU per step (1.0 against 0.73 CPU-s) and, on the FL-VAE's
        latents shipped now, took that correlation to 0.11 at step 2,000 where 1+1+1 blocks on the
        same schedule reached 0.04, and to 0.31–0.34 in the samples after the 10,000 steps
        (``fldm_spot_mid3.md``; they show dark patches on Spot's body where 1+1+1 shows speckle).

        Example:
          >>> c = Config.cpu()
          >>> c.widths, c.blocks, c.schedule, c.steps, c.learning_rate, c.experimental.invariants
          ((16, 32), (1, 3, 1), 'cosine', 10000, 0.002, True)
        """
        base = dict(
            blocks=(1, 3, 1),
            prediction="v",
            schedule="cosine",
            learning_rate=2e-3,
            end_learning_rate=1e-5,
            warmup_steps=200,
            steps=10000,
            ema_decay=0.999,
            batch_size=2,
            n_copies=16,
            copy_vertices=10000,
            encodings_per_copy=4,
            checkpoint_every=500,
            stats_samples=2,
            invariants=True,
            stats_ddim_steps=25,
            bucket=256,
        )
        return cls.tiny(**{**base, **changes})

    @classmethod
    def demo(cls, **changes) -> Config:
        """The striped-sphere demo and learning check (2 latent channels, 300 steps; seconds).

        :meth:`tiny` with a 2-channel latent (the analytic codec of
        :func:`jmeshtex.data.stripe_encoder`), 4 copies of 500 vertices and 200 diffusion steps.

        Example:
          >>> c = Config.demo()
          >>> c.latent_channels, c.steps, c.diffusion_steps
          (2, 300, 200)
        """
        base = dict(
            latent_channels=2,
            n_copies=4,
            copy_vertices=500,
            steps=300,
            batch_size=2,
            learning_rate=3e-3,
            widths=(16, 32),
            hdim=8,
            diffusion_steps=200,
            bucket=64,
        )
        return cls.tiny(**{**base, **changes})

    def noise_schedule(self) -> Schedule:
        """The noise schedule of training and sampling (``schedule``, ``diffusion_steps``,
        ``schedule_shift``).

        Example:
          >>> s = Config.tiny(schedule="cosine", schedule_shift=2.0).noise_schedule()
          >>> s.num_steps, bool(s.alpha_bars[499] < Config.tiny(schedule="cosine").noise_schedule().alpha_bars[499])
          (1000, True)
        """
        return make_schedule(
            self.schedule,
            num_steps=self.diffusion_steps,
            shift=float(self.experimental.schedule_shift),
        )

    def network(self) -> Config:
        """This config with every field the denoiser network does not read reset to its default.

        The denoiser's initialiser and forward pass are compiled once per ``network()``: two runs
        that differ in schedule, steps, data or optimiser share those programs.

        Example:
          >>> Config.tiny(steps=5).network() == Config.tiny(steps=9, diffusion_steps=50).network()
          True
        """
        fields = self.to_dict()
        return type(self).from_dict({f: fields[f] for f in NETWORK_FIELDS})

    @classmethod
    def tiny(cls, **changes) -> Config:
        """Tests, demos and notebooks: 16/32 channels, 1+1+1 blocks, 4 copies of 400 vertices.

        Example:
          >>> c = Config.tiny(latent_channels=2)
          >>> c.widths, c.n_copies, c.latent_channels
          ((16, 32), 4, 2)
        """
        base = dict(
            widths=(16, 32),
            blocks=(1, 1, 1),
            hdim=4,
            mlp_layers=1,
            filter_layers=1,
            knn=7,
            activation="relu",
            time_features=16,
            n_copies=4,
            copy_vertices=400,
            steps=200,
            batch_size=2,
            learning_rate=3e-3,
            warmup_steps=20,
            checkpoint_every=100,
            bucket=64,
        )
        return cls.from_dict({**base, **changes})


#: the :class:`Config` fields the denoiser network reads (:meth:`Config.network`)
NETWORK_FIELDS = (
    "latent_channels",
    "widths",
    "blocks",
    "hdim",
    "mlp_layers",
    "filter_layers",
    "knn",
    "activation",
    "time_features",
    "num_labels",
    "mask_conditioning",
    "invariants",
    "remat",
)

"""Configuration of the FL-VAE (Mitchel, Esteves, Makadia, CVPR 2024, §4, supplement §8–9.1).

One frozen, JSON round-trippable dataclass holds every choice of the model, of the one-ring sampling
and of planar pre-training. Defaults follow the paper where it gives a number (``d = 8`` complex
latent channels, 64 one-ring samples, a 5-layer SiLU decoder, ``λ_KL = 0.01``); the widths and depths
the paper leaves open are chosen small enough to train on two CPU cores.
"""

from __future__ import annotations

import dataclasses

from .._config import ConfigBase, cross_rule, rule

#: decoder variants: the paper's log-coordinate neural field and its barycentric ablation (Table 1)
DECODERS = ("log", "barycentric")
#: the reference colour of the encoder's token: the ring's centre sample (the reference's
#: ``ring_vae.init_conv``) or the mean of the ring's samples (the shipped models')
TOKENS = ("centre", "ring_mean")
#: the log decoder's training objective: each sample blended from its face's three corners as at
#: inference, or decoded from the ring's own vertex alone (the shipped models')
LOG_OBJECTIVES = ("blended", "vertex")
#: the VN-Transformer's normalisation: per element (the shipped models') or per channel over all
#: vertices and samples (the reference's ``square_mag_norm_encoder``)
VN_NORMS = ("element", "channel")


#: fields that do not change the model's function (data, optimiser, batching, chunking)
_TRAINING_FIELDS = (
    "num_samples",
    "kl_weight",
    "loss_normalization",
    "min_vertices",
    "max_vertices",
    "max_image_size",
    "meshes_per_image",
    "pixels_per_vertex",
    "density_spread",
    "texture_size",
    "procedural_fraction",
    "batch_size",
    "steps",
    "learning_rate",
    "final_lr_fraction",
    "warmup_steps",
    "grad_clip",
    "ema_decay",
    "checkpoint_every",
    "encode_chunk",
    "log_objective",
    "kl_warmup_steps",
    "free_bits",
    "boundary_in_loss",
    "log_sigma_init",
    "extra_images",
)
#: how :func:`~jmeshtex.fl.core.vae_loss` averages its terms
LOSS_NORMALIZATIONS = ("mean", "paper")


@dataclasses.dataclass(frozen=True)
class Experimental(ConfigBase):
    """The study switches of the FL-VAE, beyond the shipped recipe: ``Config.experimental``.

    Their defaults are the shipped models' recipe (``token`` excepted: the reference's, which the
    shipped models were converted to); the studies (``docs/results.md``) set them. Their names are
    unique across :class:`~jmeshtex.fl.Config`, so ``Config.small(free_bits=0.1)``,
    ``config.replace(vn_norm="channel")`` and ``--set token=ring_mean`` reach them, and a model
    file stores them among the config's own fields.

    Attributes:
      token: the token's reference colour: ``"centre"`` (the reference's: the colour at the vertex
        itself, sample 0 of :func:`~jmeshtex.fl.core.one_ring_samples` with ``center=True``, which
        is also a reconstruction target) or ``"ring_mean"`` (the mean sample colour; the shipped
        models', which a stored config without this field means).
      log_objective: how the log decoder is trained: ``"blended"`` (each sample decoded from its
        face's three corner latents and blended barycentrically, as at inference; beyond the
        paper, which trains each ring on its own vertex's latent and blends only at inference) or
        ``"vertex"`` (each ring decoded from its own vertex's latent: the paper's objective, and
        the shipped models'). The barycentric
        decoder ignores it.
      vn_norm: the VN-Transformer's normalisation (:func:`~jmeshtex.ops.vn_transformer_block`):
        ``"element"`` (each feature by its own magnitude; the shipped models') or ``"channel"``
        (each channel by its mean square over all vertices and samples, the reference's).
      attention_linear: add the reference's parallel linear path to each attention
        (``MHA(x) + x W``; False: the shipped models' attention alone).
      kl_warmup_steps: the KL weight ramps linearly from ``λ / kl_warmup_steps`` to ``λ`` over
        these steps (0: ``λ`` from the start, the shipped models' recipe).
      free_bits: per-channel KL floor in nats: a channel whose batch-mean KL is below it adds
        ``free_bits`` to the loss and gets no KL gradient (Kingma et al. 2016; 0: off, the shipped
        models' recipe).
      log_sigma_init: the initial ``log σ`` of the encoder (its bias; -2: the shipped models',
        a posterior far narrower than the prior, KL ≈ 3 nats per channel at the start; 0: the
        reference's zero-initialised log-variance head, the prior's width).
      boundary_in_loss: False drops the one-rings of boundary vertices (half-rings, never met on
        closed meshes) from the reconstruction and KL terms (True: the shipped models' recipe).

    Example:
      >>> Config().replace(vn_norm="channel").experimental.vn_norm
      'channel'
    """

    token: str = "centre"
    log_objective: str = "blended"
    vn_norm: str = "element"
    attention_linear: bool = False
    kl_warmup_steps: int = 0
    free_bits: float = 0.0
    boundary_in_loss: bool = True
    log_sigma_init: float = -2.0

    _MESSAGE = "{name} must be {must}, got {value!r}"
    _RULES = (
        rule("token", lambda x: x in TOKENS, f"one of {TOKENS}"),
        rule("log_objective", lambda x: x in LOG_OBJECTIVES, f"one of {LOG_OBJECTIVES}"),
        rule("vn_norm", lambda x: x in VN_NORMS, f"one of {VN_NORMS}"),
        rule("kl_warmup_steps", lambda x: x >= 0, ">= 0 (0: no KL warm-up)"),
        rule("free_bits", lambda x: x >= 0, ">= 0 nats per channel (0: off)"),
    )


#: ``repr`` flat (:class:`~jmeshtex._config.ConfigBase`): the FLDM copies' cache names the encoder by it
@dataclasses.dataclass(frozen=True, repr=False)
class Config(ConfigBase):
    """Every hyper-parameter of the FL-VAE, its one-ring sampling and its planar pre-training.

    Model (paper §4, eq. 21–28):

    Attributes:
      latent_dim: ``d``, complex latent channels per vertex (paper: 8).
      num_samples: ``S``, area-uniform samples per one-ring (paper: 64).
      features: width ``C`` of the encoder's real sample MLP and complex set features.
      num_heads: attention heads of each VN-Transformer block (``features`` divisible by it).
      num_blocks: VN-Transformer blocks over {samples, token}.
      decoder_features: width of the decoder MLP.
      decoder_layers: dense layers of the decoder MLP, SiLU between them (paper: 5).
      decoder: ``"log"`` (the paper's FL-VAE: invariants plus ``log_p(q)·conj(z)``, eq. 18) or
        ``"barycentric"`` (the "FL-VAE (Bary.)" ablation: invariants interpolated across the triangle,
        no log coordinates).
      kl_weight: ``λ`` of the KL term (paper: 0.01).
      loss_normalization: ``"paper"`` (eq. 26–28 as printed: the L1 norm over RGB and the KL summed
        over the ``d`` channels, each averaged over samples / vertices) or ``"mean"`` (L1 and KL
        also averaged over RGB and channels, which weakens ``λ`` by ``3/d``: the recipe of the shipped
        model, kept as the default so its stored config reads as trained). The presets use ``"paper"``.
      log_sigma_max: upper clip of ``log σ`` (keeps ``exp`` finite early in training).
      delta: ``δ > 0`` of the layer norms and vector-neuron layers.
      experimental: the study switches beyond the shipped recipe and the paper
        (:class:`~jmeshtex.fl.core.Experimental`: the token, the log decoder's objective, the
        VN norm, the attention's linear path, KL warm-up and free bits, the initial ``log σ``,
        boundary rings in the loss); each may also be given by its own name to ``replace``,
        ``from_dict`` and the presets, and a model file stores them among the fields above.

    Planar pre-training (supplement §9.1). Two data modes: with ``pixels_per_vertex = 0`` (the
    shipped model's) a fixed pool of ``meshes_per_image`` meshes of ``min_vertices``–``max_vertices``
    vertices over each whole image; with ``pixels_per_vertex > 0`` (the presets) a fresh
    ``texture_size²`` texture per mesh and step (:func:`~jmeshtex.fl.core.training_texture`: augmented
    image crops and procedural textures) meshed at that density (:func:`~jmeshtex.fl.core.density_mesh`).

    Attributes:
      min_vertices, max_vertices: pool mode: range of the random resolution of each planar training
        mesh (farthest-point samples over the image, then Delaunay).
      max_image_size: images are downscaled (by an integer stride) so their longer side is at most this.
      meshes_per_image: pool mode: planar meshes drawn per image into the training pool.
      pixels_per_vertex: stream mode when > 0: texture pixels per mesh vertex (paper ≈ 26: 10K
        vertices over 512²; Spot at 30K vertices ≈ 15–20 texels per vertex).
      density_spread: stream mode: each mesh's pixels per vertex is ``pixels_per_vertex`` times a
        log-uniform factor in ``[1/density_spread, density_spread]`` (1: exactly the given density).
      texture_size: stream mode: side in pixels of each training texture.
      procedural_fraction: stream mode: share of procedural textures (the rest are image crops).
      extra_images: stream mode with the default images: also crop matplotlib's bundled sample
        images (:func:`~jmeshtex.fl.core.matplotlib_images`: 5 more; False: scikit-image's only,
        the shipped models' data).
      batch_size: planar meshes per optimiser step (their vertices are concatenated).
      steps: optimiser steps.
      learning_rate: peak Adam learning rate (cosine decay to ``learning_rate · final_lr_fraction``).
      final_lr_fraction: the cosine schedule's floor.
      warmup_steps: linear warm-up steps.
      grad_clip: global gradient-norm clip.
      ema_decay: decay of an exponential moving average of the weights
        (:func:`jmeshtex.optim.ema_update`) kept during training and returned as the model; 0: the
        trained weights themselves. At a peak learning rate the weights' held-out quality swings by
        several dB from one checkpoint to the next (a global colour shift); the average does not.
      checkpoint_every: steps between checkpoints.
      encode_chunk: vertices per jitted encoder call in :func:`~jmeshtex.fl.encode`.

    Randomness (initialisation, training meshes, one-ring samples) comes from the ``key`` given to
    :func:`~jmeshtex.fl.train` and the task functions, never from the config.

    Example:
      >>> c = Config()
      >>> c.latent_dim, c.num_samples, c.decoder_layers, c.kl_weight
      (8, 64, 5, 0.01)
      >>> Config.from_dict(c.to_dict()) == c
      True
    """

    latent_dim: int = 8
    num_samples: int = 64
    features: int = 32
    num_heads: int = 4
    num_blocks: int = 2
    decoder_features: int = 64
    decoder_layers: int = 5
    decoder: str = "log"
    kl_weight: float = 0.01
    loss_normalization: str = "mean"
    log_sigma_max: float = 2.0
    delta: float = 1e-6
    experimental: Experimental = Experimental()
    # planar pre-training
    min_vertices: int = 64
    max_vertices: int = 192
    max_image_size: int = 256
    meshes_per_image: int = 8
    pixels_per_vertex: float = 0.0
    density_spread: float = 1.0
    texture_size: int = 64
    procedural_fraction: float = 0.5
    extra_images: bool = False
    batch_size: int = 2
    steps: int = 2000
    learning_rate: float = 2e-3
    final_lr_fraction: float = 0.05
    warmup_steps: int = 50
    grad_clip: float = 1.0
    ema_decay: float = 0.0
    checkpoint_every: int = 250
    encode_chunk: int = 2048

    _MESSAGE = "{name} must be {must}, got {value!r}"
    #: what a resumed run may change: the schedule follows ``steps``; ``checkpoint_every`` only
    #: says how often state is written
    _RESUMABLE = frozenset({"steps", "checkpoint_every"})
    _RULES = (
        rule("latent_dim num_samples", lambda x: int(x) >= 1, ">= 1"),
        cross_rule(
            lambda c: int(c.features) >= 1 and int(c.num_heads) >= 1,
            "features and num_heads must be >= 1",
        ),
        cross_rule(
            lambda c: c.features % c.num_heads == 0,
            "features ({c.features}) must be divisible by num_heads ({c.num_heads})",
        ),
        rule("num_blocks", lambda x: int(x) >= 0, ">= 0"),
        rule("decoder_layers", lambda x: int(x) >= 2, ">= 2"),
        rule("decoder_features", lambda x: int(x) >= 1, ">= 1"),
        rule("decoder", lambda x: x in DECODERS, f"one of {DECODERS}"),
        rule("kl_weight", lambda x: x >= 0, ">= 0"),
        rule("ema_decay", lambda x: 0 <= x < 1, "in [0, 1) (0: no weight average)"),
        cross_rule(
            lambda c: -20 <= c.experimental.log_sigma_init <= c.log_sigma_max,
            "need -20 <= log_sigma_init <= log_sigma_max, got {c.experimental.log_sigma_init}, "
            "{c.log_sigma_max}",
        ),
        rule(
            "loss_normalization",
            lambda x: x in LOSS_NORMALIZATIONS,
            f"one of {LOSS_NORMALIZATIONS}",
        ),
        rule("pixels_per_vertex", lambda x: x >= 0, ">= 0 (0: the image-pool data mode)"),
        rule("density_spread", lambda x: x >= 1, ">= 1"),
        rule("texture_size", lambda x: x >= 8, ">= 8"),
        rule("procedural_fraction", lambda x: 0 <= x <= 1, "in [0, 1]"),
        rule("delta", lambda x: x > 0, "> 0"),
        cross_rule(
            lambda c: 3 <= c.min_vertices <= c.max_vertices,
            "need 3 <= min_vertices <= max_vertices, got {c.min_vertices}, {c.max_vertices}",
        ),
        rule("max_image_size", lambda x: x >= 8, ">= 8"),
        rule("meshes_per_image batch_size", lambda x: x >= 1, ">= 1"),
        rule("steps", lambda x: x >= 0, ">= 0"),
        cross_rule(
            lambda c: c.learning_rate > 0 and 0 <= c.final_lr_fraction <= 1,
            "need learning_rate > 0 and final_lr_fraction in [0, 1], got {c.learning_rate}, "
            "{c.final_lr_fraction}",
        ),
        cross_rule(
            lambda c: c.warmup_steps >= 0 and c.grad_clip > 0,
            "need warmup_steps >= 0 and grad_clip > 0",
        ),
        rule("checkpoint_every encode_chunk", lambda x: x >= 1, ">= 1"),
    )

    @classmethod
    def paper(cls, **changes) -> Config:
        """The paper's model size (§4, supplement §8.1): ``C = 128``, 8 VN-Transformer layers × 8 heads,
        decoder 5 × 512, trained with eq. 26–28 as printed at ≈ 26 pixels per vertex, cosine 1e-3 → 1e-5.

        Sized for an accelerator (a CPU step takes seconds); 256² textures (≈ 2.5K vertices each)
        instead of the paper's 512² (10K), same density. The paper trains 1.5M iterations.

        Example:
          >>> c = Config.paper()
          >>> c.features, c.num_blocks, c.num_heads, c.decoder_features, c.decoder_layers
          (128, 8, 8, 512, 5)
        """
        base = dict(
            features=128,
            num_heads=8,
            num_blocks=8,
            decoder_features=512,
            decoder_layers=5,
            loss_normalization="paper",
            pixels_per_vertex=26.0,
            density_spread=1.5,
            texture_size=256,
            max_image_size=512,
            batch_size=4,
            steps=200_000,
            learning_rate=1e-3,
            final_lr_fraction=0.01,
            warmup_steps=1000,
            checkpoint_every=1000,
        )
        return cls.from_dict({**base, **changes})

    @classmethod
    def small(cls, **changes) -> Config:
        """A preset that trains on two CPU cores: ``C = 32``, 2 VN-Transformer layers × 4 heads, decoder
        5 × 128, 32 samples per one-ring (the paper: 64; halves the encoder's cost), the paper's loss
        and data density (64² textures, ≈ 158 vertices each), cosine 1e-3 → 1e-5 over 20K steps,
        a weight EMA (0.999) and ``kl_weight = 1e-3`` (the paper: 0.01), both beyond the paper,
        whose training script is not public. At λ = 0.01 the log model's KL collapses onto half of
        the channels and its barycentric ablation leads; at 1e-3 every channel stays alive and the
        log model leads on held-out photographs (``docs/results.md``).

        Example:
          >>> c = Config.small()
          >>> c.features, c.num_blocks, c.decoder_features, c.pixels_per_vertex, c.loss_normalization
          (32, 2, 128, 26.0, 'paper')
        """
        cpu_size = dict(  # the paper's recipe (loss, data density, schedule) at CPU size
            features=32,
            num_heads=4,
            num_blocks=2,
            decoder_features=128,
            num_samples=32,
            texture_size=64,
            batch_size=2,
            steps=20_000,
            warmup_steps=500,
            ema_decay=0.999,
            kl_weight=1e-3,
            checkpoint_every=250,
        )
        return cls.paper(**{**cpu_size, **changes})

    def architecture(self) -> Config:
        """The same network with every data/training field at its default: a cache key for jitted
        encoders and decoders (configs that differ only in training settings compile once).

        Example:
          >>> Config(steps=7, learning_rate=0.1).architecture() == Config()
          True
        """
        defaults = Config().to_dict()
        return self.replace(**{name: defaults[name] for name in _TRAINING_FIELDS})

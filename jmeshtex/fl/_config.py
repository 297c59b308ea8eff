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


#: fields that do not change the model's function (data, optimiser, batching, chunking)
_TRAINING_FIELDS = ("num_samples", "kl_weight", "min_vertices", "max_vertices", "max_image_size", "meshes_per_image",
                    "batch_size", "steps", "learning_rate", "final_lr_fraction", "warmup_steps", "grad_clip",
                    "checkpoint_every", "encode_chunk")


@dataclasses.dataclass(frozen=True)
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
      log_sigma_max: upper clip of ``log σ`` (keeps ``exp`` finite early in training).
      delta: ``δ > 0`` of the layer norms and vector-neuron layers.

    Planar pre-training (supplement §9.1):

    Attributes:
      min_vertices, max_vertices: range of the random resolution of each planar training mesh
        (farthest-point samples over the image, then Delaunay).
      max_image_size: images are downscaled (by an integer stride) so their longer side is at most this.
      meshes_per_image: planar meshes drawn per image into the training pool.
      batch_size: planar meshes per optimiser step (their vertices are concatenated).
      steps: optimiser steps.
      learning_rate: peak Adam learning rate (cosine decay to ``learning_rate · final_lr_fraction``).
      final_lr_fraction: the cosine schedule's floor.
      warmup_steps: linear warm-up steps.
      grad_clip: global gradient-norm clip.
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
    log_sigma_max: float = 2.0
    delta: float = 1e-6
    # planar pre-training
    min_vertices: int = 64
    max_vertices: int = 192
    max_image_size: int = 256
    meshes_per_image: int = 8
    batch_size: int = 2
    steps: int = 2000
    learning_rate: float = 2e-3
    final_lr_fraction: float = 0.05
    warmup_steps: int = 50
    grad_clip: float = 1.0
    checkpoint_every: int = 250
    encode_chunk: int = 2048

    _MESSAGE = "{name} must be {must}, got {value}"
    _RULES = (
        rule("latent_dim num_samples", lambda x: int(x) >= 1, ">= 1"),
        cross_rule(lambda c: int(c.features) >= 1 and int(c.num_heads) >= 1, "features and num_heads must be >= 1"),
        cross_rule(lambda c: c.features % c.num_heads == 0,
                   "features ({c.features}) must be divisible by num_heads ({c.num_heads})"),
        rule("num_blocks", lambda x: int(x) >= 0, ">= 0"),
        rule("decoder_layers", lambda x: int(x) >= 2, ">= 2"),
        rule("decoder_features", lambda x: int(x) >= 1, ">= 1"),
        rule("decoder", lambda x: x in DECODERS, f"one of {DECODERS}", message="{name} must be {must}, got {value!r}"),
        rule("kl_weight", lambda x: x >= 0, ">= 0"),
        rule("delta", lambda x: x > 0, "> 0"),
        cross_rule(lambda c: 3 <= c.min_vertices <= c.max_vertices,
                   "need 3 <= min_vertices <= max_vertices, got {c.min_vertices}, {c.max_vertices}"),
        rule("max_image_size", lambda x: x >= 8, ">= 8"),
        rule("meshes_per_image batch_size", lambda x: x >= 1, ">= 1"),
        rule("steps", lambda x: x >= 0, ">= 0"),
        cross_rule(lambda c: c.learning_rate > 0 and 0 <= c.final_lr_fraction <= 1,
                   "need learning_rate > 0 and final_lr_fraction in [0, 1], got {c.learning_rate}, "
                   "{c.final_lr_fraction}"),
        cross_rule(lambda c: c.warmup_steps >= 0 and c.grad_clip > 0, "need warmup_steps >= 0 and grad_clip > 0"),
        rule("checkpoint_every encode_chunk", lambda x: x >= 1, ">= 1"),
    )

    def architecture(self) -> Config:
        """The same network with every data/training field at its default: a cache key for jitted
        encoders and decoders (configs that differ only in training settings compile once).

        Example:
          >>> Config(steps=7, learning_rate=0.1).architecture() == Config()
          True
        """
        defaults = Config()
        return self.replace(**{name: getattr(defaults, name) for name in _TRAINING_FIELDS})

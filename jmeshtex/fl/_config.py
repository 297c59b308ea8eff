"""Configuration of the FL-VAE (Mitchel, Esteves, Makadia, CVPR 2024, §4, supplement §8–9.1).

One frozen, JSON round-trippable dataclass holds every choice of the model, of the one-ring sampling
and of planar pre-training. Defaults follow the paper where it gives a number (``d = 8`` complex
latent channels, 64 one-ring samples, a 5-layer SiLU decoder, ``λ_KL = 0.01``); the widths and depths
the paper leaves open are chosen small enough to train on two CPU cores.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from .._errors import ConfigError

#: decoder variants: the paper's log-coordinate neural field and its barycentric ablation (Table 1)
DECODERS = ("log", "barycentric")


#: fields that do not change the model's function (data, optimiser, batching, chunking)
_TRAINING_FIELDS = ("num_samples", "kl_weight", "min_vertices", "max_vertices", "max_image_size", "meshes_per_image",
                    "batch_meshes", "steps", "lr", "final_lr_fraction", "warmup_steps", "grad_clip",
                    "checkpoint_every", "encode_chunk", "seed")


def _check(cond: bool, message: str) -> None:
    if not cond:
        raise ConfigError(message)


@dataclasses.dataclass(frozen=True)
class FLVAEConfig:
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
      batch_meshes: planar meshes per optimiser step (their vertices are concatenated).
      steps: optimiser steps.
      lr: peak Adam learning rate (cosine decay to ``lr · final_lr_fraction``).
      final_lr_fraction: the cosine schedule's floor.
      warmup_steps: linear warm-up steps.
      grad_clip: global gradient-norm clip.
      checkpoint_every: steps between checkpoints.
      encode_chunk: vertices per jitted encoder call in :func:`~jmeshtex.fl.encode_mesh`.
      seed: PRNG seed of initialisation, meshes and samples.

    Example:
      >>> c = FLVAEConfig()
      >>> c.latent_dim, c.num_samples, c.decoder_layers, c.kl_weight
      (8, 64, 5, 0.01)
      >>> FLVAEConfig.from_dict(c.to_dict()) == c
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
    batch_meshes: int = 2
    steps: int = 2000
    lr: float = 2e-3
    final_lr_fraction: float = 0.05
    warmup_steps: int = 50
    grad_clip: float = 1.0
    checkpoint_every: int = 250
    encode_chunk: int = 2048
    seed: int = 0

    def __post_init__(self):
        _check(int(self.latent_dim) >= 1, f"latent_dim must be >= 1, got {self.latent_dim}")
        _check(int(self.num_samples) >= 1, f"num_samples must be >= 1, got {self.num_samples}")
        _check(int(self.features) >= 1 and int(self.num_heads) >= 1, "features and num_heads must be >= 1")
        _check(self.features % self.num_heads == 0,
               f"features ({self.features}) must be divisible by num_heads ({self.num_heads})")
        _check(int(self.num_blocks) >= 0, f"num_blocks must be >= 0, got {self.num_blocks}")
        _check(int(self.decoder_layers) >= 2, f"decoder_layers must be >= 2, got {self.decoder_layers}")
        _check(int(self.decoder_features) >= 1, f"decoder_features must be >= 1, got {self.decoder_features}")
        _check(self.decoder in DECODERS, f"decoder must be one of {DECODERS}, got {self.decoder!r}")
        _check(self.kl_weight >= 0, f"kl_weight must be >= 0, got {self.kl_weight}")
        _check(self.delta > 0, f"delta must be > 0, got {self.delta}")
        _check(3 <= self.min_vertices <= self.max_vertices,
               f"need 3 <= min_vertices <= max_vertices, got {self.min_vertices}, {self.max_vertices}")
        _check(self.max_image_size >= 8, f"max_image_size must be >= 8, got {self.max_image_size}")
        _check(self.meshes_per_image >= 1, f"meshes_per_image must be >= 1, got {self.meshes_per_image}")
        _check(self.batch_meshes >= 1, f"batch_meshes must be >= 1, got {self.batch_meshes}")
        _check(self.steps >= 0, f"steps must be >= 0, got {self.steps}")
        _check(self.lr > 0 and 0 <= self.final_lr_fraction <= 1,
               f"need lr > 0 and final_lr_fraction in [0, 1], got {self.lr}, {self.final_lr_fraction}")
        _check(self.warmup_steps >= 0 and self.grad_clip > 0, "need warmup_steps >= 0 and grad_clip > 0")
        _check(self.checkpoint_every >= 1, f"checkpoint_every must be >= 1, got {self.checkpoint_every}")
        _check(self.encode_chunk >= 1, f"encode_chunk must be >= 1, got {self.encode_chunk}")

    def to_dict(self) -> dict[str, Any]:
        """The fields as a JSON-compatible dict."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FLVAEConfig:
        """Rebuild from :meth:`to_dict` output; unknown keys raise :class:`~jmeshtex.ConfigError`."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ConfigError(f"FLVAEConfig: unknown fields {unknown}; known: {sorted(names)}")
        return cls(**data)

    def model(self) -> FLVAEConfig:
        """The same model with every data/training field at its default: a cache key for jitted
        encoders and decoders (configs that differ only in training settings compile once).

        Example:
          >>> FLVAEConfig(steps=7, lr=0.1).model() == FLVAEConfig()
          True
        """
        defaults = FLVAEConfig()
        return self.replace(**{name: getattr(defaults, name) for name in _TRAINING_FIELDS})

    def replace(self, **changes) -> FLVAEConfig:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

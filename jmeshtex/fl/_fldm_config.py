"""Configuration of Field Latent Diffusion (Mitchel, Esteves, Makadia, CVPR 2024, §5–6, supp. §8.2).

One frozen, JSON round-trippable dataclass :class:`FLDMConfig` holds the denoiser's architecture, the
diffusion schedule, the training data (re-triangulated copies) and the optimiser. Presets:

- :meth:`FLDMConfig.paper`: the paper's denoiser (96 / 192 channels, 2 + 4 + 4 FCResNet blocks),
  500 copies of ~30K vertices, linear schedule, T = 1000;
- :meth:`FLDMConfig.cpu`: a CPU-sized denoiser (32 / 64 channels, 1 + 2 + 2 blocks);
- :meth:`FLDMConfig.tiny`: tests, demos and notebooks (16 / 32 channels, 1 + 1 + 1 blocks, few copies).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from .._errors import ConfigError
from ._diffusion import SCHEDULES


def _check(cond: bool, message: str) -> None:
    if not cond:
        raise ConfigError(message)


@dataclasses.dataclass(frozen=True)
class FLDMConfig:
    """Every choice of an FLDM run.

    Attributes:
      latent_channels: ``d``, complex latent channels per vertex (the FL-VAE's).
      widths: channels at the fine and the coarse level of the U-Net (paper: 96, 192).
      blocks: FCResNet blocks ``(down, middle, up)`` (paper: 2, 4, 4).
      hdim: filter responses per input channel of each field convolution.
      knn: neighbourhood size of the field convolutions (slots including the vertex itself).
      activation: filter nonlinearity, ``"silu"`` (paper) or ``"relu"`` (faster on CPU).
      time_features: width of the sinusoidal timestep embedding.
      num_labels: label classes for label-guided generation (0: unconditional).
      schedule: ``"linear"`` or ``"cosine"``.
      num_train_steps: diffusion steps ``T``.
      learning_rate: Adam learning rate.
      batch_size: mesh copies per step (split over devices).
      train_steps: optimiser steps of :func:`train_fldm`.
      checkpoint_every: steps between checkpoints.
      n_copies: re-triangulated copies of the input mesh.
      copy_vertices: vertices per copy (0: the input's count).
      pool_ratio: coarse / fine vertex ratio of the U-Net's one downsampling.
      bucket: vertex counts are padded up to a multiple of this (limits recompiles).
      seed: seed of copies, initialisation and training noise.
    """

    latent_channels: int = 4
    widths: tuple[int, int] = (96, 192)
    blocks: tuple[int, int, int] = (2, 4, 4)
    hdim: int = 16
    knn: int = 9
    activation: str = "silu"
    time_features: int = 32
    num_labels: int = 0
    schedule: str = "linear"
    num_train_steps: int = 1000
    learning_rate: float = 2e-4
    batch_size: int = 4
    train_steps: int = 20000
    checkpoint_every: int = 500
    n_copies: int = 500
    copy_vertices: int = 30000
    pool_ratio: float = 0.25
    bucket: int = 256
    seed: int = 0

    def __post_init__(self):
        def pos_int(name, v):
            _check(isinstance(v, int) and not isinstance(v, bool) and v >= 1, f"{name} must be a positive integer, got {v!r}")

        for name in ("latent_channels", "hdim", "knn", "time_features", "num_train_steps", "batch_size",
                     "train_steps", "checkpoint_every", "n_copies", "bucket"):
            pos_int(name, getattr(self, name))
        _check(len(self.widths) == 2 and all(isinstance(w, int) and w >= 1 for w in self.widths),
               f"widths must be two positive integers (fine, coarse), got {self.widths!r}")
        _check(len(self.blocks) == 3 and all(isinstance(b, int) and b >= 1 for b in self.blocks),
               f"blocks must be three positive integers (down, middle, up), got {self.blocks!r}")
        _check(self.activation in ("silu", "relu"), f"activation must be 'silu' or 'relu', got {self.activation!r}")
        _check(self.schedule in SCHEDULES, f"schedule must be one of {SCHEDULES}, got {self.schedule!r}")
        _check(isinstance(self.num_labels, int) and self.num_labels >= 0, f"num_labels must be >= 0, got {self.num_labels!r}")
        _check(isinstance(self.copy_vertices, int) and (self.copy_vertices == 0 or self.copy_vertices >= 16),
               f"copy_vertices must be 0 (keep the input's count) or >= 16, got {self.copy_vertices!r}")
        _check(0.05 <= self.pool_ratio <= 0.75, f"pool_ratio must be in [0.05, 0.75], got {self.pool_ratio!r}")
        _check(self.learning_rate > 0, f"learning_rate must be > 0, got {self.learning_rate!r}")
        _check(self.num_train_steps >= 2, "num_train_steps must be >= 2")

    @classmethod
    def paper(cls, **changes) -> FLDMConfig:
        """The paper's denoiser and data (96/192 channels, 2+4+4 blocks, 500 copies of 30K vertices).

        Example:
          >>> FLDMConfig.paper().widths, FLDMConfig.paper().blocks
          ((96, 192), (2, 4, 4))
        """
        return cls(**changes)

    @classmethod
    def cpu(cls, **changes) -> FLDMConfig:
        """A CPU preset: 32/64 channels, 1+2+2 blocks, ReLU filters, 32 copies of 5K vertices."""
        base = dict(widths=(32, 64), blocks=(1, 2, 2), hdim=8, activation="relu", n_copies=32,
                    copy_vertices=5000, train_steps=3000, batch_size=2, learning_rate=1e-3)
        return cls(**{**base, **changes})

    @classmethod
    def tiny(cls, **changes) -> FLDMConfig:
        """Tests, demos and notebooks: 16/32 channels, 1+1+1 blocks, 4 copies of 400 vertices.

        Example:
          >>> c = FLDMConfig.tiny(latent_channels=2)
          >>> c.widths, c.n_copies, c.latent_channels
          ((16, 32), 4, 2)
        """
        base = dict(widths=(16, 32), blocks=(1, 1, 1), hdim=4, knn=7, activation="relu", time_features=16,
                    n_copies=4, copy_vertices=400, train_steps=200, batch_size=2, learning_rate=3e-3,
                    checkpoint_every=100, bucket=64)
        return cls(**{**base, **changes})

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible dict (tuples become lists)."""
        return {f.name: list(v) if isinstance(v := getattr(self, f.name), tuple) else v for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FLDMConfig:
        """Inverse of :meth:`to_dict`; unknown keys raise :class:`ConfigError`.

        Example:
          >>> c = FLDMConfig.tiny()
          >>> FLDMConfig.from_dict(c.to_dict()) == c
          True
        """
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ConfigError(f"FLDMConfig: unknown fields {unknown}; known: {sorted(names)}")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})

    def replace(self, **changes) -> FLDMConfig:
        """A validated copy with some fields changed."""
        return dataclasses.replace(self, **changes)

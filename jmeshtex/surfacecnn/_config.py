"""Hyper-parameters of surface-aware texture synthesis (Kovács, Hermosilla & Raidou, CGF 2024)."""

from __future__ import annotations

import dataclasses

from .._config import ConfigBase, cross_rule, integers, is_finite_number, rule

BOUNDARY_MODES = ("zero", "clamp")
POOL_MODES = ("mean", "max")


@dataclasses.dataclass(frozen=True)
class Config(ConfigBase):
    """Settings of the precomputation and the Gram-matching optimisation.

    The defaults are the paper's (and its reference tool's): Adam with learning rate 0.1, halved
    every 200 steps, 500 steps, colours clipped to [0, 1] after every step, initial texel colours
    uniform in [0, 0.2], average pooling, the Gram matrices of every ReLU and pooling output.

    Attributes:
      size: texture resolution (``size × size`` texels).
      steps: optimisation steps.
      learning_rate: Adam's initial learning rate.
      halve_every: the learning rate is halved after every this many steps (200 → halved at 200
        and 400).
      init_low, init_high: range of the uniform initial colours (synthesis).
      pool: ``"mean"`` (the paper's average pooling) or ``"max"`` (VGG's own).
      boundary: what a tap whose geodesic walk hits a mesh boundary reads: ``"zero"`` (zero
        padding, like a 2D CNN at the image border) or ``"clamp"`` (the texel where the walk
        stopped).
      layers: names of the feature maps whose Gram matrices are matched (``"relu1_1"``, ...,
        ``"pool1"``, ...), or None for every ReLU and pooling output of the network.
      content_layer: the feature map of the content term (style transfer).
      content_weight: weight of the content term against the (layer-averaged) style term.
      dtype: ``"float32"`` (default) or ``"float64"`` for the network and the optimisation.

    Example:
      >>> c = Config(size=64, steps=10)
      >>> c.learning_rate_at(0), c.learning_rate_at(450)
      (0.1, 0.025)
    """

    size: int = 512
    steps: int = 500
    learning_rate: float = 0.1
    halve_every: int = 200
    init_low: float = 0.0
    init_high: float = 0.2
    pool: str = "mean"
    boundary: str = "zero"
    layers: tuple[str, ...] | None = None
    content_layer: str = "relu4_2"
    content_weight: float = 1.0
    dtype: str = "float32"

    _RULES = (
        integers("size", 4),
        integers("steps", 0),
        integers("halve_every", 1),
        rule("learning_rate content_weight init_low init_high", lambda x: is_finite_number(x) and x >= 0,
             "a finite number >= 0"),
        rule("learning_rate", lambda x: x > 0, "> 0"),
        cross_rule(lambda c: 0.0 <= c.init_low <= c.init_high <= 1.0,
                   "{cls} needs 0 <= init_low <= init_high <= 1, got {c.init_low}, {c.init_high}"),
        rule("pool", lambda x: x in POOL_MODES, f"one of {POOL_MODES}"),
        rule("boundary", lambda x: x in BOUNDARY_MODES, f"one of {BOUNDARY_MODES}"),
        rule("layers", lambda x: x is None or (isinstance(x, tuple) and len(x) > 0 and all(isinstance(n, str) for n in x)),
             "None or a non-empty tuple of names"),
        rule("dtype", lambda x: x in ("float32", "float64"), "'float32' or 'float64'"),
    )

    def learning_rate_at(self, step: int) -> float:
        """The learning rate of (0-based) step ``step``: halved after every ``halve_every`` steps."""
        return float(self.learning_rate * 0.5 ** (step // self.halve_every))

"""Hyper-parameters of surface-aware texture synthesis (Kovács, Hermosilla & Raidou, CGF 2024)."""

from __future__ import annotations

import dataclasses

from .._config import ConfigBase, cross_rule, integers, is_finite_number, rule
from ..metrics import VGG19_NAMES

BOUNDARY_MODES = ("opposite", "zero", "clamp")
FRAME_MODES = ("global", "smooth", "uv")
EXEMPLAR_PADDING = ("centre", "zero")
POOL_MODES = ("mean", "max")
#: radius (texels) over which the ``"global"`` frames turn at a crease (``Config.frame_smoothing``):
#: chosen on the fandisk's creases, numbers in ``docs/results.md``
FRAME_SMOOTHING = 4.0
#: every feature map a VGG-16 or VGG-19 has: ``conv<b>_<i>``, ``relu<b>_<i>``, ``pool<b>``
LAYER_NAMES = frozenset(
    [
        *VGG19_NAMES,
        *(n.replace("conv", "relu") for n in VGG19_NAMES),
        *(f"pool{b}" for b in range(1, 6)),
    ]
)


@dataclasses.dataclass(frozen=True)
class Config(ConfigBase):
    """Settings of the precomputation and the Gram-matching optimisation.

    The defaults are the paper's (and its reference tool's, ``texture_synthesis.py`` /
    ``style_transfer.py`` / ``src/tmscnn.rs``): Adam with learning rate 0.1, halved every 200 steps,
    500 steps, colours clipped to [0, 1] after every step, initial texel colours uniform in
    [0, 0.2], average pooling; synthesis matches the Gram matrices of every ReLU and pooling output
    (the reference's 21 ``block*_conv*``/``block*_pool`` layers), style transfer those of
    ``relu1_1 … relu5_1`` (``block{1..5}_conv1``) plus a content term at ``relu4_2``
    (``block4_conv2``) weighted 1000 for VGG-19 with Caffe preprocessing. Tangent frames follow a
    global vector projected on the surface, failed boundary walks read the opposite tap, exemplar
    taps outside the image read the centre pixel, and synthesis re-unwraps the mesh with xatlas.

    Presets: :meth:`cpu` (the defaults, 512²), :meth:`paper` (1024²), :meth:`tiny` (tests); time
    and CPU-seconds per step in ``docs/results.md``.

    Attributes:
      size: texture resolution (``size × size`` texels; 512 is the CPU preset, the paper's 1024 is
        :meth:`paper`).
      steps: optimisation steps.
      learning_rate: Adam's initial learning rate.
      halve_every: the learning rate is halved after every this many steps (200 → halved at 200
        and 400).
      init_low, init_high: range of the uniform initial colours (synthesis).
      pool: ``"mean"`` (the paper's average pooling) or ``"max"`` (VGG's own).
      boundary: what a tap whose geodesic walk hits a mesh boundary reads: ``"opposite"`` (the
        reference's rule: the opposite tap if its walk succeeded, else the centre), ``"zero"``
        (zero padding, like a 2D CNN at the image border) or ``"clamp"`` (the texel where the walk
        stopped).
      frames: tangent frames of the texels (:func:`~jmeshtex.surfacecnn.core.texture_atlas`):
        ``"global"`` (the paper's: ``frame_vector`` projected on the surface), ``"smooth"`` (the
        smoothest direction field, Knöppel et al. 2013) or ``"uv"`` (the UV layout's; jumps at
        chart seams — an ablation).
      frame_vector: the world vector of the ``"global"`` frames (reference: x, fallback y).
      frame_smoothing: radius, in texels, over which the ``"global"`` frames turn at creases
        (:func:`~jmeshtex.surfacecnn.core.texture_atlas`; default ``FRAME_SMOOTHING`` = 4, chosen
        in ``docs/results.md``); 0 is the paper's field. In the checkpoint fingerprint: a
        checkpoint written before the field existed (whose frames may have been the paper's) is
        refused rather than resumed under other frames.
      unwrap: the texture layout :func:`~jmeshtex.surfacecnn.synthesize` optimises: ``"xatlas"``
        (the reference's: every mesh is re-unwrapped, so a texel covers about the same surface
        everywhere) or ``"mesh"`` (the mesh's own UVs, whose texel density may vary a lot:
        :func:`~jmeshtex.surfacecnn.core.texel_density_spread`). A mesh without UVs is unwrapped
        either way; :func:`~jmeshtex.surfacecnn.stylize` always keeps the mesh's UVs (its content
        texture lives in them).
      exemplar_padding: what the 2D network reads for exemplar taps outside the image:
        ``"centre"`` (the reference's: the centre pixel) or ``"zero"`` (``"SAME"`` zero padding).
      layers: names of the feature maps whose Gram matrices are matched (``"relu1_1"``, ...,
        ``"pool1"``, ...), or None for the task's default (synthesis: every ReLU and pooling output;
        style transfer: the first ReLU of every block).
      content_layer: the feature map of the content term (style transfer).
      content_weight: weight of the content term against the (layer-averaged) style term, or None
        for the reference's 1000 rescaled to the network's input scale
        (:func:`~jmeshtex.surfacecnn.core.default_content_weight`: 1000 for Caffe-preprocessed VGG-19,
        ≈0.30 for the embedded torchvision VGG-16).
      network: ``"vgg16"`` (the embedded torchvision weights, always available) or ``"vgg19"``
        (the paper's; needs ``weights_path``, read by :func:`jmeshtex.metrics.load_vgg19` with Caffe
        preprocessing). A ``weights=`` argument of the task verbs overrides both.
      weights_path: the VGG-19 weights file (``.npz`` or Keras ``.h5``).
      dtype: ``"float32"`` (default) or ``"float64"`` for the network and the optimisation.
      checkpoint_every: steps between checkpoints (with the task verbs' ``checkpoint_dir``).

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
    boundary: str = "opposite"
    frames: str = "global"
    frame_vector: tuple[float, float, float] = (1.0, 0.0, 0.0)
    frame_smoothing: float = FRAME_SMOOTHING
    unwrap: str = "xatlas"
    exemplar_padding: str = "centre"
    layers: tuple[str, ...] | None = None
    content_layer: str = "relu4_2"
    content_weight: float | None = None
    network: str = "vgg16"
    weights_path: str | None = None
    dtype: str = "float32"
    checkpoint_every: int = 50

    #: what a resumed run may change: the step count and the checkpoint cadence
    _RESUMABLE = frozenset({"steps", "checkpoint_every"})
    _RULES = (
        integers("size", 4),
        integers("steps", 0),
        integers("halve_every checkpoint_every", 1),
        rule(
            "learning_rate init_low init_high",
            lambda x: is_finite_number(x) and x >= 0,
            "a finite number >= 0",
        ),
        rule(
            "content_weight",
            lambda x: x is None or (is_finite_number(x) and x >= 0),
            "None or a finite number >= 0",
        ),
        rule("learning_rate", lambda x: x > 0, "> 0"),
        rule(
            "frame_smoothing",
            lambda x: is_finite_number(x) and x >= 0,
            "a finite number of texels >= 0 (0: the paper's frames)",
        ),
        cross_rule(
            lambda c: 0.0 <= c.init_low <= c.init_high <= 1.0,
            "{cls} needs 0 <= init_low <= init_high <= 1, got {c.init_low}, {c.init_high}",
        ),
        rule("pool", lambda x: x in POOL_MODES, f"one of {POOL_MODES}"),
        rule("boundary", lambda x: x in BOUNDARY_MODES, f"one of {BOUNDARY_MODES}"),
        rule("frames", lambda x: x in FRAME_MODES, f"one of {FRAME_MODES}"),
        rule(
            "frame_vector",
            lambda x: len(x) == 3 and all(is_finite_number(a) for a in x) and any(x),
            "three finite numbers, not all zero",
        ),
        rule("unwrap", lambda x: x in ("xatlas", "mesh"), "'xatlas' or 'mesh'"),
        rule("exemplar_padding", lambda x: x in EXEMPLAR_PADDING, f"one of {EXEMPLAR_PADDING}"),
        rule("network", lambda x: x in ("vgg16", "vgg19"), "'vgg16' or 'vgg19'"),
        rule("weights_path", lambda x: x is None or isinstance(x, str), "None or a path string"),
        cross_rule(
            lambda c: c.network != "vgg19" or c.weights_path is not None,
            "{cls}(network='vgg19') needs weights_path: the paper's Keras ImageNet VGG-19 "
            "(e.g. vgg19_weights_tf_dim_ordering_tf_kernels_notop.h5, or an .npz of its arrays) "
            "cannot ship with jmeshtex; give its file, or use network='vgg16' (embedded)",
        ),
        rule(
            "layers",
            lambda x: (
                x is None
                or (isinstance(x, tuple) and len(x) > 0 and all(n in LAYER_NAMES for n in x))
            ),
            "None or a non-empty tuple of VGG layer names ('relu1_1', 'pool1', ...)",
        ),
        rule("dtype", lambda x: x in ("float32", "float64"), "'float32' or 'float64'"),
        rule("content_layer", lambda x: x in LAYER_NAMES, "a VGG layer name ('relu4_2', ...)"),
    )

    @classmethod
    def paper(cls, **changes) -> Config:
        """The paper's scale: 1024² texels, 500 steps, every ReLU and pool output (Kovács et al.
        2024, Sec. 6; pass ``network="vgg19", weights_path=...`` for its network).

        Example:
          >>> c = Config.paper()
          >>> c.size, c.steps, c.layers
          (1024, 500, None)
        """
        return cls(**{**dict(size=1024, steps=500, layers=None), **changes})

    @classmethod
    def cpu(cls, **changes) -> Config:
        """The CPU preset (the defaults): 512² texels, 500 steps, every ReLU and pool output; time
        per step in ``docs/results.md``.

        Example:
          >>> Config.cpu() == Config()
          True
        """
        return cls(**{**dict(size=512, steps=500, layers=None), **changes})

    @classmethod
    def tiny(cls, **changes) -> Config:
        """Tests and doctests: 16² texels, 3 steps, the Gram of ``relu1_1`` and ``pool1`` only.

        Example:
          >>> c = Config.tiny()
          >>> c.size, c.steps, c.layers
          (16, 3, ('relu1_1', 'pool1'))
        """
        return cls(**{**dict(size=16, steps=3, layers=("relu1_1", "pool1")), **changes})

    def learning_rate_at(self, step: int) -> float:
        """The learning rate of (0-based) step ``step``: halved after every ``halve_every`` steps."""
        return float(self.learning_rate * 0.5 ** (step // self.halve_every))

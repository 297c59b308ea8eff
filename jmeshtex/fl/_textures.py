"""Training textures and planar meshes at a chosen pixel density (paper supplement §9.1).

The paper pre-trains the FL-VAE on 10K-vertex planar meshes over 512² images, about 26 pixels per
vertex, "deliberately coarser than at inference"; the meshes met at inference (Spot remeshed to 30K
vertices over its 1024² atlas) have about 15–20 texels per vertex. This module makes that data on
the fly, every texture a pure function of a key:

- :func:`training_texture`: with probability ``procedural_fraction`` a :func:`procedural_texture`
  (fractal noise, stripes, Voronoi cells, checkers, linear/radial gradients — in saturated colours),
  else an :func:`augmented_crop` of one of the training images (random scale, rotation, flip, colour
  jitter). Every key gives a different texture, so a run of ``T`` steps over ``B`` meshes sees
  ``T·B`` distinct textures.
- :func:`density_mesh`: a :func:`~jmeshtex.fl.core.planar_mesh` over a texture with
  ``round(H·W / pixels_per_vertex)`` vertices, so the texels per one-ring match the target's.

The scikit-image images split into ``TRAINING_IMAGES`` and ``HELD_OUT_IMAGES`` (three
natural colour photographs, never used by :func:`training_images` and so never trained on by
:func:`~jmeshtex.fl.train` with its default images): the held-out reconstruction of
the FL-VAE benchmark (``docs/results.md``) separates under-training from domain shift.
"""

from __future__ import annotations

import jax
import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from .._errors import InputError
from .._mesh import Mesh
from .._random import check_key, host_rng
from .._types import Float
from ._planar import BUILTIN_IMAGES, _to_rgb01, builtin_images, downscale, planar_mesh

#: scikit-image images never used for training (natural colour photographs; ``cat`` is ``chelsea``)
HELD_OUT_IMAGES = ("chelsea", "coffee", "rocket")
#: scikit-image images (bundled in its wheel) that training textures are cut from: the built-in
#: images less the held-out photographs, plus five grey ones (cells, a clock, a logo, text)
TRAINING_IMAGES = tuple(
    sorted(set(BUILTIN_IMAGES) - set(HELD_OUT_IMAGES) | {"cell", "clock", "logo", "page", "text"})
)
#: matplotlib's bundled sample data used as extra training images (``Config.extra_images``): a
#: photograph, a logo, two elevation maps and an MRI slice (grey ones as grey images)
MATPLOTLIB_IMAGES = (
    "Minduka_Present_Blue_Pack.png",
    "logo2.png",
    "jacksboro_fault_dem.npz",
    "topobathy.npz",
    "s1045.ima.gz",
)
#: matplotlib sample images never used for training (``grace_hopper.jpg``: a held-out texture of
#: the FL-VAE's evaluation on Spot)
HELD_OUT_MATPLOTLIB_IMAGES = ("grace_hopper.jpg",)
#: kinds of :func:`procedural_texture`
PROCEDURAL_KINDS = ("noise", "stripes", "cells", "checker", "gradient")


def training_images(*, max_size: int = 512, extra: bool = False) -> list[np.ndarray]:
    """``TRAINING_IMAGES`` as ``[H, W, 3]`` RGB in [0, 1], box-downscaled to ``max_size`` (no held-out image).

    Args:
      max_size: longest side in pixels.
      extra: also :func:`~jmeshtex.fl.core.matplotlib_images` (``MATPLOTLIB_IMAGES``, after the scikit-image ones).

    Example:
      >>> imgs = training_images(max_size=64)
      >>> len(imgs) == len(TRAINING_IMAGES), max(max(im.shape[:2]) for im in imgs) <= 64
      (True, True)
    """
    out = builtin_images(max_size=max_size, names=TRAINING_IMAGES)
    return out + matplotlib_images(max_size=max_size) if extra else out


def matplotlib_images(*, max_size: int = 512) -> list[np.ndarray]:
    """matplotlib's bundled sample images ``MATPLOTLIB_IMAGES`` as ``[H, W, 3]`` RGB in [0, 1].

    Colour images drop their alpha (composited on white); elevation maps and the MRI slice are
    scaled to [0, 1] and repeated over RGB. Box-downscaled to ``max_size``. Never
    ``HELD_OUT_MATPLOTLIB_IMAGES``.

    Raises:
      InputError: matplotlib is not installed (``pip install 'jmeshtex[render]'``).

    Example:
      >>> imgs = matplotlib_images(max_size=64)
      >>> len(imgs) == len(MATPLOTLIB_IMAGES), all(im.shape[2] == 3 for im in imgs)
      (True, True)
    """
    try:
        import matplotlib.cbook as cbook
        import matplotlib.image as mimage
    except ImportError as err:
        raise InputError(
            "extra training images come from matplotlib's sample data: pip install 'jmeshtex[render]'"
        ) from err
    import gzip

    out = []
    for name in MATPLOTLIB_IMAGES:
        path = cbook.get_sample_data(name, asfileobj=False)
        if name.endswith(".npz"):
            with np.load(path) as data:
                grid = np.asarray(data["elevation" if "elevation" in data else "topo"], np.float64)
        elif name.endswith(".ima.gz"):
            with gzip.open(path) as f:
                grid = np.frombuffer(f.read(), np.uint16).astype(np.float64).reshape(256, 256)
        else:
            grid = None
            image = _to_rgb01(mimage.imread(path))
        if grid is not None:
            grid = (grid - grid.min()) / max(float(np.ptp(grid)), 1e-9)
            image = np.repeat(grid[..., None], 3, axis=-1)
        out.append(downscale(image, max_size))
    return out


def held_out_images(*, max_size: int = 512) -> list[np.ndarray]:
    """``HELD_OUT_IMAGES`` as ``[H, W, 3]`` RGB in [0, 1] (for evaluation only)."""
    return builtin_images(max_size=max_size, names=HELD_OUT_IMAGES)


def _saturated_colors(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` colours with random hue, saturation in [0.55, 1], value in [0.35, 1] (HSV → RGB)."""
    h = rng.random(n)
    s = rng.uniform(0.55, 1.0, n)
    v = rng.uniform(0.35, 1.0, n)
    k = (np.array([5.0, 3.0, 1.0])[None] + 6.0 * h[:, None]) % 6.0
    return v[:, None] - v[:, None] * s[:, None] * np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0)


def _palette(t: np.ndarray, colors: np.ndarray) -> np.ndarray:
    """Piecewise-linear colour map of ``t`` in [0, 1] through ``colors [n, 3]``."""
    n = len(colors)
    x = np.clip(t, 0.0, 1.0) * (n - 1)
    i = np.minimum(np.floor(x).astype(int), n - 2)
    w = (x - i)[..., None]
    return colors[i] * (1 - w) + colors[i + 1] * w


def _value_noise(rng: np.random.Generator, size: int) -> np.ndarray:
    """Fractal value noise in [0, 1]: octaves of bilinearly upsampled random grids."""
    out = np.zeros((size, size))
    base = int(rng.integers(2, 9))
    amp, total = 1.0, 0.0
    persistence = rng.uniform(0.35, 0.7)
    for octave in range(int(rng.integers(1, 5))):
        cells = min(base * 2**octave, size)
        grid = rng.random((cells + 1, cells + 1))
        c = np.linspace(0, cells, size)
        out += amp * ndimage.map_coordinates(grid, np.meshgrid(c, c, indexing="ij"), order=1)
        total += amp
        amp *= persistence
    out /= total
    return (out - out.min()) / max(np.ptp(out), 1e-9)


def procedural_texture(
    key: jax.Array, size: int, *, kind: str | None = None
) -> Float[np.ndarray, "H W 3"]:
    """A random procedural texture in saturated colours, ``[size, size, 3]`` RGB in [0, 1].

    Kinds (``PROCEDURAL_KINDS``, one drawn at random when ``kind`` is None): fractal value noise
    through a 2–4 colour palette; sine or square stripes of random period (4 px to the texture's side)
    and direction; Voronoi cells (4–80 seeds) in random colours, sometimes with dark borders; rotated
    checkers; linear or radial gradients through 2–3 colours.

    Args:
      key: PRNG key (the texture is a function of it).
      size: side in pixels (≥ 8).
      kind: one of ``PROCEDURAL_KINDS``, or None.

    Returns:
      ``[size, size, 3]`` float64 RGB in [0, 1].

    Raises:
      InputError: unknown ``kind`` or ``size < 8``.

    Example:
      >>> import jax
      >>> t = procedural_texture(jax.random.key(0), 32, kind="stripes")
      >>> t.shape, bool(t.min() >= 0 and t.max() <= 1)
      ((32, 32, 3), True)
    """
    check_key(key)
    return _procedural(host_rng(key), int(size), kind)


def _procedural(rng: np.random.Generator, size: int, kind: str | None) -> np.ndarray:
    if size < 8:
        raise InputError(f"texture size must be >= 8, got {size}")
    if kind is None:
        kind = PROCEDURAL_KINDS[int(rng.integers(len(PROCEDURAL_KINDS)))]
    if kind not in PROCEDURAL_KINDS:
        raise InputError(f"kind must be one of {PROCEDURAL_KINDS} or None, got {kind!r}")
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    theta = rng.uniform(0, 2 * np.pi)
    u = np.cos(theta) * x + np.sin(theta) * y
    if kind == "noise":
        img = _palette(_value_noise(rng, size), _saturated_colors(rng, int(rng.integers(2, 5))))
    elif kind == "stripes":
        period = np.exp(rng.uniform(np.log(4.0 / size), 0.0))
        t = np.sin(2 * np.pi * u / period + rng.uniform(0, 2 * np.pi))
        if rng.random() < 0.5:
            t = np.tanh(rng.uniform(2, 20) * t)
        img = _palette(0.5 + 0.5 * t, _saturated_colors(rng, 2))
    elif kind == "cells":
        n = int(rng.integers(4, 81))
        seeds = rng.random((n, 2))
        dist, idx = cKDTree(seeds).query(np.stack([x.ravel(), y.ravel()], -1), k=2)
        img = _saturated_colors(rng, n)[idx[:, 0]].reshape(size, size, 3)
        if rng.random() < 0.4:
            edge = (dist[:, 1] - dist[:, 0]).reshape(size, size) < rng.uniform(0.005, 0.03)
            img = np.where(edge[..., None], rng.uniform(0.0, 0.2), img)
    elif kind == "checker":
        period = np.exp(rng.uniform(np.log(6.0 / size), np.log(0.5)))
        v = -np.sin(theta) * x + np.cos(theta) * y
        t = (np.floor(u / period) + np.floor(v / period)) % 2
        img = _palette(t, _saturated_colors(rng, 2))
    else:  # gradient
        if rng.random() < 0.5:
            t = (u - u.min()) / max(np.ptp(u), 1e-9)
        else:
            c = rng.random(2)
            t = np.sqrt((x - c[0]) ** 2 + (y - c[1]) ** 2)
            t = t / max(t.max(), 1e-9)
        img = _palette(t, _saturated_colors(rng, int(rng.integers(2, 4))))
    return np.clip(img, 0.0, 1.0)


def image_levels(image: np.ndarray) -> tuple[np.ndarray, ...]:
    """Box-filtered pyramid of an image (each level half the previous side, down to ~32 px): what
    :func:`augmented_crop` reads from. Build it once per image for a training run."""
    levels = [np.ascontiguousarray(_to_rgb01(image), np.float64)]
    while min(levels[-1].shape[:2]) >= 32:
        levels.append(downscale(levels[-1], max(levels[-1].shape[:2]) // 2))
    return tuple(levels)


def _hue_rotation(angle: float) -> np.ndarray:
    """RGB → RGB rotation by ``angle`` about the grey axis (a hue shift that keeps luminance ~)."""
    c, s = np.cos(angle), np.sin(angle)
    k = np.full((3, 3), 1.0 / 3.0)
    cross = np.array([[0.0, -1.0, 1.0], [1.0, 0.0, -1.0], [-1.0, 1.0, 0.0]]) / np.sqrt(3.0)
    return c * np.eye(3) + (1 - c) * k + s * cross


def augmented_crop(
    image: Float[np.ndarray, "H W 3"], key: jax.Array, size: int
) -> Float[np.ndarray, "S S 3"]:
    """A random ``[size, size]`` view of ``image``: scale, rotation, flip and colour jitter.

    The view covers ``size · zoom`` source pixels per side (``zoom`` log-uniform in [0.5, 4]; the
    source is read from a box-filtered pyramid level so zooming out does not alias), rotated by a
    uniform angle, mirrored with probability ½, read bilinearly (reflecting at the borders). Colours
    then get a hue rotation (uniform over the circle with probability ½, else within ±0.3 rad), a
    saturation factor in [0.6, 1.6], contrast in [0.75, 1.3] and brightness ±0.1; with probability
    0.15 the luminance is mapped through a random saturated palette instead (so grey images also
    give colour).

    Args:
      image: ``[H, W, 3]`` (or ``[H, W]``) image in [0, 1].
      key: PRNG key (the view is a function of it).
      size: output side in pixels.

    Returns:
      ``[size, size, 3]`` float64 RGB in [0, 1].

    Example:
      >>> import jax, numpy as np
      >>> img = np.random.default_rng(0).random((64, 64, 3))
      >>> augmented_crop(img, jax.random.key(0), 16).shape
      (16, 16, 3)
    """
    check_key(key)
    return _augmented(image_levels(image), host_rng(key), int(size))


def _augmented(levels: tuple[np.ndarray, ...], rng: np.random.Generator, size: int) -> np.ndarray:
    zoom = float(np.exp(rng.uniform(np.log(0.5), np.log(4.0))))
    level = 0
    while level + 1 < len(levels) and zoom >= 2.0:
        level, zoom = level + 1, zoom / 2.0
    src = levels[level]
    h, w = src.shape[:2]
    zoom = min(zoom, 0.95 * min(h, w) / size)  # the view fits inside the image
    theta = rng.uniform(0, 2 * np.pi)
    half = 0.5 * size * zoom * (abs(np.cos(theta)) + abs(np.sin(theta)))
    cy = rng.uniform(min(half, h / 2), max(h - half, h / 2))
    cx = rng.uniform(min(half, w / 2), max(w - half, w / 2))
    g = (np.arange(size) + 0.5 - size / 2) * zoom
    gy, gx = np.meshgrid(g, g, indexing="ij")
    if rng.random() < 0.5:
        gx = -gx
    c, s = np.cos(theta), np.sin(theta)
    coords = np.stack([cy + s * gx + c * gy - 0.5, cx + c * gx - s * gy - 0.5])
    out = np.stack(
        [ndimage.map_coordinates(src[..., ch], coords, order=1, mode="reflect") for ch in range(3)],
        -1,
    )
    # colour jitter
    if rng.random() < 0.15:
        lum = out @ np.array([0.299, 0.587, 0.114])
        lum = (lum - lum.min()) / max(np.ptp(lum), 1e-9)
        return _palette(lum, _saturated_colors(rng, int(rng.integers(2, 5))))
    angle = rng.uniform(-np.pi, np.pi) if rng.random() < 0.5 else rng.uniform(-0.3, 0.3)
    out = out @ _hue_rotation(angle).T
    grey = out.mean(-1, keepdims=True)
    out = grey + rng.uniform(0.6, 1.6) * (out - grey)
    mean = out.mean()
    out = mean + rng.uniform(0.75, 1.3) * (out - mean) + rng.uniform(-0.1, 0.1)
    return np.clip(out, 0.0, 1.0)


def training_texture(
    key: jax.Array, images: list[np.ndarray], *, size: int, procedural_fraction: float = 0.5
) -> Float[np.ndarray, "S S 3"]:
    """One training texture: procedural (probability ``procedural_fraction``) or an augmented image crop.

    Args:
      key: PRNG key (the texture is a function of it).
      images: source images (e.g. :func:`~jmeshtex.fl.training_images`); may be empty if ``procedural_fraction == 1``.
      size: side in pixels.
      procedural_fraction: probability of a :func:`procedural_texture`.

    Returns:
      ``[size, size, 3]`` float64 RGB in [0, 1].

    Example:
      >>> import jax
      >>> t = training_texture(jax.random.key(3), [], size=16, procedural_fraction=1.0)
      >>> t.shape
      (16, 16, 3)
    """
    check_key(key)
    return _training_texture(
        host_rng(key), [image_levels(im) for im in images], size, procedural_fraction
    )


def _training_texture(
    rng: np.random.Generator, levels: list, size: int, procedural_fraction: float
) -> np.ndarray:
    """:func:`training_texture` from a host generator and precomputed :func:`image_levels`."""
    if procedural_fraction < 1 and not levels:
        raise InputError("training_texture: no images given and procedural_fraction < 1")
    if rng.random() < procedural_fraction:
        return _procedural(rng, size, None)
    return _augmented(levels[int(rng.integers(len(levels)))], rng, size)


def mesh_vertices_for(size: int, pixels_per_vertex: float) -> int:
    """Vertex count of a :func:`density_mesh` over a ``size × size`` texture: ``round(size² / ppv)``, ≥ 4.

    Example:
      >>> mesh_vertices_for(64, 26.0)
      158
    """
    return max(4, int(round(size * size / float(pixels_per_vertex))))


def density_mesh(
    texture: Float[np.ndarray, "H W 3"], pixels_per_vertex: float, *, rng: np.random.Generator
) -> Mesh:
    """A :func:`~jmeshtex.fl.core.planar_mesh` over ``texture`` with ``H·W / pixels_per_vertex`` vertices.

    Args:
      texture: ``[H, W, 3]`` RGB in [0, 1].
      pixels_per_vertex: texture pixels per mesh vertex (paper: ≈ 26; Spot at 30K: ≈ 15–20).
      rng: random generator (the farthest-point candidates).

    Returns:
      A textured planar :class:`~jmeshtex.Mesh`.

    Example:
      >>> m = density_mesh(np.zeros((32, 32, 3)), 16.0, rng=np.random.default_rng(0))
      >>> m.num_vertices
      64
    """
    if not pixels_per_vertex > 0:
        raise InputError(f"pixels_per_vertex must be > 0, got {pixels_per_vertex}")
    h, w = texture.shape[:2]
    return planar_mesh(texture, max(4, int(round(h * w / float(pixels_per_vertex)))), rng=rng)


def _stream_meshes(rng: np.random.Generator, levels: list, config) -> list[Mesh]:
    """The ``config.batch_size`` planar meshes of one stream-mode training step (see :func:`training_meshes`)."""
    spread = np.log(float(config.density_spread))
    out = []
    for _ in range(config.batch_size):
        ppv = float(config.pixels_per_vertex) * float(np.exp(rng.uniform(-spread, spread)))
        texture = _training_texture(
            rng, levels, int(config.texture_size), float(config.procedural_fraction)
        )
        out.append(density_mesh(texture, ppv, rng=rng))
    return out


def max_stream_vertices(config) -> int:
    """Largest vertex count of a stream-mode training mesh of ``config`` (the densest draw)."""
    return mesh_vertices_for(
        int(config.texture_size), float(config.pixels_per_vertex) / float(config.density_spread)
    )


def training_meshes(
    key: jax.Array, config, *, images: list[np.ndarray] | None = None
) -> list[Mesh]:
    """The planar meshes of one stream-mode training step: ``config.batch_size`` fresh textures at the density.

    Each mesh: a :func:`training_texture` of side ``config.texture_size`` (procedural with
    probability ``config.procedural_fraction``, else an augmented crop of ``images``), meshed by
    :func:`density_mesh` at ``config.pixels_per_vertex`` times a log-uniform factor in
    ``[1/density_spread, density_spread]``. :func:`~jmeshtex.fl.train` draws its step ``t`` the
    same way from a generator of its data key and ``t``.

    Args:
      key: PRNG key (the meshes are a function of it).
      config: :class:`~jmeshtex.fl.Config` with ``pixels_per_vertex > 0``.
      images: source images (default :func:`~jmeshtex.fl.training_images` at ``config.max_image_size``: no
        held-out image).

    Returns:
      ``config.batch_size`` textured planar :class:`~jmeshtex.Mesh` objects.

    Raises:
      InputError: ``config.pixels_per_vertex`` is 0 (the pool data mode).

    Example:
      >>> import jax
      >>> from jmeshtex.fl import Config
      >>> c = Config.small(texture_size=32, procedural_fraction=1.0)
      >>> [m.texture.shape for m in training_meshes(jax.random.key(0), c, images=[])]
      [(32, 32, 3), (32, 32, 3)]
    """
    check_key(key)
    if not config.pixels_per_vertex > 0:
        raise InputError(
            "training_meshes needs config.pixels_per_vertex > 0 (the stream data mode)"
        )
    if images is None:
        images = (
            training_images(max_size=config.max_image_size)
            if config.procedural_fraction < 1
            else []
        )
    return _stream_meshes(host_rng(key), [image_levels(im) for im in images], config)

"""Planar training meshes laid over images (paper supplement §9.1).

Each training mesh is a flat triangulation of the unit-aspect rectangle of an image: farthest-point
samples (the four corners first, then greedily the candidate farthest from all chosen points) and
their Delaunay triangulation, with ``uv`` = the point's position over the image and the image as
texture. Resolutions are drawn at random in ``[min_vertices, max_vertices]``, coarser than the
meshes met at inference, so the encoder learns one-rings that span many texels.

Images: :func:`builtin_images` — scikit-image's bundled natural images and textures (no download);
:func:`folder_images` — every PNG/JPEG in a folder.
"""

from __future__ import annotations

import os
import pathlib

import numpy as np
from scipy.spatial import Delaunay

from .._errors import InputError, MeshIOError
from .._mesh import Mesh
from .._types import Float

#: scikit-image images bundled in its wheel (natural photos, textures, micrographs)
BUILTIN_IMAGES = (
    "astronaut",
    "brick",
    "camera",
    "chelsea",
    "coffee",
    "coins",
    "colorwheel",
    "grass",
    "gravel",
    "hubble_deep_field",
    "immunohistochemistry",
    "moon",
    "retina",
    "rocket",
)


def _to_rgb01(image) -> np.ndarray:
    img = np.asarray(image)
    if img.dtype == bool:
        img = img.astype(np.float64)
    elif np.issubdtype(img.dtype, np.integer):
        img = img.astype(np.float64) / float(np.iinfo(img.dtype).max)
    else:
        img = img.astype(np.float64)
    if img.ndim == 2:
        img = img[..., None]
    if img.ndim != 3 or img.shape[0] < 2 or img.shape[1] < 2:
        raise InputError(
            f"an image must be [H, W] or [H, W, C] with H, W >= 2, got shape {img.shape}"
        )
    if img.shape[2] in (2, 4):  # drop alpha (composite on white)
        alpha = img[..., -1:]
        img = img[..., :-1] * alpha + (1.0 - alpha)
    if img.shape[2] == 1:
        img = np.repeat(img, 3, axis=2)
    return np.clip(img[..., :3], 0.0, 1.0)


def downscale(image: Float[np.ndarray, "H W 3"], max_size: int) -> np.ndarray:
    """Box-filter an image by the smallest integer factor that brings its longer side to ``<= max_size``."""
    h, w = image.shape[:2]
    k = int(np.ceil(max(h, w) / max_size))
    if k <= 1:
        return image
    h2, w2 = h // k, w // k
    return image[: h2 * k, : w2 * k].reshape(h2, k, w2, k, -1).mean(axis=(1, 3))


def builtin_images(
    *, max_size: int = 256, names: tuple[str, ...] = BUILTIN_IMAGES
) -> list[np.ndarray]:
    """scikit-image's bundled images as ``[H, W, 3]`` float64 RGB in [0, 1], downscaled to ``max_size``.

    Example:
      >>> imgs = builtin_images(max_size=64, names=("brick", "coffee"))
      >>> [im.shape for im in imgs]
      [(64, 64, 3), (40, 60, 3)]
    """
    import skimage.data

    out = []
    for name in names:
        if not hasattr(skimage.data, name):
            raise InputError(f"scikit-image has no bundled image {name!r}; known: {BUILTIN_IMAGES}")
        out.append(downscale(_to_rgb01(getattr(skimage.data, name)()), max_size))
    return out


def folder_images(folder: str | os.PathLike, *, max_size: int = 256) -> list[np.ndarray]:
    """Every ``.png``/``.jpg``/``.jpeg`` image in ``folder`` (sorted by name), as RGB in [0, 1].

    Raises:
      MeshIOError: the folder does not exist or holds no readable image.
    """
    from ..io import load_texture

    folder = pathlib.Path(folder)
    if not folder.is_dir():
        raise MeshIOError(
            f"image folder {folder} does not exist. Fix: pass an existing folder or 'builtin'"
        )
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg"))
    if not files:
        raise MeshIOError(
            f"no .png/.jpg images in {folder}. Fix: add images or use --images builtin"
        )
    out = []
    for p in files:
        try:
            out.append(downscale(_to_rgb01(load_texture(p)), max_size))
        except (OSError, ValueError) as err:
            raise MeshIOError(f"cannot read image {p}: {err}") from err
    return out


def farthest_points(
    candidates: Float[np.ndarray, "M 2"], n: int, *, first: np.ndarray
) -> np.ndarray:
    """Greedy farthest-point selection of ``n`` indices from ``candidates``, seeded with ``first``.

    Example:
      >>> pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.1, 0.0], [0.5, 0.0]])
      >>> farthest_points(pts, 3, first=np.array([0])).tolist()
      [0, 1, 3]
    """
    chosen = list(first)
    d = np.min(np.linalg.norm(candidates[:, None, :] - candidates[first][None], axis=-1), axis=1)
    for _ in range(n - len(chosen)):
        i = int(np.argmax(d))
        chosen.append(i)
        d = np.minimum(d, np.linalg.norm(candidates - candidates[i], axis=1))
    return np.asarray(chosen)


def planar_mesh(
    image: Float[np.ndarray, "H W 3"], num_vertices: int, *, rng: np.random.Generator
) -> Mesh:
    """A flat Delaunay mesh of farthest-point samples over an image, textured with it.

    The rectangle is ``[0, W/H] × [0, 1]`` (z = 0), so texels are square; ``uv`` maps it onto the image.

    Args:
      image: ``[H, W, 3]`` RGB in [0, 1].
      num_vertices: number of vertices (≥ 4).
      rng: random generator (candidate points).

    Returns:
      A :class:`~jmeshtex.Mesh` with ``uv`` and ``texture``, faces counter-clockwise (+z normal).

    Example:
      >>> m = planar_mesh(np.zeros((8, 16, 3)), 20, rng=np.random.default_rng(0))
      >>> m.num_vertices, bool(np.ptp(m.vertices[:, 0]) == 2.0)
      (20, True)
    """
    image = _to_rgb01(image)
    if num_vertices < 4:
        raise InputError(f"num_vertices must be >= 4, got {num_vertices}")
    h, w = image.shape[:2]
    aspect = w / h
    # The boundary first, evenly spaced at the interior's expected spacing s (n vertices over the
    # area `aspect` at √3/2·s² each): with interior samples only, the hull's edges join the corners
    # to points a hair inside and Delaunay fills the gap with slivers as long as a side (invisible
    # while the sheet is flat, folds once it is bent, and one-rings that span the whole sheet).
    spacing = np.sqrt(2.0 * aspect / (np.sqrt(3.0) * num_vertices))
    counts = [max(1, int(round(length / spacing))) for length in (aspect, 1.0, aspect, 1.0)]
    while sum(counts) > max(4, num_vertices // 2):  # coarse meshes: keep most vertices inside
        counts = [max(1, c // 2) for c in counts]
    starts = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    boundary = np.concatenate(
        [
            a + (b - a) * (np.arange(c) / c)[:, None]
            for a, b, c in zip(starts, np.roll(starts, -1, axis=0), counts, strict=True)
        ]
    )
    cand = np.concatenate([boundary, rng.random((max(8 * num_vertices, 256), 2))])
    scaled = cand * np.array([aspect, 1.0])
    idx = farthest_points(scaled, num_vertices, first=np.arange(len(boundary)))
    uv = cand[idx]
    xy = scaled[idx]
    tri = Delaunay(xy).simplices.astype(np.int64)
    a, b, c = xy[tri[:, 0]], xy[tri[:, 1]], xy[tri[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    tri = np.where((cross < 0)[:, None], tri[:, [0, 2, 1]], tri)
    tri = tri[np.abs(cross) > 1e-12]
    vertices = np.concatenate([xy, np.zeros((len(xy), 1))], axis=1)
    return Mesh(vertices, tri, uv=uv[tri], texture=image.astype(np.float32), name="planar")


def planar_pool(
    images: list[np.ndarray],
    *,
    per_image: int,
    min_vertices: int,
    max_vertices: int,
    rng: np.random.Generator,
) -> list[Mesh]:
    """``per_image`` planar meshes of random resolution in ``[min_vertices, max_vertices]`` per image.

    The training pool of :func:`~jmeshtex.fl.train` (supplement §9.1): :func:`planar_mesh` over each
    image, image by image.

    Args:
      images: ``[H, W, 3]`` RGB images in [0, 1] (e.g. :func:`builtin_images`).
      per_image: meshes per image.
      min_vertices, max_vertices: range of the (uniformly drawn) vertex count of each mesh.
      rng: random generator (resolutions and points).

    Returns:
      ``len(images) * per_image`` textured :class:`~jmeshtex.Mesh` objects.

    Example:
      >>> pool = planar_pool([np.zeros((8, 8, 3))], per_image=2, min_vertices=10, max_vertices=12,
      ...                    rng=np.random.default_rng(0))
      >>> len(pool), all(10 <= m.num_vertices <= 12 for m in pool)
      (2, True)
    """
    if not images:
        raise InputError("no training images given")
    return [
        planar_mesh(img, int(rng.integers(min_vertices, max_vertices + 1)), rng=rng)
        for img in images
        for _ in range(per_image)
    ]

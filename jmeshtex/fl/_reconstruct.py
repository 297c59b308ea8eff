"""Texture → latents → texture atlas: FL-VAE reconstruction of a textured mesh, with metrics.

:func:`reconstruct` encodes a textured mesh (or a re-triangulated copy of it, as in the paper's
Table 1, where latents live on a remeshed surface) and decodes every used texel of the original UV
atlas: the texel's surface point is found on the latent mesh (closest point), then the three corner
predictions are blended there (eq. 18 + blending; or the barycentric ablation). Quality is measured
in the atlas over the used texels: PSNR, DSSIM and LPIPS-VGG (:mod:`jmeshtex.metrics`).
"""

from __future__ import annotations

import dataclasses
import os
import pathlib

import numpy as np

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._types import PRNGKey
from ..geometry import rasterize_uv, sample_texture, surface_correspondence
from ._codec import _check_model, decode_points_in_faces, encode
from ._colors import SurfaceColors, surface_colors
from ._model import FieldLatents, Model


@dataclasses.dataclass(frozen=True)
class Reconstruction:
    """What :func:`reconstruct` returns.

    Attributes:
      texture: ``[size, size, 3]`` reconstructed atlas in [0, 1] (0 on unused texels).
      target: ``[size, size, 3]`` the original texture resampled at the same texel centres.
      valid: ``[size, size]`` used texels.
      latents: :class:`~jmeshtex.fl.FieldLatents` on ``latent_mesh``.
      latent_mesh: the mesh the latents live on (the input, or its re-triangulation).
      metrics: ``{"psnr", "dssim", "lpips"}`` over the used texels (``lpips`` only if asked).
      texels: ``(row [N], col [N], face [N], bary [N, 3])``: each used texel and its point on
        ``latent_mesh`` (what :func:`~jmeshtex.fl.core.p1_baselines` fits), or None.
    """

    texture: np.ndarray
    target: np.ndarray
    valid: np.ndarray
    latents: FieldLatents
    latent_mesh: Mesh
    metrics: dict
    texels: tuple | None = None


def atlas_metrics(
    texture: np.ndarray, target: np.ndarray, valid: np.ndarray, *, lpips: bool = True
) -> dict:
    """PSNR (dB), DSSIM (atlases of at least 11×11 texels) and optionally LPIPS-VGG over the used texels.

    Unused texels are set to the same value (0) in both images before LPIPS, which sees whole
    images; PSNR and DSSIM are averaged over ``valid`` only.

    Example:
      >>> import numpy as np
      >>> a = np.full((16, 16, 3), 0.5); b = a + 0.1; m = np.ones((16, 16), bool)
      >>> round(atlas_metrics(a, b, m, lpips=False)["psnr"], 3)
      20.0
    """
    from .. import metrics

    out = {"psnr": float(metrics.psnr(texture, target, mask=valid))}
    if min(valid.shape) >= 11:
        out["dssim"] = float(metrics.dssim(texture, target, mask=valid))
    if lpips:
        a = np.where(valid[..., None], texture, 0.0).astype(np.float32)[None]
        b = np.where(valid[..., None], target, 0.0).astype(np.float32)[None]
        out["lpips"] = float(np.asarray(metrics.lpips(a, b))[0])
    return out


def reconstruct(
    model: Model,
    mesh: Mesh,
    *,
    key: PRNGKey,
    size: int | None = None,
    latent_mesh: Mesh | tuple | None = None,
    lpips: bool = True,
) -> Reconstruction:
    """Encode a textured mesh and reconstruct its UV atlas from the latent means.

    Args:
      model: the FL-VAE (:class:`~jmeshtex.fl.Model`, e.g. :func:`~jmeshtex.fl.load_pretrained`).
      mesh: a textured :class:`~jmeshtex.Mesh` (``uv`` and ``texture``): the reference.
      key: PRNG key of the one-ring sampling.
      size: atlas side in texels (default: the texture's height).
      latent_mesh: where the latents live (e.g. ``jmeshtex.geometry.remesh(mesh, ...)``); its
        colours are read from ``mesh`` at the closest surface points. Default: ``mesh`` itself.
      lpips: also compute LPIPS-VGG (a VGG-16 forward pass on the atlas; seconds on a CPU).

    Returns:
      :class:`Reconstruction`.

    Raises:
      InputError: the reference has no texture or UVs.

    Example:
      >>> import jax, numpy as np
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.fl import Config, init
      >>> v, f = grid(3)
      >>> mesh = Mesh(v, f, uv=v[f][..., :2], texture=np.full((16, 16, 3), 0.5, np.float32))
      >>> model = init(Config(features=8, num_heads=2, num_blocks=1, num_samples=8), key=jax.random.key(0))
      >>> r = reconstruct(model, mesh, key=jax.random.key(1), lpips=False)
      >>> r.texture.shape, int(r.valid.sum()), sorted(r.metrics)
      ((16, 16, 3), 256, ['dssim', 'psnr'])
    """
    model = _check_model(model)
    mesh = as_mesh(mesh, what="mesh")
    if mesh.uv is None or mesh.texture is None:
        raise InputError(
            "reconstruct needs a textured reference mesh (Mesh with uv and texture); "
            "load it with jmeshtex.io.load_mesh(path, texture=...)"
        )
    colors: SurfaceColors = surface_colors(mesh)
    size = int(mesh.texture.shape[0]) if size is None else int(size)
    if latent_mesh is not None:
        latent_mesh = as_mesh(latent_mesh, what="latent_mesh")
    target_mesh = mesh if latent_mesh is None else latent_mesh
    latents = encode(model, target_mesh, colors=colors, key=key)
    texels = rasterize_uv(mesh.uv, size)
    face, bary = texels.face, texels.bary
    if latent_mesh is None:
        lface, lbary = face, bary
    else:
        points = np.einsum(
            "nk,nkd->nd", bary, np.asarray(mesh.vertices, np.float64)[mesh.faces[face]]
        )
        lface, lbary = surface_correspondence(latent_mesh.vertices, latent_mesh.faces, points)
    colors_pred = decode_points_in_faces(model, target_mesh, latents, lface, lbary)
    texture = np.zeros((size, size, 3))
    valid = np.zeros((size, size), bool)
    texture[texels.row, texels.col] = np.clip(colors_pred, 0.0, 1.0)
    valid[texels.row, texels.col] = True
    # target: the original texture at the same texel centres
    jj, ii = np.mgrid[0:size, 0:size]
    uv = np.stack([(ii + 0.5) / size, 1.0 - (jj + 0.5) / size], axis=-1)
    target = np.where(valid[..., None], sample_texture(colors.texture, uv), 0.0)
    return Reconstruction(
        texture,
        target,
        valid,
        latents,
        target_mesh,
        atlas_metrics(texture, target, valid, lpips=lpips),
        (texels.row, texels.col, lface, lbary),
    )


_SHORT = {"p1_oracle": "P1", "p1_fit": "P1 fit", "flat_color": "flat"}


def _baseline_caption(baselines: dict) -> str:
    parts = [f"{_SHORT.get(k, k)} {m['psnr']:.1f}" for k, m in baselines.items() if "psnr" in m]
    return "original; " + ", ".join(parts) + " dB"


def side_by_side(
    mesh: Mesh,
    result: Reconstruction,
    path: str | os.PathLike | None = None,
    *,
    view=(15.0, 35.0),
    size=(384, 384),
    y_up: bool = True,
    baselines: dict | None = None,
) -> np.ndarray:
    """Render the reference with its original and with the reconstructed texture, side by side.

    Args:
      mesh: the textured reference given to :func:`~jmeshtex.fl.reconstruct`.
      result: its :class:`~jmeshtex.fl.Reconstruction`.
      path: where to write the image as a PNG (:func:`jmeshtex.io.save_png`; folders are created);
        None: only return it.
      view: ``(elevation, azimuth)`` of the camera in degrees.
      size: ``(height, width)`` of each of the two renders.
      y_up: the mesh's up axis is +y (as Spot and most OBJ files); the renderer's is +z.
      baselines: ``{name: metrics}`` (:func:`~jmeshtex.fl.core.baseline_metrics`) whose PSNRs are
        printed under the original's render, beside the reconstruction's.

    Returns:
      ``[H, 2 W, 3]`` image: the original left, the reconstruction (with its PSNR) right.

    Example:
      >>> import jax, numpy as np
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> from jmeshtex.fl import Config, init
      >>> v, f = grid(2)
      >>> mesh = Mesh(v, f, uv=v[f][..., :2], texture=np.full((8, 8, 3), 0.5, np.float32))
      >>> r = reconstruct(init(Config(num_samples=4), key=jax.random.key(0)), mesh, key=jax.random.key(1), lpips=False)
      >>> side_by_side(mesh, r, y_up=False, size=(32, 32)).shape
      (32, 64, 3)
    """
    from ..io import save_png
    from ..render import render_mesh

    mesh = as_mesh(mesh, what="mesh")
    if mesh.uv is None:
        raise InputError("side_by_side needs the reference mesh with UVs")
    v = np.asarray(mesh.vertices, np.float64)
    if y_up:
        v = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)
    left = render_mesh(
        Mesh(v, mesh.faces, uv=mesh.uv, texture=result.target),
        view=view,
        size=size,
        title="original" if not baselines else _baseline_caption(baselines),
    )
    right = render_mesh(
        Mesh(v, mesh.faces, uv=mesh.uv, texture=result.texture),
        view=view,
        size=size,
        title=f"FL-VAE ({result.metrics.get('psnr', float('nan')):.2f} dB)",
    )
    image = np.concatenate([left, right], axis=1)
    if path is not None:
        pathlib.Path(path).parent.mkdir(parents=True, exist_ok=True)
        save_png(image, path)
    return image

"""Random inpainting masks for training a mask-conditioned denoiser (``Config.mask_conditioning``).

Mitchel et al. (2024, §6.4) inpaint with a denoiser that can also be conditioned on the mask. To
train one, every copy of every step gets a random mask (True: known, kept) drawn on the host from
``(key, step)``:

- with probability :data:`EMPTY_FRACTION` (¼) the mask is empty, so the model also learns plain
  generation (an empty mask is what :func:`~jmeshtex.fldm.sample` passes);
- otherwise a half-space cut through the copy: a direction ``u`` uniform on the sphere and a
  threshold at a quantile ``q ~ U(0.2, 0.8)`` of ``⟨x_v, u⟩``, ``mask_v = ⟨x_v, u⟩ > thr`` (a
  connected cap of 20–80 % of the vertices on a sphere; the shape the demo and the tests inpaint).

Masks are scalar per-vertex fields, so nothing here touches the gauge.
"""

from __future__ import annotations

import numpy as np

from .._mesh import Mesh, as_mesh
from .._random import host_rng

#: fraction of training masks that are empty (plain generation)
EMPTY_FRACTION = 0.25
#: range of the fraction of vertices a non-empty training mask keeps
KEPT_RANGE = (0.2, 0.8)


def _random_mask(vertices: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    if rng.random() < EMPTY_FRACTION:
        return np.zeros(len(vertices), bool)
    u = rng.normal(size=3)
    u /= max(np.linalg.norm(u), 1e-12)
    proj = (vertices - vertices.mean(0)) @ u
    thr = np.quantile(proj, 1.0 - rng.uniform(*KEPT_RANGE))
    return proj > thr


def random_mask(mesh: Mesh, *, key) -> np.ndarray:
    """One random training mask on ``mesh`` (module docstring): ``[V]`` bool, True where kept.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` (or a ``(vertices, faces)`` pair).
      key: PRNG key; the same key gives the same mask.

    Returns:
      ``[V]`` bool: empty (¼ of keys) or a half-space cap keeping 20–80 % of the vertices.

    Example:
      >>> import jax
      >>> from jmeshtex.data import icosphere
      >>> masks = [random_mask(icosphere(2), key=jax.random.key(i)) for i in range(8)]
      >>> all(m.shape == (162,) for m in masks), all(m.mean() <= 0.85 for m in masks)
      (True, True)
    """
    mesh = as_mesh(mesh)
    return _random_mask(np.asarray(mesh.vertices, np.float64), host_rng(key))


def batch_masks(
    meshes, index: np.ndarray, num_vertices: int, rng: np.random.Generator
) -> np.ndarray:
    """``[len(index), num_vertices]`` random masks of the copies ``meshes[index]`` (False on padding)."""
    out = np.zeros((len(index), num_vertices), bool)
    for row, i in enumerate(np.asarray(index)):
        v = np.asarray(meshes[int(i)].vertices, np.float64)
        out[row, : len(v)] = _random_mask(v, rng)
    return out

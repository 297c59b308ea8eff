"""Extrinsic tangent frames: convert intrinsic tangent vectors (complex numbers) to and from 3D.

The frame of vertex p has the angle-weighted normal ``n``, the x-axis along the reference edge
(slot 0 of the one-ring, the same gauge as :func:`~jmeshtex.geometry.one_ring_neighborhood`)
projected onto the tangent plane, and ``y = n × x``. A tangent vector ``z = r e^{iθ}`` in p's
intrinsic frame is sent to ``r (cos θ x + sin θ y)``.

Accuracy: the intrinsic angle θ of a neighbour is its *normalised* cumulative corner angle, while
the extrinsic angle is measured after projecting onto the tangent plane. On flat regions (and at
boundary vertices of flat sheets) the two agree to rounding, so ``tangent_to_3d(log_p(q))`` is
exactly ``x_q - x_p``. Elsewhere they differ at second order in the edge length h: up to
3.5e-4 rad on ``icosphere(3)`` (1.4e-3 on ``icosphere(2)``, 8.8e-5 on ``icosphere(4)``), shrinking
fourfold per halving of h. Use these frames for rendering, DGTS displacements and tracing, never
for intrinsic computations.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._mesh import accepts_mesh
from .._neighborhoods import TangentFrames
from .._types import ArrayLike, Complex, Float, Int
from ._adjacency import one_rings
from ._intrinsic import check_mesh, corner_angles, edge_lengths


@accepts_mesh
def tangent_frames(
    vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"]
) -> TangentFrames:
    """Orthonormal per-vertex frames (angle-weighted normal, projected reference edge).

    .. math::
        n_p \\propto \\sum_{f \\ni p} \\alpha_{p,f}\\, \\hat n_f, \\quad
        x_p \\propto e - (e\\cdot n_p)\\, n_p,\\ e = x_{q_0} - x_p, \\quad y_p = n_p \\times x_p

    (Thürmer & Wüthrich 1998 for the angle-weighted normal.) Where the projected reference edge
    vanishes (a needle vertex) or a vertex has no faces, a fixed perpendicular / the z-frame is used
    so the frame stays orthonormal.

    Args:
      vertices: ``[V, 3]`` positions.
      faces: ``[F, 3]`` consistently oriented manifold triangles.

    Returns:
      :class:`~jmeshtex.TangentFrames` ``(normal, x, y)``, each ``[V, 3]`` float64.

    Example:
      >>> from jmeshtex.data import grid
      >>> fr = tangent_frames(*grid(2))
      >>> fr.normal[4].tolist(), fr.x[4].round(6).tolist(), fr.y[4].round(6).tolist()
      ([0.0, 0.0, 1.0], [-0.707107, -0.707107, 0.0], [0.707107, -0.707107, 0.0])
    """
    v, f = check_mesh(vertices, faces)
    V = len(v)
    face_n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    face_n /= np.linalg.norm(face_n, axis=1, keepdims=True)
    alpha = corner_angles(edge_lengths(v, f))
    normal = np.zeros((V, 3))
    for axis in range(3):
        normal[:, axis] = np.bincount(
            f.ravel(), (alpha * face_n[:, axis : axis + 1]).ravel(), minlength=V
        )
    normal = _normalize_or(normal, np.array([0.0, 0.0, 1.0]))

    rings = one_rings(f, V)
    edge = np.where(rings.mask[:, :1], v[rings.ring[:, 0]] - v, 0.0)
    x = edge - np.sum(edge * normal, axis=1, keepdims=True) * normal
    # fallback axis: the coordinate axis least aligned with n, made perpendicular
    axis = np.eye(3)[np.argmin(np.abs(normal), axis=1)]
    fallback = axis - np.sum(axis * normal, axis=1, keepdims=True) * normal
    tiny = np.linalg.norm(x, axis=1) <= 1e-12 * np.maximum(np.linalg.norm(edge, axis=1), 1e-300)
    x = np.where(tiny[:, None], fallback, x)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(normal, x)
    return TangentFrames(normal=normal, x=x, y=y)


def _normalize_or(a: np.ndarray, default: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(a, axis=1, keepdims=True)
    ok = norm > 1e-300
    return np.where(ok, a / np.where(ok, norm, 1.0), default)


def tangent_to_3d(
    z: Complex[ArrayLike, "V ..."], frames: TangentFrames
) -> Float[ArrayLike, "V ... 3"]:
    """Tangent vectors (complex, per-vertex frames) to 3D vectors in the tangent planes.

    .. math:: v = \\operatorname{Re}(z)\\, x_p + \\operatorname{Im}(z)\\, y_p

    Works on NumPy and JAX arrays (jit/vmap/grad safe); the output follows ``z``'s precision
    (complex64 → float32).

    Args:
      z: ``[V, ...]`` complex tangent vectors in each vertex's intrinsic frame.
      frames: from :func:`tangent_frames`.

    Returns:
      ``[V, ..., 3]`` real vectors orthogonal to each vertex normal.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import grid
      >>> fr = tangent_frames(*grid(2))
      >>> tangent_to_3d(np.full(9, 1j), fr)[4].round(6).tolist()
      [0.707107, -0.707107, 0.0]
    """
    xp = jnp if isinstance(z, jax.Array) else np
    z = xp.asarray(z)
    real_dtype = xp.real(z).dtype
    shape = (z.shape[0],) + (1,) * (z.ndim - 1) + (3,)
    fx = xp.asarray(frames.x, dtype=real_dtype).reshape(shape)
    fy = xp.asarray(frames.y, dtype=real_dtype).reshape(shape)
    return xp.real(z)[..., None] * fx + xp.imag(z)[..., None] * fy


def tangent_from_3d(
    v3: Float[ArrayLike, "V ... 3"], frames: TangentFrames
) -> Complex[ArrayLike, "V ..."]:
    """3D vectors to tangent vectors (complex) in each vertex's frame; the normal part is dropped.

    .. math:: z = \\langle v, x_p \\rangle + i\\, \\langle v, y_p \\rangle

    Inverse of :func:`tangent_to_3d` on tangent vectors; on any vector it returns the projection onto
    the tangent plane. Works on NumPy and JAX arrays; float32 input gives complex64.

    Args:
      v3: ``[V, ..., 3]`` vectors in world coordinates.
      frames: from :func:`tangent_frames`.

    Returns:
      ``[V, ...]`` complex tangent vectors.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.data import grid
      >>> fr = tangent_frames(*grid(2))
      >>> v3 = np.tile([[1.0, 1.0, 5.0]], (9, 1))
      >>> np.round(tangent_from_3d(v3, fr)[4], 6)
      np.complex128(-1.414214+0j)
    """
    xp = jnp if isinstance(v3, jax.Array) else np
    v3 = xp.asarray(v3)
    shape = (v3.shape[0],) + (1,) * (v3.ndim - 2) + (3,)
    fx = xp.asarray(frames.x, dtype=v3.dtype).reshape(shape)
    fy = xp.asarray(frames.y, dtype=v3.dtype).reshape(shape)
    re, im = xp.sum(v3 * fx, axis=-1), xp.sum(v3 * fy, axis=-1)
    return jax.lax.complex(re, im) if xp is jnp else re + 1j * im

"""An analytic latent codec for colour fields on :func:`~jmeshtex.data.striped_sphere`-like meshes.

It has the FL-VAE's contract (complex ``[V, d]`` latents in the one-ring frames) with ``d = 2``:

.. math:: z_{v,0} = (a + s_v)\\, \\hat g_v, \\qquad z_{v,1} = i\\,(a + 1 - s_v)\\, \\hat g_v

with ``s_v`` the intensity of the vertex colour (:func:`~jmeshtex.data.rgb_to_intensity`), ``ĝ_v``
the unit tangent direction of the meridian in v's frame and ``a`` = :data:`STRIPE_OFFSET`; decoding
is ``s = ½ (|z_0| − a) + ½ (1 + a − |z_1|)`` clipped to [0, 1]. Magnitudes carry the colour, phases
the stripes' orientation, so a diffusion model on these latents must learn both; no trained FL-VAE
is needed (tests, the FLDM demo and notebook).
"""

from __future__ import annotations

import numpy as np

from .._mesh import Mesh
from .._types import Complex, Float
from ._procedural import rgb_to_intensity

#: the codec's ``a``: keeps ``|z|`` away from 0 where the direction is undefined
STRIPE_OFFSET = 0.3


def stripe_encoder(mesh: Mesh) -> Complex[np.ndarray, "V 2"]:
    """The analytic codec's encoder (module docstring): colours of ``mesh`` → ``[V, 2]`` latents.

    Reads ``mesh.vertex_colors`` (e.g. a :func:`~jmeshtex.geometry.remesh` copy, whose colours are
    transferred from the exemplar). The meridian direction is expressed in the intrinsic one-ring
    frames through :func:`~jmeshtex.geometry.tangent_frames` (whose x-axis is the same reference
    edge).

    Args:
      mesh: a :class:`~jmeshtex.Mesh` with ``vertex_colors`` ``[V, 3]`` in [0, 1].

    Returns:
      ``[V, 2]`` complex128 latents in the one-ring frames.

    Example:
      >>> from jmeshtex.data import striped_sphere
      >>> mesh = striped_sphere(subdivisions=1)
      >>> z = stripe_encoder(mesh)
      >>> z.shape, bool(np.allclose(stripe_decoder(z), rgb_to_intensity(mesh.vertex_colors)))
      ((42, 2), True)
    """
    from ..geometry import tangent_frames, tangent_from_3d

    s = rgb_to_intensity(mesh.vertex_colors)
    frames = tangent_frames(mesh.vertices, mesh.faces)
    g = tangent_from_3d(np.broadcast_to([0.0, 0.0, 1.0], mesh.vertices.shape), frames)
    mag = np.abs(g)
    g = np.where(mag > 1e-6, g / np.maximum(mag, 1e-12), 1.0 + 0j)  # poles: any direction
    z = np.stack([(STRIPE_OFFSET + s) * g, 1j * (STRIPE_OFFSET + 1 - s) * g], axis=1)
    return z.astype(np.complex128)


#: a stable name of the codec, for cache keys and checkpoint fingerprints
stripe_encoder.identity = f"stripe_codec:{STRIPE_OFFSET}"  # type: ignore[attr-defined]


def stripe_decoder(z: Complex[np.ndarray, "V 2"]) -> Float[np.ndarray, " V"]:
    """The analytic codec's decoder: latents → intensity in [0, 1] (gauge-invariant).

    Args:
      z: ``[V, 2]`` complex latents (:func:`stripe_encoder`'s layout).

    Returns:
      ``[V]`` float64 intensities in [0, 1].

    Example:
      >>> stripe_decoder(np.array([[0.8 + 0j, 0.8j]])).tolist()
      [0.5]
    """
    z = np.asarray(z)
    s = 0.5 * (np.abs(z[:, 0]) - STRIPE_OFFSET) + 0.5 * (1 + STRIPE_OFFSET - np.abs(z[:, 1]))
    return np.clip(s, 0.0, 1.0)

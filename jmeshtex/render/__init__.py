"""Rendering: host visibility (which face, where, per pixel) + shading as a pure JAX function.

:func:`render` / :func:`render_views` draw a mesh (vertex colours, scalars, UV textures) from
:class:`Camera` objects (:func:`look_at`, the standard rig :func:`orbit_cameras`); :func:`rasterize`
and :func:`shade` are the two halves, for losses through renders; :func:`figure` lays out labelled
panels and :func:`turntable` writes PNG strips / GIFs. :func:`render_mesh` / :func:`render_grid` are
the one-call helpers with overlays (arrows, edges, titles).
"""

from .._extras import needs_render as _needs_render  # noqa: F401 (names a missing extra)
from ..geometry import UP_AXES as UP_AXES
from ..geometry import up_vector as up_vector
from ._camera import Camera as Camera
from ._camera import look_at as look_at
from ._camera import orbit_cameras as orbit_cameras
from ._figure import figure as figure
from ._figure import render_grid as render_grid
from ._figure import turntable as turntable
from ._render import render as render
from ._render import render_views as render_views
from ._render import texture_lod as texture_lod
from ._render_mesh import render_mesh as render_mesh
from ._shade import Lighting as Lighting
from ._shade import camera_lighting as camera_lighting
from ._shade import mip_pyramid as mip_pyramid
from ._shade import sample_mipmapped as sample_mipmapped
from ._shade import shade as shade
from ._visibility import Visibility as Visibility
from ._visibility import rasterize as rasterize

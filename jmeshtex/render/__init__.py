"""Off-screen rendering to PNG (matplotlib Agg): vertex colours, UV textures, scalar and tangent fields."""

from ._render import render_grid as render_grid
from ._render import render_mesh as render_mesh

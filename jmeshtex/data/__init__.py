"""Embedded default data: procedural meshes (and, from later modules, bundled images and weights)."""

from ._meshes import grid as grid
from ._meshes import icosahedron as icosahedron
from ._meshes import icosphere as icosphere
from ._meshes import single_triangle as single_triangle
from ._meshes import torus as torus

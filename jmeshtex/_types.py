"""Array type aliases used in signatures across jmeshtex.

Shapes are written with jaxtyping (``Float[Array, "V 3"]``); the dimension names used throughout:

===========  ==========================================================
``V``        vertices (padded to a common size in batches)
``F``        faces
``K``        neighbourhood slots per vertex (one-ring degree or k of k-NN), padded
``M``        incident faces / children per vertex, padded
``C``, ``D`` feature channels in / out
``N``        samples, traces, texels ...
===========  ==========================================================

Host-side geometry returns NumPy arrays (float64 / complex128 / int32); pure ops accept either NumPy
or JAX arrays. The aliases below are the union of both so one annotation serves both worlds.
"""

from __future__ import annotations

import jax
import numpy as np
from jaxtyping import Array, Bool, Complex, Float, Inexact, Int, Num, Shaped

ArrayLike = jax.Array | np.ndarray
PRNGKey = jax.Array

__all__ = [
    "Array",
    "ArrayLike",
    "Bool",
    "Complex",
    "Float",
    "Inexact",
    "Int",
    "Num",
    "PRNGKey",
    "Shaped",
]

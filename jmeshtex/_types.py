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
or JAX arrays and return JAX arrays. So arguments are annotated ``Float[ArrayLike, "V 3"]``
(``ArrayLike`` = NumPy or JAX array), the results of ops ``Float[Array, "V 3"]`` (``Array`` =
``jax.Array``, tracers included) and the results of host geometry ``Float[np.ndarray, "V 3"]``.

The annotations are checked at run time in the test suite (jaxtyping + beartype, pyproject's
``--jaxtyping-packages``): a wrong shape, dtype or pytree fails at the call, naming the argument.
Outside the tests they cost nothing.
"""

from __future__ import annotations

import jax
import numpy as np
from jaxtyping import Array, Bool, Complex, Float, Inexact, Int, Num, Real, Shaped

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
    "Real",
    "PRNGKey",
    "Shaped",
]

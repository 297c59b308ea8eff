"""Helpers shared by the geometry tests: independent oracles, written without the library, and the
hypothesis strategy of their bad-mesh property tests."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from jmeshtex.testing import BAD_MESH_KINDS, bad_meshes


def bad_mesh_cases(max_vertices: int = 60) -> st.SearchStrategy:
    """``(kind, (v, f))``: a kind of :data:`~jmeshtex.testing.BAD_MESH_KINDS` and a mesh of it."""
    return st.sampled_from(sorted(BAD_MESH_KINDS)).flatmap(
        lambda kind: st.tuples(st.just(kind), bad_meshes(kind, max_vertices=max_vertices))
    )


def euler(v, f) -> int:
    """``V - E + F`` of a triangle mesh, its edges counted from the faces."""
    edges = np.unique(
        np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0
    )
    return len(v) - len(edges) + len(f)

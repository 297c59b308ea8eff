"""Helpers shared by the geometry tests: independent oracles, written without the library."""

from __future__ import annotations

import numpy as np


def euler(v, f) -> int:
    """``V - E + F`` of a triangle mesh, its edges counted from the faces."""
    edges = np.unique(
        np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0
    )
    return len(v) - len(edges) + len(f)

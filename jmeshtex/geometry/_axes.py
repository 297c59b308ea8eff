"""World axes by name: the one parser of ``up=`` (and ``side=``) arguments across jmeshtex."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import InputError

#: up-axis names accepted wherever ``up=`` is
UP_AXES = ("x", "y", "z", "-x", "-y", "-z")


def up_vector(up: str | Sequence[float] | np.ndarray) -> np.ndarray:
    """The unit ``[3]`` vector of an axis: ``"x"|"y"|"z"|"-x"|"-y"|"-z"`` or a 3-vector.

    Args:
      up: an axis name (case and surrounding spaces ignored) or a non-zero finite 3-vector.

    Returns:
      ``[3]`` float64 unit vector.

    Raises:
      InputError: an unknown name, or not a non-zero finite 3-vector.

    Example:
      >>> up_vector("-y")
      array([ 0., -1.,  0.])
      >>> up_vector((0, 0, 2))
      array([0., 0., 1.])
    """
    if isinstance(up, str):
        name = up.strip().lower()
        if name not in UP_AXES:
            raise InputError(f"up must be one of {', '.join(UP_AXES)} or a 3-vector, got {up!r}")
        vec = np.zeros(3)
        vec["xyz".index(name[-1])] = -1.0 if name.startswith("-") else 1.0
        return vec
    try:
        vec = np.asarray(up, dtype=np.float64) if np.ndim(up) == 1 else np.full(0, np.nan)
    except (TypeError, ValueError):
        vec = np.full(0, np.nan)
    if vec.shape != (3,) or not np.isfinite(vec).all() or np.linalg.norm(vec) < 1e-12:
        raise InputError(
            f"up must be one of {', '.join(UP_AXES)} or a non-zero finite 3-vector, got {up!r}"
        )
    return vec / np.linalg.norm(vec)

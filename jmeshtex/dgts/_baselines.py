"""Outputs on one base scored against the oracle beside the baselines that bound them."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import jax
import numpy as np

from .._mesh import Mesh
from ._quality import oracle_texture
from ._texture_measure import knob_scores, texture_noise, texture_operators


def scores_beside_baselines(
    outputs: Mapping[str, Sequence[Mesh]],
    base: Mesh | tuple,
    *,
    kind: str,
    period: float,
    noise_samples: int = 2,
    key: jax.Array,
) -> tuple[dict[str, tuple[float, float, float]], Mesh, list[Mesh]]:
    """Each group of ``outputs`` (displaced copies of ``base``) scored by
    :func:`~jmeshtex.dgts.core.knob_scores` against the oracle (the reference's ``kind`` texture at
    ``period`` mean edges of the base, :func:`~jmeshtex.dgts.core.oracle_texture`), with two
    baselines added: ``"noise"`` (:func:`~jmeshtex.dgts.core.texture_noise` at the oracle's relief,
    ``noise_samples`` draws) and ``"no displacement"`` (the base itself).

    Returns:
      ``(scores, oracle, noise)``: ``scores[name] = (density, relief, distance)``, the group's mean
      knob density and relief as ratios to the oracle's and its mean patch distance (periods); the
      oracle mesh; the noise meshes.

    Example:
      >>> import jax
      >>> from jmeshtex.data import icosphere
      >>> base = icosphere(3)
      >>> s, oracle, _ = scores_beside_baselines({"oracle": [oracle_texture(base, "knobs", period=4.0)]},
      ...                                       base, kind="knobs", period=4.0, key=jax.random.key(0))
      >>> s["oracle"], s["no displacement"][2] > s["noise"][2] > 0
      ((1.0, 1.0, 0.0), True)
    """
    ops = texture_operators(base, period=period)
    oracle = oracle_texture(base, kind, period=period)
    own = knob_scores(oracle, oracle, ops=ops)
    keys = jax.random.split(key, noise_samples)
    noise = [texture_noise(base, ops, own.relief, key=k) for k in keys]
    groups = {
        **outputs,
        "noise": noise,
        "no displacement": [Mesh(*base) if isinstance(base, tuple) else base],
    }
    scores = {}
    for name, meshes in groups.items():
        s = [knob_scores(m, oracle, ops=ops) for m in meshes]
        scores[name] = (
            float(np.mean([x.density for x in s]) / own.density),
            float(np.mean([x.relief for x in s]) / own.relief),
            float(np.mean([x.distance for x in s])),
        )
    return scores, oracle, noise

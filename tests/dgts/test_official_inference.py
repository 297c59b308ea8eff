"""Inference parity with the official DGTS code: ``--gen-levels`` and the official noise pattern.

``official/dgts_official_infer.npz`` (``official/README.md``) holds the official
``Mesh2Mesh.growing`` run unchanged as ``animate`` calls it: a 5-level generator (5 layers of width
8, random weights), a raw target loaded with ``load_real_mesh(target, 0, raw=True)`` (to unit
edge), the default ``--gen-levels [1, 4]`` through ``trim``, ``zero_places = (0, 0, 1, 1, 1)``; its
noise and its output. jmeshtex, given the same weights (``from_official_state_dict``), levels
(``official_gen_levels``) and noise, reproduces the output.
"""

from __future__ import annotations

import json
import pathlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex.dgts import Config, from_official_state_dict, official_gen_levels, transfer
from jmeshtex.dgts.core import plan_transfer, run_plan, upsample

FIXTURE = pathlib.Path(__file__).parent / "official" / "dgts_official_infer.npz"
CONFIG = Config(num_layers=5, start_features=8, min_features=8, max_features=8)
RTOL = 1e-5  # float32 (STYLE.md), relative to the largest coordinate


@pytest.fixture(scope="module")
def off() -> dict[str, np.ndarray]:
    with np.load(FIXTURE, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


def _rel(ours, official) -> float:
    ours, official = np.asarray(ours, np.float64), np.asarray(official, np.float64)
    assert ours.shape == official.shape
    return float(np.abs(ours - official).max() / np.abs(official).max())


def _match(ours: np.ndarray, theirs: np.ndarray) -> np.ndarray:
    """``perm`` with ``ours[j] == theirs[perm[j]]`` (the same vertices in another order)."""
    d = np.linalg.norm(ours[:, None] - theirs[None], axis=-1)
    perm = d.argmin(1)
    assert np.array_equal(np.sort(perm), np.arange(len(theirs))) and d.min(1).max() < 1e-4
    return perm


def test_official_growing_is_reproduced_from_the_same_weights_levels_and_noise(off):
    json.loads(str(off["README"]))
    state = {k.split("/", 1)[1]: v for k, v in off.items() if k.startswith("generator/")}
    model = from_official_state_dict(state, config=CONFIG)
    assert model.num_levels == 5
    start, stop = official_gen_levels(model)  # --gen-levels [1, 4] through the official trim
    assert (start, stop) == tuple(off["start_stop"]) == (1, 4)
    target = (off["raw_vertices"].astype(np.float64), off["faces"])
    plan = plan_transfer(model, target, start_level=start, stop_level=stop)
    # the raw target to unit edge about its vertex mean (the official to_unit_edge)
    assert _rel(plan.vertices, off["unit_vertices"]) < RTOL
    # the official noise in jmeshtex's vertex order (subdivision numbers the midpoints otherwise)
    v, perms, noise = plan.vertices, [], []
    for i, geo in enumerate(plan.geometry):
        perm = _match(np.asarray(v), off[f"base{i}"])
        perms.append(perm)
        noise.append(jnp.asarray(off[f"noise{i}"][perm]))
        v = upsample(v, geo.edge_vertices, scale=CONFIG.scale_factor)
    # zero_places (0, 0, 1, 1, 1): noise on the first two levels run only
    assert [bool(np.any(z)) for z in noise] == [True, True, False, False]
    out = run_plan(model, plan, noise)
    assert _rel(out, off["output"][perms[-1]]) < RTOL
    # transfer() with the official levels draws noise with the same pattern and maps the
    # official unit-edge output back to the target's coordinates
    res = transfer(model, target, start_level=start, stop_level=stop, key=jax.random.key(0))
    assert [bool(np.any(z)) for z in res.noise[0]] == [True, True, False, False]
    assert [np.shape(z) for z in res.noise[0]] == [np.shape(z) for z in noise]
    assert len(res.faces) == len(off["output_faces"])
    mapped = np.asarray(plan.to_target(out))
    unit = (mapped - target[0].mean(0)) * plan.factor  # back to the official frame
    assert _rel(unit, off["output"][perms[-1]]) < RTOL

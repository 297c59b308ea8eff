"""Parity with the official DGTS code: converted official weights reproduce the official outputs.

``../shared/parity/dgts_official.npz`` (its ``README`` key documents every array) holds, for
icosphere(3) at mean edge 1, level 4 of an official ``SingleMeshGenerator`` (default ``Options``),
the vertex noise, the official face features and adjacency, the stack output and the displaced
vertices of ``forward_level``, all from amirhertz/geometric-textures @087c967 run on CPU in float32.
"""

from __future__ import annotations

import json
import os
import pathlib

import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex.dgts import Config, from_official_state_dict, load_official
from jmeshtex.dgts.core import generator_level, official_level_params, to_official_state_dict
from jmeshtex.geometry import face_neighborhood, to_jax
from jmeshtex.ops import face_conv_stack, face_features

#: float32 parity bound of the brief (STYLE.md: float32 ~1e-5 relative)
RTOL = 1e-5


def _parity_file() -> pathlib.Path | None:
    """``../shared/parity/dgts_official.npz``, found the way the root conftest finds ``../shared/data``."""
    env = os.environ.get("JMESHTEX_SHARED_DATA")
    root = pathlib.Path(__file__).resolve().parents[2]
    candidates = [pathlib.Path(env).parent / "parity"] if env else []
    candidates += [root.parent / "shared" / "parity", root / ".." / "shared" / "parity"]
    for c in candidates:
        if (c / "dgts_official.npz").is_file():
            return (c / "dgts_official.npz").resolve()
    return None


@pytest.fixture(scope="module")
def official():
    path = _parity_file()
    if path is None:
        pytest.skip("../shared/parity/dgts_official.npz is absent (the official DGTS outputs)")
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    json.loads(str(arrays["README"]))  # the layout notes must be valid JSON
    return path, arrays


def _rel(a, b) -> float:
    return float(np.abs(np.asarray(a, np.float64) - b).max() / np.abs(b).max())


def test_face_features_and_adjacency_match_the_official_ones(official):
    _, d = official
    nb = to_jax(face_neighborhood(d["faces"], len(d["vertices"])))
    np.testing.assert_array_equal(np.asarray(nb.neighbors).T, d["gfmm"])
    ours = np.asarray(
        face_features(jnp.asarray(d["vertices"] + d["noise"]), nb)
    )  # [F, 3, (len, x, y, z)]
    off = d["features"][0].reshape(3, 4, -1).transpose(2, 0, 1)  # [F, 3, (x, y, z, len)], y = x × n
    converted = np.stack([ours[..., 1], -ours[..., 2], ours[..., 3], ours[..., 0]], -1)
    assert _rel(converted, off) < RTOL


def test_converted_level_reproduces_the_official_stack_and_forward_level(official):
    _, d = official
    params = official_level_params(d, 4)
    widths = (params.embed.weight.shape[1], *(c.weight.shape[1] for c in params.convs))
    assert widths == Config().level_features(4, generator=True)  # the official default Options
    v = jnp.asarray(d["vertices"], jnp.float32)
    z = jnp.asarray(d["noise"], jnp.float32)
    nb = to_jax(face_neighborhood(d["faces"], len(v)))
    stack = np.asarray(
        face_conv_stack(face_features(v + z, nb), nb, params)
    )  # the official (c_x, c_y, c_z)
    assert _rel(stack, d["stack_out"][0].T) < RTOL
    moved = np.asarray(
        v + generator_level(params, v, nb, z, y_sign=Config(official_axes=True).y_sign)
    )
    assert (
        _rel(moved - d["vertices"], d["level_vs"] - d["vertices"]) < RTOL
    )  # the displacement itself
    assert _rel(moved, d["level_vs"]) < RTOL


def test_load_official_runs_the_official_level_through_a_model(official, tmp_path):
    path, d = official
    level4 = {k: v for k, v in d.items() if k.startswith("levels.4.")}
    # a model needs levels 0 … L−1: put the official level 4 at every level of a 5-level model whose
    # widths all equal level 4's (128 → 64 → 32 …), then check that the weights survive the round trip
    cfg = Config(start_features=128, min_features=32, max_features=128, official_axes=True)
    state = {
        k.replace("levels.4.", f"levels.{lv}."): v for lv in range(5) for k, v in level4.items()
    }
    file = tmp_path / "official.npz"
    np.savez(file, **state)
    model = load_official(file, config=cfg)
    assert model.num_levels == 5
    back = to_official_state_dict(model)
    assert set(back) == set(state)
    for k, v in state.items():
        np.testing.assert_array_equal(back[k], v)
    v = jnp.asarray(d["vertices"], jnp.float32)
    nb = to_jax(face_neighborhood(d["faces"], len(v)))
    assert model.config.experimental.official_axes
    moved = np.asarray(
        v
        + generator_level(
            model.generators[2], v, nb, jnp.asarray(d["noise"]), y_sign=model.config.y_sign
        )
    )
    assert _rel(moved, d["level_vs"]) < RTOL
    # and through the whole transfer path: one level run on the parity mesh itself
    from jmeshtex import Mesh
    from jmeshtex.dgts.core import plan_transfer, run_plan

    plan = plan_transfer(model, Mesh(d["vertices"].astype(np.float64), d["faces"]), start_level=4)
    out = plan.to_target(run_plan(model, plan, [jnp.asarray(d["noise"])]))
    assert _rel(out, d["level_vs"]) < RTOL
    with pytest.raises(Exception, match="widths"):
        from_official_state_dict(state)  # the default Config has 32 channels at level 0

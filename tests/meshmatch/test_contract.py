"""The method contract for MeshMatch: Mesh in, ``key=`` for randomness, a result that round-trips
through ``save``/``load``. (MeshMatch trains nothing, so there is no ``train``/``Model``.)"""

from __future__ import annotations

import dataclasses

import jax
import numpy as np
import pytest

from jmeshtex import InputError, Mesh, MeshIOError, meshmatch
from jmeshtex.data import icosphere

CONFIG = meshmatch.Config(levels=2, min_vertices=40, steps=2, coarse_steps=4, hks_eigenpairs=8)


def _source() -> Mesh:
    sphere = icosphere(2)
    v = sphere.vertices
    colors = np.clip(
        0.5 + 0.4 * np.sin(5 * v + np.array([0.0, 1.0, 2.0])) * np.cos(3 * v[:, 1:2]), 0, 1
    )
    return sphere.replace(vertex_colors=colors.astype(np.float32))


def _assert_same(
    a: meshmatch.MeshMatchTransfer, b: meshmatch.MeshMatchTransfer, *, name: bool = True
) -> None:
    for field in dataclasses.fields(Mesh):
        if field.name == "name" and not name:
            continue
        x, y = getattr(a.mesh, field.name), getattr(b.mesh, field.name)
        if x is None or isinstance(x, str):
            assert x == y, field.name
        else:
            assert np.asarray(x).dtype == np.asarray(y).dtype, field.name
            np.testing.assert_array_equal(x, y, err_msg=field.name)
    for name in ("colors", "voted", "nnf", "rotation", "cost"):
        x, y = getattr(a.match, name), getattr(b.match, name)
        assert x.dtype == y.dtype, name
        np.testing.assert_array_equal(x, y, err_msg=name)


def test_transfer_takes_meshes_and_a_key_and_round_trips(tmp_path, key):
    source, target = _source(), icosphere(3)
    out = meshmatch.transfer(source, target, key=key, config=CONFIG)
    assert isinstance(out, meshmatch.MeshMatchTransfer)
    assert out.mesh.vertex_colors.shape == (target.num_vertices, 3)
    assert (
        out.match.nnf.shape == (target.num_vertices,) and out.match.nnf.max() < source.num_vertices
    )

    folder = meshmatch.save(out, tmp_path / "result")
    back = meshmatch.load(folder)
    _assert_same(back, out)
    assert back.match.stats == out.match.stats

    again = meshmatch.transfer(source, target, key=key, config=CONFIG)  # same key: same result
    _assert_same(again, out)
    # a (V, F) pair is a mesh too (without the Mesh's name)
    pair = meshmatch.transfer(source, (target.vertices, target.faces), key=key, config=CONFIG)
    _assert_same(pair, out, name=False)

    other = meshmatch.transfer(source, target, key=jax.random.fold_in(key, 1), config=CONFIG)
    assert np.any(other.match.nnf != out.match.nnf)  # a different key searches differently


def test_save_and_load_reject_what_they_cannot_handle(tmp_path):
    with pytest.raises(InputError, match="MeshMatchTransfer"):
        meshmatch.save(icosphere(1), tmp_path)
    with pytest.raises(MeshIOError, match="holds no MeshMatch transfer"):
        meshmatch.load(tmp_path)
    with pytest.raises(InputError, match="source must be a jmeshtex.Mesh"):
        meshmatch.transfer("sphere.obj", icosphere(1), key=jax.random.key(0))


def test_config_uses_the_shared_field_names():
    names = {f.name for f in dataclasses.fields(meshmatch.Config)}
    assert {"steps", "coarse_steps", "levels"} <= names
    assert not names & {"iterations", "coarse_iterations", "seed", "num_levels"}
    assert meshmatch.Config.from_dict(meshmatch.Config(steps=3).to_dict()).steps == 3

"""The one model file format (`jmeshtex.io.save_model` / `load_model`) and every method's use of it:
round trips keep structure, shapes and dtypes; missing, truncated, garbage, foreign-kind and
wrong-version files are a typed `CorruptModelError` naming the file; writes are atomic and replace a
symbolic link instead of writing through it."""

from __future__ import annotations

import io
import json
import os
import zipfile
from typing import NamedTuple

import jax
import numpy as np
import pytest

from jmeshtex import CorruptModelError, MeshIOError, fl
from jmeshtex.io import load_model, save_model


class _Layer(NamedTuple):
    weight: np.ndarray
    bias: np.ndarray


def _params():
    rng = np.random.default_rng(0)
    return {
        "layers": (
            _Layer(rng.normal(size=(3, 4)).astype(np.float32), np.zeros(4, np.float32)),
            _Layer(rng.normal(size=(4, 2)) + 1j * rng.normal(size=(4, 2)), np.ones(2)),
        ),
        "scale": np.arange(3, dtype=np.float64),
    }


def _save(path, **kw):
    args = dict(kind="test.Model", params=_params(), config={"width": 4}, extra={"step": 7})
    return save_model(path, **{**args, **kw})


def test_round_trip_keeps_key_paths_structure_shapes_and_dtypes(tmp_path):
    path = _save(tmp_path / "sub" / "m.npz")
    like = _params()
    file = load_model(path, kind="test.Model", like=like)
    assert file.config == {"width": 4} and file.extra == {"step": 7} and file.format_version == 1
    assert sorted(file.arrays) == [
        "layers/0/bias",
        "layers/0/weight",
        "layers/1/bias",
        "layers/1/weight",
        "scale",
    ]
    assert jax.tree.structure(file.params) == jax.tree.structure(like)
    assert isinstance(file.params["layers"][1], _Layer)
    for a, b in zip(jax.tree.leaves(file.params), jax.tree.leaves(like), strict=True):
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(a, b)
    nested = load_model(path, kind="test.Model").params  # without like: nested dicts
    np.testing.assert_array_equal(nested["layers"]["1"]["weight"], like["layers"][1].weight)
    assert sorted(p.name for p in (tmp_path / "sub").iterdir()) == ["m.npz"]  # no temporaries


def test_shapes_and_dtypes_are_checked_against_like(tmp_path):
    path = _save(tmp_path / "m.npz")
    bad = _params()
    bad["scale"] = np.zeros(4)
    with pytest.raises(CorruptModelError, match=r"m\.npz.*'scale' is float64\[3\].*float64\[4\]"):
        load_model(path, kind="test.Model", like=bad)
    bad = _params()
    bad["scale"] = np.zeros(3, np.float32)
    with pytest.raises(CorruptModelError, match="'scale' is float64"):
        load_model(path, kind="test.Model", like=bad)
    bad = _params()
    bad["extra_layer"] = np.zeros(1)
    with pytest.raises(CorruptModelError, match="1 missing \\(first 'extra_layer'\\)"):
        load_model(path, kind="test.Model", like=bad)
    bad = _params()
    del bad["scale"]
    with pytest.raises(CorruptModelError, match="1 unexpected \\(first 'scale'\\)") as err:
        load_model(path, kind="test.Model", like=bad)
    assert "layers/0/weight" not in str(err.value)  # no dump of the parameter tree


def _garbage_files(tmp_path, good):
    data = good.read_bytes()
    yield "missing", tmp_path / "none.npz", "no such file"
    (tmp_path / "folder.npz").mkdir()
    yield "folder", tmp_path / "folder.npz", "not a file"
    (tmp_path / "empty.npz").write_bytes(b"")
    yield "empty", tmp_path / "empty.npz", "not a readable model file"
    (tmp_path / "half.npz").write_bytes(data[: len(data) // 2])
    yield "truncated", tmp_path / "half.npz", "not a readable model file"
    (tmp_path / "text.npz").write_bytes(b"hello, not a model\n" * 20)
    yield "garbage", tmp_path / "text.npz", "not a readable model file"
    flipped = bytearray(data)
    flipped[len(data) // 3 : len(data) // 3 + 64] = b"\xff" * 64
    (tmp_path / "flipped.npz").write_bytes(bytes(flipped))
    yield "flipped bytes", tmp_path / "flipped.npz", "model"
    np.save(tmp_path / "array.npy", np.zeros(3))
    yield "npy", tmp_path / "array.npy", "not a readable model file"
    np.savez(tmp_path / "plain.npz", w=np.zeros(3))
    yield "plain npz", tmp_path / "plain.npz", "not a jmeshtex model file"
    _save(tmp_path / "foreign.npz", kind="other.Model")
    yield "foreign kind", tmp_path / "foreign.npz", "holds a 'other.Model', not a 'test.Model'"
    _save(tmp_path / "future.npz", format_version=9)
    yield "wrong version", tmp_path / "future.npz", "format version 9; this jmeshtex reads 1"
    buf = io.BytesIO()
    np.savez(buf, __jmeshtex_model__=np.asarray("{not json"), w=np.zeros(3))
    (tmp_path / "badheader.npz").write_bytes(buf.getvalue())
    yield "bad header", tmp_path / "badheader.npz", "damaged model header"
    buf = io.BytesIO()
    header = {"container": 2, "kind": "test.Model", "format_version": 1, "config": {}}
    np.savez(buf, __jmeshtex_model__=np.asarray(json.dumps(header)))
    (tmp_path / "container.npz").write_bytes(buf.getvalue())
    yield "container version", tmp_path / "container.npz", "container version 2"


def test_every_unreadable_file_is_a_corrupt_model_error_naming_it(tmp_path):
    good = _save(tmp_path / "good.npz")
    cases = list(_garbage_files(tmp_path, good))
    assert len(cases) == 12
    for name, path, match in cases:
        with pytest.raises(CorruptModelError, match=match) as err:
            load_model(path, kind="test.Model", like=_params())
        assert str(path) in str(err.value), name
        assert isinstance(err.value, MeshIOError)  # code catching MeshIOError keeps working
        assert len(str(err.value)) < 400, name


def test_the_write_is_atomic_and_replaces_a_link_instead_of_writing_through_it(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("user data")
    link = tmp_path / "m.npz"
    os.symlink(victim, link)
    _save(link)
    assert victim.read_text() == "user data" and not link.is_symlink()
    assert load_model(link, kind="test.Model").extra == {"step": 7}
    with pytest.raises(MeshIOError, match="not JSON"):
        save_model(tmp_path / "x.npz", kind="k", params={}, config={"bad": object()})
    assert not (tmp_path / "x.npz").exists()


def test_fl_refuses_its_earlier_layout_and_reads_the_shipped_weights_in_the_one_format(tmp_path):
    model = fl.init(fl.Config(latent_dim=2, features=8, num_heads=2), key=jax.random.key(0))
    leaves = jax.tree.leaves(model.params)  # the layout before the one model format (version 0)
    arrays = {f"leaf_{i:04d}": np.asarray(leaf) for i, leaf in enumerate(leaves)}
    meta = {"config": model.config.to_dict(), "num_leaves": len(leaves)}
    np.savez(
        tmp_path / "old.npz", meta=np.frombuffer(json.dumps(meta).encode(), np.uint8), **arrays
    )
    with pytest.raises(CorruptModelError, match="not a jmeshtex model file"):
        fl.load(tmp_path / "old.npz")
    new = fl.save(model, tmp_path / "new", extra={"step": 2})
    assert fl.load(new).config == model.config and fl.load_extra(new) == {"step": 2}
    with zipfile.ZipFile(fl.load_pretrained.__globals__["_PRETRAINED"]["log"]) as z:
        assert "meta.npy" not in z.namelist()  # the shipped weights are in the one format
    assert fl.load_pretrained().config.latent_dim == 8


def test_each_method_refuses_another_methods_model(tmp_path):
    from jmeshtex import dgts, fldm

    model = fl.init(fl.Config(latent_dim=2, features=8, num_heads=2), key=jax.random.key(0))
    fl.save(model, tmp_path / "fl")
    with pytest.raises(CorruptModelError, match="holds a 'jmeshtex.fl.Model', not a 'jmeshtex.d"):
        dgts.load(tmp_path / "fl")
    with pytest.raises(CorruptModelError, match="not a 'jmeshtex.fldm.Model'"):
        fldm.load(tmp_path / "fl")
    with pytest.raises(CorruptModelError, match="no DGTS model"):
        dgts.load(tmp_path)
    with pytest.raises(CorruptModelError, match="no FLDM model"):
        fldm.load(tmp_path)
    (tmp_path / "fl" / "model.npz").write_bytes(b"")
    with pytest.raises(CorruptModelError, match="cannot read FL-VAE model .*model.npz"):
        fl.load(tmp_path / "fl" / "model.npz")


def test_a_model_whose_arrays_do_not_fit_its_config_is_corrupt(tmp_path):
    from jmeshtex import fldm

    cfg = fldm.Config.tiny(latent_channels=2, diffusion_steps=20)
    model = fldm.Model(fldm.core.init_denoiser(jax.random.key(0), cfg), cfg, np.ones(2))
    back = fldm.load(fldm.save(model, tmp_path / "good"))
    for a, b in zip(jax.tree.leaves(model.params), jax.tree.leaves(back.params), strict=True):
        assert np.asarray(a).dtype == np.asarray(b).dtype
        np.testing.assert_array_equal(a, b)
    params = {"params": jax.tree.map(np.asarray, model.params), "scale": np.ones(2)}
    other = cfg.replace(widths=tuple(2 * w for w in cfg.widths)).to_dict()
    save_model(
        tmp_path / "bad" / "model.npz",
        kind="jmeshtex.fldm.Model",
        params=params,
        config=other,
        format_version=2,
    )
    with pytest.raises(
        CorruptModelError, match=r"bad/model\.npz: array 'params/.*its config needs"
    ):
        fldm.load(tmp_path / "bad")
    save_model(
        tmp_path / "scale" / "model.npz",
        kind="jmeshtex.fldm.Model",
        params={**params, "scale": np.ones(3)},
        config=cfg.to_dict(),
        format_version=2,
    )
    with pytest.raises(CorruptModelError, match="'scale' is float64\\[3\\]"):
        fldm.load(tmp_path / "scale")
    save_model(
        tmp_path / "cfg" / "model.npz",
        kind="jmeshtex.fldm.Model",
        params=params,
        config={**cfg.to_dict(), "steps": -1},
        format_version=2,
    )
    with pytest.raises(CorruptModelError, match="stored config is not a valid Config"):
        fldm.load(tmp_path / "cfg")


def test_non_finite_weights_are_refused_naming_the_entry(tmp_path):
    params = {"w": np.array([1.0, np.nan]), "b": np.ones(2)}
    path = save_model(tmp_path / "m.npz", kind="k", config={}, params=params)
    with pytest.raises(CorruptModelError, match=r"NaN or infinite numbers in w"):
        load_model(path, kind="k")

"""The method contract, proved once for every method (the optax ``alias_test.py`` pattern).

``_METHODS_UNDER_TEST`` holds, per method, a tiny config, a tiny data builder and the call of its
task verb. Every method must keep the shape of DESIGN.md:

- ``Config``: a frozen :class:`~jmeshtex._config.ConfigBase` dataclass, ``to_dict``/``from_dict``
  round trip through JSON, unknown fields refused, no ``seed`` (randomness is a ``key``);
- methods that train: ``train(data, config, *, key, ...)`` (data first, config second, ``key``
  keyword-only and required), returning a :class:`jmeshtex.TrainResult` of the method's ``Model``;
  the same key gives the same model, another key another; ``save(model, path)`` then ``load(path)``
  gives the same verb output; a device mesh is always the keyword ``device_mesh=``;
- task verbs take a :class:`~jmeshtex.Mesh` (a typed error for anything else) and a required
  keyword-only ``key``, count with ``num_samples`` and return a named result type exported by the
  method (never a bare array); the same key gives the same result, another key another;
- methods that do not train: ``save(result, path)`` then ``load(path)`` gives the same result;
- ``load`` of a folder without a model or result is a typed error, and so is ``save`` with its
  arguments swapped;
- one vocabulary: the long-running calls (``train``, and the optimising verbs of a method that does
  not train) take ``progress=True``, ``checkpoint_dir=None``, ``stop_after=None`` (what trains) and
  ``device_mesh=None`` (what trains) by those names, their config holds ``checkpoint_every``; no
  ``checkpoint=``, ``card=``/``extra=`` spellings of the same thing elsewhere;
- a ``Model`` is a pytree whose config is static (only arrays are leaves); result types are named
  without the method's name (``fldm.Samples``, not ``fldm.FLDMSamples``); ``save`` writes a folder
  and returns its path;
- file errors say which file failed: a model file :class:`~jmeshtex.CorruptModelError`, a checkpoint
  folder :class:`~jmeshtex.CheckpointError`, both :class:`~jmeshtex.MeshIOError`.

A method that departs from any clause fails a test here.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import json
from collections.abc import Callable
from typing import Any

import jax
import numpy as np
import pytest

import jmeshtex
from jmeshtex import (
    CheckpointError,
    CorruptModelError,
    InputError,
    JmeshtexError,
    Mesh,
    MeshIOError,
    TrainResult,
    dgts,
    fl,
    fldm,
    meshmatch,
    surfacecnn,
)
from jmeshtex._config import ConfigBase
from jmeshtex.data import grid, icosahedron, icosphere, striped_sphere, torus
from tests._presets import FL_MICRO_MESHES, FLDM_MICRO

#: every training here runs 1 to 4 steps: its steps compile at the suite's quick level (conftest.py)
pytestmark = pytest.mark.few_steps


@dataclasses.dataclass(frozen=True)
class _Method:
    """One row of the table: how to build, train and call one method at toy size."""

    name: str
    module: Any
    config: Any
    #: () -> the data ``train`` takes first (None for methods that do not train)
    data: Callable[[], Any] | None
    #: (model or None, key) -> the verb's result; the verb's mesh argument comes from ``mesh``
    verb: Callable[[Any, Mesh, jax.Array], Any]
    #: () -> the Mesh the verb runs on
    mesh: Callable[[], Mesh]
    #: the public verbs of the method (signature clauses)
    verbs: tuple[str, ...]
    #: the verb's result type, exported by the method
    result_type: type
    #: train's keywords besides key (e.g. progress=False)
    train_kwargs: dict = dataclasses.field(default_factory=dict)
    #: (result, mesh) -> asserts what the verb's result must hold (shapes, finiteness)
    check: Callable[[Any, Mesh], None] = lambda result, mesh: None
    #: Config field names shared across methods that this method must use
    shared_names: frozenset = frozenset({"steps"})
    #: the method's other configs (same Config clauses)
    other_configs: tuple = ()
    #: result fields that are not a function of the key (timings) or not saved (prebuilt caches)
    volatile: tuple[str, ...] = ()
    not_saved: tuple[str, ...] = ()
    #: verbs that draw no random numbers: their key may be optional (still keyword-only)
    keyless_verbs: tuple[str, ...] = ()
    #: the long-running calls (train, or a verb that optimises) that share the run keywords
    runs: tuple[str, ...] = ("train",)


# ------------------------------------------------------------------------------------- the table

_DGTS = dgts.Config(
    num_layers=3, start_features=4, min_features=4, max_features=4, steps=2, shared_levels=2
)


def _dgts_data():
    return dgts.training_meshes(
        icosphere(2),
        icosahedron(),
        config=dgts.PrepareConfig(levels=2, steps=20, samples_per_level=200),
        key=jax.random.key(0),
        progress=False,
    )


_FL = FL_MICRO_MESHES.replace(
    latent_dim=2, meshes_per_image=1, batch_size=1, steps=2, warmup_steps=0
)


def _fl_data():
    rng = np.random.default_rng(0)
    return [rng.random((16, 16, 3)) for _ in range(2)]


def _sheet() -> Mesh:
    v, f = grid(3)
    yy, xx = np.mgrid[0:8, 0:8] / 8
    texture = np.stack([xx, yy, 0.5 + 0 * xx], -1).astype(np.float32)
    return Mesh(v, f, uv=v[f][..., :2], texture=texture)


_FLDM = FLDM_MICRO.replace(n_copies=2, steps=3, checkpoint_every=2, batch_size=2)


def _colour_latents(mesh: Mesh) -> np.ndarray:
    """A tiny analytic codec: two complex channels from the vertex colours (no FL-VAE needed)."""
    c = np.asarray(mesh.vertex_colors, np.float64)
    return np.stack([c[:, 0] + 1j * c[:, 1], c[:, 2] - 0.5 + 0.3j], axis=1)


def _fldm_data():
    return fldm.build_dataset(
        striped_sphere(subdivisions=1),
        _FLDM,
        encode=_colour_latents,
        key=jax.random.key(0),
        progress=False,
    )


_MESHMATCH = meshmatch.Config(levels=2, min_vertices=40, steps=2, coarse_steps=4, hks_eigenpairs=8)


def _meshmatch_source() -> Mesh:
    sphere = icosphere(2)
    v = sphere.vertices
    colors = 0.5 + 0.4 * np.sin(5 * v + np.array([0.0, 1.0, 2.0])) * np.cos(3 * v[:, 1:2])
    return sphere.replace(vertex_colors=np.clip(colors, 0, 1).astype(np.float32))


_SURFACECNN = surfacecnn.Config(size=8, steps=3)
_EXEMPLAR = np.random.default_rng(0).uniform(size=(8, 8, 3))


def _two_triangles() -> Mesh:
    v, f = grid(1)
    return Mesh(v, f, uv=v[f][..., :2])


def _check_dgts(out, mesh):
    assert out.vertices.shape[0] == 2 and out.vertices.shape[1:] == out.base.shape
    assert np.abs(out.vertices - out.base).max() > 0  # the generators did displace the target


def _check_fl(out, mesh):
    assert out.texture.shape == out.target.shape and out.valid.any()
    assert out.latents.mu.shape == (mesh.num_vertices, _FL.latent_dim)
    assert np.isfinite(out.metrics["psnr"])


def _check_fldm(out, mesh):
    assert out.latents.shape == (2, mesh.num_vertices, _FLDM.latent_channels)
    assert np.isfinite(out.latents).all() and out.known_mask is None and out.steps == 3


def _check_meshmatch(out, mesh):
    assert out.mesh.vertex_colors.shape == (mesh.num_vertices, 3)
    assert out.match.nnf.shape == (mesh.num_vertices,) and out.match.nnf.max() < 162


def _check_surfacecnn(out, mesh):
    assert out.texture.shape == (8, 8, 3) and out.colors.shape == (64, 3)
    assert out.losses.shape == (3,) and out.texture.dtype == np.float32


_METHODS_UNDER_TEST = (
    _Method(
        name="dgts",
        module=dgts,
        config=_DGTS,
        data=_dgts_data,
        verb=lambda model, mesh, key: dgts.transfer(model, mesh, key=key, num_samples=2),
        mesh=lambda: torus(8, 6),
        verbs=("transfer", "interpolate"),
        result_type=dgts.Transfer,
        train_kwargs={"progress": False},
        check=_check_dgts,
        other_configs=(dgts.PrepareConfig(),),
    ),
    _Method(
        name="fl",
        module=fl,
        config=_FL,
        data=_fl_data,
        verb=lambda model, mesh, key: fl.reconstruct(model, mesh, key=key, lpips=False),
        mesh=_sheet,
        verbs=("encode", "reconstruct"),
        result_type=fl.Reconstruction,
        train_kwargs={"progress": False},
        check=_check_fl,
        shared_names=frozenset({"steps", "learning_rate", "batch_size"}),
    ),
    _Method(
        name="fldm",
        module=fldm,
        config=_FLDM,
        data=_fldm_data,
        verb=lambda model, mesh, key: fldm.sample(model, mesh, key=key, num_samples=2, steps=3),
        mesh=lambda: striped_sphere(subdivisions=1),
        verbs=("sample", "inpaint"),
        result_type=fldm.Samples,
        train_kwargs={"progress": False},
        check=_check_fldm,
        shared_names=frozenset({"steps", "learning_rate", "batch_size", "diffusion_steps"}),
    ),
    _Method(
        name="meshmatch",
        module=meshmatch,
        config=_MESHMATCH,
        data=None,
        verb=lambda _, mesh, key: meshmatch.transfer(
            _meshmatch_source(), mesh, key=key, config=_MESHMATCH
        ),
        mesh=lambda: icosphere(3),
        verbs=("transfer", "paint_by_example"),
        result_type=meshmatch.Transfer,
        check=_check_meshmatch,
        shared_names=frozenset({"steps", "coarse_steps", "levels"}),
        runs=(),  # a transfer is a search of seconds, not a run to checkpoint
        volatile=("stats",),
    ),
    _Method(
        name="surfacecnn",
        module=surfacecnn,
        config=_SURFACECNN,
        data=None,
        verb=lambda _, mesh, key: surfacecnn.synthesize(
            mesh, _EXEMPLAR, _SURFACECNN, key=key, layers=("relu1_1",), progress=False
        ),
        mesh=_two_triangles,
        verbs=("synthesize", "stylize"),
        result_type=surfacecnn.SynthesisResult,
        check=_check_surfacecnn,
        shared_names=frozenset({"steps", "learning_rate"}),
        volatile=("stats", "surface"),
        not_saved=("surface",),
        keyless_verbs=("stylize",),  # stylize starts from the content texture: it draws nothing
        runs=("synthesize", "stylize"),
    ),
)
_ROWS = {m.name: m for m in _METHODS_UNDER_TEST}
_TRAINED = tuple(m for m in _METHODS_UNDER_TEST if m.data is not None)
_UNTRAINED = tuple(m for m in _METHODS_UNDER_TEST if m.data is None)


def _ids(methods):
    return [m.name for m in methods]


# ------------------------------------------------------------------------------------- helpers


def _flatten(value, skip: tuple[str, ...], prefix: str = "") -> list[tuple[str, Any]]:
    """``(path, leaf)`` pairs of a result: dataclass/NamedTuple fields, dict items, sequences."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        items = [(f.name, getattr(value, f.name)) for f in dataclasses.fields(value)]
    elif isinstance(value, tuple) and hasattr(value, "_fields"):
        items = list(zip(value._fields, value, strict=True))
    elif isinstance(value, dict):
        items = sorted(value.items())
    elif isinstance(value, (list, tuple)):
        items = list(enumerate(value))
    else:
        return [(prefix, value)]
    out = []
    for name, item in items:
        if str(name) in skip:
            continue
        out += _flatten(item, skip, f"{prefix}/{name}")
    return out


def _same(a, b, skip: tuple[str, ...] = ()) -> bool:
    fa, fb = _flatten(a, skip), _flatten(b, skip)
    if [p for p, _ in fa] != [p for p, _ in fb]:
        return False
    for (_, x), (_, y) in zip(fa, fb, strict=True):
        if isinstance(x, (np.ndarray, jax.Array, np.generic)):
            x, y = np.asarray(x), np.asarray(y)
            if x.dtype != y.dtype or not np.array_equal(x, y, equal_nan=True):
                return False
        elif x != y:
            return False
    return True


def _array_leaves(value) -> list[np.ndarray]:
    return [np.asarray(x) for _, x in _flatten(value, ()) if isinstance(x, (np.ndarray, jax.Array))]


@functools.cache
def _train(name: str):
    """``(method, data, train result)`` of the row ``name``, trained once with key 1."""
    method = _ROWS[name]
    data = method.data()
    result = method.module.train(data, method.config, key=jax.random.key(1), **method.train_kwargs)
    return method, data, result


#: for a test that trains a row again itself (``_train``): on the worker of the ``trained`` fixture's
#: tests, whose persistent compilation cache holds the row's training step, the training compiles
#: nothing (measured for FLDM: 60 CPU-s on the other worker, 17 here)
_WITH_TRAINED = pytest.mark.xdist_group("tests/test_method_contract.py")


@pytest.fixture(scope="module", params=_TRAINED, ids=_ids(_TRAINED))
def trained(request):
    """``(method, data, train result)`` for each method that trains."""
    return _train(request.param.name)


# ------------------------------------------------------------------------------------ config


@pytest.mark.parametrize("method", _METHODS_UNDER_TEST, ids=_ids(_METHODS_UNDER_TEST))
def test_config_is_frozen_round_trips_and_has_no_seed(method):
    assert isinstance(method.config, method.module.Config)
    for config in (method.config, *method.other_configs):
        cls = type(config)
        assert isinstance(config, ConfigBase) and dataclasses.is_dataclass(config)
        with pytest.raises(dataclasses.FrozenInstanceError):
            config.steps = 5  # type: ignore[misc]
        back = cls.from_dict(json.loads(json.dumps(config.to_dict())))
        assert back == config and back is not config
        names = {f.name for f in dataclasses.fields(config)}
        assert "steps" in names
        assert not names & {"seed", "lr", "iterations", "num_levels", "train_steps"}, names
        with pytest.raises(jmeshtex.ConfigError, match="unknown fields \\['lr'\\]"):
            cls.from_dict({**config.to_dict(), "lr": 0.1})
    names = {f.name for f in dataclasses.fields(method.config)}
    assert method.shared_names <= names, method.shared_names - names


# ------------------------------------------------------------------------------------ signatures


@pytest.mark.parametrize("method", _TRAINED, ids=_ids(_TRAINED))
def test_train_takes_data_first_config_second_and_a_keyword_key(method):
    params = list(inspect.signature(method.module.train).parameters.values())
    data, config = params[0], params[1]
    assert data.name != "config" and data.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD
    assert data.default is inspect.Parameter.empty, "the data is required"
    assert config.name == "config" and config.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD
    by_name = {p.name: p for p in params}
    assert by_name["key"].kind is inspect.Parameter.KEYWORD_ONLY
    assert by_name["key"].default is inspect.Parameter.empty
    assert "seed" not in by_name and "mesh" not in by_name, "a device mesh is device_mesh="


def _public(method):
    """``(qualified name, object)`` of every public name of a method and of its ``core``."""
    for prefix, module in (
        (method.name, method.module),
        (f"{method.name}.core", method.module.core),
    ):
        for name in dir(module):
            if not name.startswith("_"):
                yield f"{prefix}.{name}", getattr(module, name)


@pytest.mark.parametrize("method", _METHODS_UNDER_TEST, ids=_ids(_METHODS_UNDER_TEST))
def test_a_device_mesh_is_always_the_keyword_device_mesh(method):
    for name, obj in _public(method):
        if not inspect.isfunction(obj):
            continue
        for p in inspect.signature(obj).parameters.values():
            if "sharding" in str(p.annotation) or p.name == "device_mesh":
                assert p.name == "device_mesh", f"{name}({p.name}=...)"


@pytest.mark.parametrize("method", _METHODS_UNDER_TEST, ids=_ids(_METHODS_UNDER_TEST))
def test_verbs_take_a_required_keyword_key_and_count_with_num_samples(method):
    for verb in method.verbs:
        params = inspect.signature(getattr(method.module, verb)).parameters
        assert params["key"].kind is inspect.Parameter.KEYWORD_ONLY, verb
        if verb not in method.keyless_verbs:
            assert params["key"].default is inspect.Parameter.empty, verb
        assert not set(params) & {"seed", "n", "num", "count", "samples"}, (verb, list(params))


#: pure building blocks that take the key positionally, as jax.random does
_POSITIONAL_KEY = {
    "fl.core.augmented_crop",
    "fl.core.procedural_texture",
    "fl.core.training_meshes",
    "fl.core.training_texture",
    "fldm.core.draw_sampling_noise",
    "fldm.core.init_denoiser",
}


@pytest.mark.parametrize("method", _METHODS_UNDER_TEST, ids=_ids(_METHODS_UNDER_TEST))
def test_public_functions_are_documented_and_take_a_key_not_a_seed(method):
    for name, obj in _public(method):
        if inspect.ismodule(obj) or not callable(obj):
            continue
        assert (obj.__doc__ or "").strip(), f"{name} has no docstring"
        if not inspect.isfunction(obj):
            continue
        params = inspect.signature(obj).parameters
        assert "seed" not in params, f"{name}: randomness is a key= argument"
        if "key" in params and name not in _POSITIONAL_KEY:
            assert params["key"].kind is inspect.Parameter.KEYWORD_ONLY, name


#: the most names a method's top level may hold (the contract plus a handful of helpers);
#: everything else is a building block in ``<method>.core``
_MAX_TOP_LEVEL = 25
#: what a method's top level holds besides its verbs, results and a few helpers
_CONTRACT = {"Config", "save", "load", "core"}
_TRAINED_CONTRACT = {"Model", "train", "TrainResult"}


@pytest.mark.parametrize("method", _METHODS_UNDER_TEST, ids=_ids(_METHODS_UNDER_TEST))
def test_the_top_level_is_the_contract_and_core_holds_the_building_blocks(method):
    top = {n for n in dir(method.module) if not n.startswith("_")}
    core = {n for n in dir(method.module.core) if not n.startswith("_")}
    need = _CONTRACT | {*method.verbs, method.result_type.__name__}
    if method.data is not None:
        need |= _TRAINED_CONTRACT
    assert need <= top, f"{method.name} lacks {sorted(need - top)} at its top level"
    assert len(top) <= _MAX_TOP_LEVEL, (
        f"{method.name} exports {len(top)} names (at most {_MAX_TOP_LEVEL}); move the building "
        f"blocks to {method.name}.core: {sorted(top - need)}"
    )
    assert not top & core, f"{sorted(top & core)} are in both {method.name} and {method.name}.core"
    assert inspect.ismodule(method.module.core)
    assert method.module.core.__name__ == f"jmeshtex.{method.name}.core"
    assert "building" in (method.module.core.__doc__ or ""), "core's docstring says what it is for"
    for name in core:  # re-exported from the method's private modules, never defined twice
        home = getattr(getattr(method.module.core, name), "__module__", None)
        if home is not None and home.startswith("jmeshtex."):
            assert home.startswith(f"jmeshtex.{method.name}._"), (name, home)


def test_result_types_have_distinct_names_exported_by_their_method():
    names = [f"{m.name}.{m.result_type.__name__}" for m in _METHODS_UNDER_TEST]
    assert len(set(names)) == len(names), names
    for m in _METHODS_UNDER_TEST:
        assert getattr(m.module, m.result_type.__name__) is m.result_type
    for m in _TRAINED:
        assert m.module.TrainResult is TrainResult


def _rows(*, methods=_METHODS_UNDER_TEST):
    return [pytest.param(m, id=m.name) for m in methods]


#: every run keyword, its default, and which runs take it (``"all"`` or only what trains)
_RUN_KEYWORDS = {
    "progress": (True, "all"),
    "checkpoint_dir": (None, "all"),
    "stop_after": (None, "trains"),
    "device_mesh": (None, "trains"),
}


@pytest.mark.parametrize("method", _rows(methods=[m for m in _METHODS_UNDER_TEST if m.runs]))
def test_runs_share_their_keywords_and_defaults_and_the_config_holds_checkpoint_every(method):
    for run in method.runs:
        params = inspect.signature(getattr(method.module, run)).parameters
        for name, (default, who) in _RUN_KEYWORDS.items():
            if who == "trains" and method.data is None:
                continue
            assert name in params, f"{method.name}.{run} lacks {name}="
            assert params[name].kind is inspect.Parameter.KEYWORD_ONLY, (run, name)
            assert params[name].default == default, (run, name, params[name].default)
        assert "checkpoint_every" not in params, f"{method.name}.{run}: it is a Config field"
    assert "checkpoint_every" in {f.name for f in dataclasses.fields(method.config)}


#: spellings of a shared word that the contract has one name for
_OTHER_SPELLINGS = {"checkpoint": "checkpoint_dir", "mesh_axis": "device_mesh", "quiet": "progress"}


@pytest.mark.parametrize("method", _rows())
def test_no_public_function_spells_a_shared_keyword_another_way(method):
    for name, obj in _public(method):
        if not inspect.isfunction(obj):
            continue
        for p in inspect.signature(obj).parameters:
            assert p not in _OTHER_SPELLINGS, (
                f"{name}({p}=...): the contract says {_OTHER_SPELLINGS[p]}="
            )
    if method.data is not None:  # train's checkpoint cadence is a Config field, never a keyword
        assert "checkpoint_every" not in inspect.signature(method.module.train).parameters


@pytest.mark.parametrize("method", _rows())
def test_result_types_are_named_without_the_method_name(method):
    name = method.result_type.__name__.lower()
    assert not name.startswith(method.name.lower()), f"{method.name}.{method.result_type.__name__}"
    for public, obj in _public(method):
        if inspect.isclass(obj) and obj.__module__.startswith(f"jmeshtex.{method.name}."):
            assert not obj.__name__.lower().startswith(method.name.lower()), public


def _model_of(method):
    """An untrained model of a row, at the row's toy size (no training needed)."""
    if method.name == "fl":
        return fl.init(method.config, key=jax.random.key(0))
    if method.name == "fldm":
        return fldm.init(method.data(), method.config, key=jax.random.key(0))
    return _train(method.name)[2].model


@pytest.mark.parametrize("method", _rows(methods=_TRAINED))
def test_a_model_is_a_pytree_of_arrays_with_a_static_config(method):
    model = _model_of(method)
    leaves = jax.tree.leaves(model)
    assert leaves and all(isinstance(x, (np.ndarray, jax.Array)) for x in leaves), sorted(
        {type(x).__name__ for x in leaves}
    )
    copied = jax.tree.map(lambda x: x, model)
    assert isinstance(copied, method.module.Model) and copied.config is model.config


@pytest.mark.parametrize("method", _rows(methods=_TRAINED))
def test_save_writes_a_folder_and_returns_it(method, tmp_path):
    model = _model_of(method)
    written = method.module.save(model, tmp_path / "model")
    assert written == tmp_path / "model" and written.is_dir()
    assert method.module.load(written).config == model.config


@pytest.mark.parametrize("method", _UNTRAINED, ids=_ids(_UNTRAINED))
def test_save_of_a_result_writes_a_folder_and_returns_it(method, tmp_path):
    result = method.verb(None, method.mesh(), jax.random.key(7))
    written = method.module.save(result, tmp_path / "result")
    assert written == tmp_path / "result" and written.is_dir()


def test_file_errors_say_which_file_failed(tmp_path):
    from jmeshtex.io import Checkpoints

    assert issubclass(CorruptModelError, MeshIOError) and issubclass(CheckpointError, MeshIOError)
    assert not issubclass(CorruptModelError, CheckpointError)
    assert not issubclass(CheckpointError, CorruptModelError)
    assert issubclass(jmeshtex.CheckpointMismatchError, CheckpointError)
    with pytest.raises(CheckpointError, match="no checkpoint"):
        Checkpoints(tmp_path / "none").restore({})
    (tmp_path / "file").write_text("x")
    with pytest.raises(CheckpointError, match="not a folder"):
        Checkpoints(tmp_path / "file")
    for m in _TRAINED:
        with pytest.raises(CorruptModelError):
            m.module.load(tmp_path)


# ------------------------------------------------------------------------------------ training


def test_train_returns_a_train_result_of_the_model_and_depends_on_the_key_only(trained):
    method, data, result = trained
    assert isinstance(result, TrainResult) and isinstance(result.model, method.module.Model)
    assert result.model.config == method.config
    assert result.resumed_from is None and result.seconds > 0
    assert all(np.isfinite(np.asarray(v)).all() for v in result.losses.values())
    again = method.module.train(data, method.config, key=jax.random.key(1), **method.train_kwargs)
    other = method.module.train(data, method.config, key=jax.random.key(2), **method.train_kwargs)
    same = _array_leaves(jax.tree.leaves(again.model))
    for x, y in zip(_array_leaves(jax.tree.leaves(result.model)), same, strict=True):
        np.testing.assert_array_equal(x, y)
    assert any(
        not np.array_equal(x, y)
        for x, y in zip(
            _array_leaves(jax.tree.leaves(result.model)),
            _array_leaves(jax.tree.leaves(other.model)),
            strict=True,
        )
    ), f"{method.name}.train: another key gave the same model"


def test_save_then_load_gives_the_same_model_and_the_same_verb_output(trained, tmp_path):
    method, _, result = trained
    module, model = method.module, result.model
    path = tmp_path / "model"
    written = module.save(model, path)
    assert written == path
    loaded = module.load(written)
    assert isinstance(loaded, module.Model) and loaded.config == model.config
    leaves, back = jax.tree.leaves(model), jax.tree.leaves(loaded)
    assert len(leaves) == len(back)
    for x, y in zip(leaves, back, strict=True):
        assert np.asarray(x).dtype == np.asarray(y).dtype
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    mesh, key = method.mesh(), jax.random.key(3)
    before, after = method.verb(model, mesh, key), method.verb(loaded, mesh, key)
    assert _same(before, after, method.volatile), f"{method.name}: load changed the verb's output"
    with pytest.raises(JmeshtexError):
        module.save(path, model)  # object first, path second
    (tmp_path / "empty").mkdir()
    with pytest.raises(CorruptModelError):
        module.load(tmp_path / "empty")


def test_the_verb_returns_a_named_result_that_depends_on_the_key_only(trained):
    method, _, result = trained
    _check_verb(method, result.model)


@pytest.mark.parametrize("method", _UNTRAINED, ids=_ids(_UNTRAINED))
def test_the_verb_of_a_method_without_training_returns_a_named_result(method):
    _check_verb(method, None)


def _check_verb(method, model):
    mesh = method.mesh()
    a = method.verb(model, mesh, jax.random.key(5))
    b = method.verb(model, mesh, jax.random.key(5))
    c = method.verb(model, mesh, jax.random.key(6))
    assert isinstance(a, method.result_type), type(a)
    method.check(a, mesh)
    assert not isinstance(a, (np.ndarray, jax.Array)), "a verb returns a named result"
    assert _same(a, b, method.volatile), f"{method.name}: the same key gave another result"
    assert not _same(a, c, method.volatile), f"{method.name}: another key gave the same result"
    with pytest.raises(InputError, match="(?i)mesh"):
        method.verb(model, "mesh.obj", jax.random.key(5))


# ------------------------------------------------------------------------- results on disk


@pytest.mark.parametrize("method", _UNTRAINED, ids=_ids(_UNTRAINED))
def test_save_then_load_gives_the_same_result(method, tmp_path):
    result = method.verb(None, method.mesh(), jax.random.key(7))
    written = method.module.save(result, tmp_path / "result")
    assert (tmp_path / "result").is_dir()
    back = method.module.load(tmp_path / "result")
    assert isinstance(back, method.result_type)
    assert _same(back, result, method.not_saved), f"{method.name}: load changed the result"
    assert written is not None
    with pytest.raises(InputError):
        method.module.save(tmp_path / "result", result)  # object first, path second
    with pytest.raises(MeshIOError):
        method.module.load(tmp_path / "nothing")


# ----------------------------------------------------------- the parts only one method has


@_WITH_TRAINED
def test_dgts_interpolation_is_a_function_of_its_key():
    _, _, result = _train("dgts")
    target = torus(8, 6)
    a = dgts.interpolate(result.model, target, num_frames=2, key=jax.random.key(3))
    b = dgts.interpolate(result.model, target, num_frames=2, key=jax.random.key(3))
    c = dgts.interpolate(result.model, target, num_frames=2, key=jax.random.key(4))
    assert isinstance(a, dgts.Transfer) and a.vertices.shape[0] == 2
    np.testing.assert_array_equal(a.vertices, b.vertices)
    assert not np.allclose(a.vertices, c.vertices)


@_WITH_TRAINED
def test_fl_model_is_a_pytree_with_a_static_config_and_reconstruct_encodes_with_its_key():
    _, _, result = _train("fl")
    model = result.model
    assert result.steps == _FL.steps
    doubled = jax.tree.map(lambda x: 2 * x, model)
    assert isinstance(doubled, fl.Model) and doubled.config is model.config
    mu = np.ones((3, _FL.latent_dim), np.complex64)
    jitted = jax.jit(lambda m, z: fl.core.decode_vertex_colors_from_latents(m.params, m.config, z))
    np.testing.assert_allclose(
        jitted(model, mu),
        fl.core.decode_vertex_colors_from_latents(model.params, model.config, mu),
        atol=1e-6,
    )
    with pytest.raises(jmeshtex.ConfigError, match="Model.config must be"):
        fl.Model(model.params, _FL.to_dict())
    mesh, key = _sheet(), jax.random.key(7)
    latents = fl.encode(model, mesh, key=key)
    assert isinstance(latents, fl.FieldLatents)
    np.testing.assert_array_equal(
        fl.reconstruct(model, mesh, key=key, lpips=False).latents.mu, latents.mu
    )
    coloured = Mesh(mesh.vertices, mesh.faces, vertex_colors=np.full((mesh.num_vertices, 3), 0.5))
    np.testing.assert_array_equal(  # a (V, F) pair is accepted where a mesh is expected
        fl.decode_vertex_colors(model, (mesh.vertices, mesh.faces), latents),
        fl.decode_vertex_colors(model, coloured, latents),
    )


@_WITH_TRAINED
def test_fldm_trains_from_init_its_dataset_follows_its_key_and_inpainting_keeps_the_known():
    method, data, result = _train("fldm")
    assert result.steps == _FLDM.steps and result.losses["loss"].shape == (_FLDM.steps,)
    assert np.array_equal(result.model.scale, data.scale)
    start = fldm.init(data, _FLDM, key=jax.random.key(1))  # the model train(key) started from
    assert any(
        not np.array_equal(a, b)
        for a, b in zip(
            jax.tree.leaves(start.params), jax.tree.leaves(result.model.params), strict=True
        )
    )
    first = fldm.train(data, _FLDM.replace(steps=1), key=jax.random.key(1), progress=False)
    assert first.losses["loss"][0] == result.losses["loss"][0]
    mesh = method.mesh()
    same = fldm.build_dataset(
        mesh, _FLDM, encode=_colour_latents, key=jax.random.key(0), progress=False
    )
    np.testing.assert_array_equal(same.latents, data.latents)
    other = fldm.build_dataset(
        mesh, _FLDM, encode=_colour_latents, key=jax.random.key(7), progress=False
    )
    assert not np.array_equal(other.meshes[0].vertices, data.meshes[0].vertices)
    with pytest.raises(InputError, match="Mesh"):
        fldm.build_dataset(mesh.vertices, _FLDM, encode=_colour_latents, key=jax.random.key(0))
    pair, key = (mesh.vertices, mesh.faces), jax.random.key(5)
    known, mask = _colour_latents(mesh), mesh.vertices[:, 2] > 0
    a = fldm.inpaint(result.model, mesh, known, mask, key=key, method="ddim", steps=2)
    b = fldm.inpaint(result.model, pair, known, mask, key=key, method="ddim", steps=2)
    assert isinstance(a, fldm.Samples) and np.array_equal(a.known_mask, mask)
    np.testing.assert_array_equal(a.latents, b.latents)
    np.testing.assert_allclose(a.latents[0][mask], known[mask], rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(
        fldm.sample(result.model, pair, key=key, steps=2).latents,
        fldm.sample(result.model, mesh, key=key, steps=2).latents,
    )


def test_meshmatch_takes_a_vertices_faces_pair_as_a_mesh():
    method = _ROWS["meshmatch"]
    target = method.mesh()
    key = jax.random.key(5)
    out = method.verb(None, target, key)
    pair = method.verb(None, (target.vertices, target.faces), key)
    assert _same(pair, out, ("stats", "name"))


def test_surfacecnn_takes_a_pair_and_stylize_draws_nothing():
    mesh = _two_triangles()
    pair = surfacecnn.synthesize(
        (mesh.vertices, mesh.faces),
        _EXEMPLAR,
        surfacecnn.Config(size=8, steps=1),
        key=jax.random.key(1),
        layers=("relu1_1",),
        progress=False,
    )
    assert pair.mesh.uv.shape == (2, 3, 2)  # unwrapped, having no UVs
    config = surfacecnn.Config(size=8, steps=2, content_layer="relu1_2")
    content = np.full((8, 8, 3), 0.4)
    runs = [
        surfacecnn.stylize(
            mesh,
            content,
            _EXEMPLAR,
            config,
            key=jax.random.key(k),
            layers=("relu1_1",),
            progress=False,
        )
        for k in (0, 1)
    ]
    np.testing.assert_array_equal(runs[0].texture, runs[1].texture)
    assert np.abs(runs[0].texture - 0.4).max() > 1e-3  # the optimisation moved off the content

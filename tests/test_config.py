"""The shared config mechanism (`jmeshtex._config`): rules, JSON round trip, ``replace``."""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib
import re
import types
import typing

import numpy as np
import pytest

from jmeshtex import ConfigError
from jmeshtex._config import (
    ConfigBase,
    cross_rule,
    display_name,
    flat_names,
    integers,
    is_finite_number,
    is_int,
    rule,
    stored_config,
    type_ok,
)
from jmeshtex.dgts import Config as DGTSConfig
from jmeshtex.dgts import PrepareConfig
from jmeshtex.dgts.core import Experimental as DGTSExperimental
from jmeshtex.fl import Config as FLVAEConfig
from jmeshtex.fl._io import FORMAT_VERSION as FL_FORMAT_VERSION
from jmeshtex.fl.core import Experimental as FLExperimental
from jmeshtex.fldm import Config as FLDMConfig
from jmeshtex.fldm.core import Experimental as FLDMExperimental
from jmeshtex.meshmatch import Config as MeshMatchConfig
from jmeshtex.meshmatch.core import Experimental as MeshMatchExperimental
from jmeshtex.surfacecnn import Config as SurfaceCNNConfig

WEIGHTS = pathlib.Path(__file__).resolve().parents[1] / "jmeshtex" / "fl" / "weights"


@dataclasses.dataclass(frozen=True)
class Toy(ConfigBase):
    """A config exercising every kind of rule and field the mechanism handles."""

    steps: int = 10
    lr: float = 0.1
    widths: tuple[int, int] = (4, 8)
    up: tuple[float, float, float] | None = (0.0, 0.0, 1.0)
    mode: str = "a"
    lo: float = 0.0
    hi: float = 1.0

    _RULES = (
        integers("steps", 1),
        rule("lr", lambda x: x > 0, "> 0"),
        rule(
            "widths",
            lambda w: len(w) == 2 and all(is_int(x) and x >= 1 for x in w),
            "two positive integers",
        ),
        rule(
            "mode",
            lambda x: x in ("a", "b"),
            "'a' or 'b'",
            message="mode must be {must}, got {value!r}",
        ),
        cross_rule(lambda c: c.lo <= c.hi, "{cls} needs lo <= hi, got {c.lo}, {c.hi}"),
        cross_rule(
            lambda c: c.widths[0] <= c.widths[1],
            lambda c: f"widths {c.widths} must not shrink, {{literal}}",
        ),
    )


@dataclasses.dataclass(frozen=True)
class Terse(ConfigBase):
    """A config with its own wording of field rules (``_MESSAGE``)."""

    a: int = 1
    b: int = 1

    _MESSAGE = "{name} must be {must}, got {value}"
    _RULES = (rule("a b", lambda x: x >= 1, ">= 1"),)


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"steps": 0}, "Toy.steps must be an integer >= 1, got 0"),
        ({"steps": True}, "Toy.steps must be an integer >= 1, got True"),
        ({"lr": -1.0}, "Toy.lr must be > 0, got -1.0"),
        ({"widths": (4, 0)}, "Toy.widths must be two positive integers, got (4, 0)"),
        ({"mode": "c"}, "mode must be 'a' or 'b', got 'c'"),
        ({"lo": 2.0}, "Toy needs lo <= hi, got 2.0, 1.0"),
        # a callable message is used as it is (its braces are not a template)
        ({"widths": (8, 4)}, "widths (8, 4) must not shrink, {literal}"),
    ],
)
def test_a_broken_rule_raises_config_error_with_its_message(changes, message):
    with pytest.raises(ConfigError) as err:
        Toy(**changes)
    assert str(err.value) == message
    assert isinstance(err.value, ValueError)  # ConfigError is also a ValueError


def test_rules_run_in_order_and_the_first_broken_one_is_reported():
    with pytest.raises(ConfigError, match=r"^Toy\.steps "):
        Toy(steps=0, lr=-1.0, lo=5.0)
    with pytest.raises(ConfigError, match=r"^Toy\.lr "):
        Toy(lr=-1.0, lo=5.0)
    with pytest.raises(ConfigError, match="^b must be >= 1, got 0$"):
        Terse(b=0)


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"lr": "fast"}, "Toy.lr must be > 0, got 'fast'"),  # '>' between str and int: TypeError
        ({"widths": 5}, "Toy.widths must be two positive integers, got 5"),  # len(5): TypeError
        ({"lo": None}, "Toy needs lo <= hi, got None, 1.0"),
    ],
)
def test_a_wrongly_typed_value_gets_the_rules_message_not_a_builtin_error(changes, message):
    with pytest.raises(ConfigError) as err:
        Toy(**changes)
    assert str(err.value) == message


def test_a_cross_rule_sees_the_whole_config():
    assert Toy(lo=0.5, hi=0.5).lo == 0.5
    with pytest.raises(ConfigError, match=re.escape("Toy needs lo <= hi, got 0.6, 0.5")):
        Toy(lo=0.6, hi=0.5)


def test_json_round_trip_turns_tuples_into_lists_and_back():
    c = Toy(steps=3, widths=(2, 5), up=(1.0, 0.0, 0.0), mode="b")
    d = c.to_dict()
    assert d == {
        "steps": 3,
        "lr": 0.1,
        "widths": [2, 5],
        "up": [1.0, 0.0, 0.0],
        "mode": "b",
        "lo": 0.0,
        "hi": 1.0,
    }
    back = Toy.from_dict(json.loads(json.dumps(d)))
    assert back == c and isinstance(back.widths, tuple) and isinstance(back.up, tuple)
    assert Toy.from_dict(Toy(up=None).to_dict()).up is None  # Optional tuple: None stays None


def test_from_dict_fills_missing_keys_with_defaults():
    assert Toy.from_dict({}) == Toy()
    assert Toy.from_dict({"steps": 7}) == Toy(steps=7)


def test_from_dict_converts_lists_only_for_tuple_fields():
    # a list given for a non-tuple field is not silently turned into a tuple: the rule sees the list
    with pytest.raises(ConfigError, match=re.escape("mode must be 'a' or 'b', got ['a']")):
        Toy.from_dict({"mode": ["a"]})


def test_from_dict_rejects_unknown_keys_and_names_them():
    with pytest.raises(ConfigError) as err:
        Toy.from_dict({"steps": 2, "zeta": 1, "alpha": 2})
    assert str(err.value) == (
        "Toy: unknown fields ['alpha', 'zeta']; known: ['hi', 'lo', 'lr', 'mode', 'steps', 'up', 'widths']"
    )


def test_from_dict_names_unknown_keys_of_any_type():
    with pytest.raises(ConfigError, match=re.escape("unknown fields [1, 'zeta']")):
        Toy.from_dict({1: 2, "zeta": 3, "steps": 2})


def test_from_dict_rejects_a_non_mapping():
    with pytest.raises(ConfigError, match="Toy.from_dict needs a dict of fields"):
        Toy.from_dict([("steps", 2)])  # type: ignore[arg-type]


def test_from_dict_validates():
    with pytest.raises(ConfigError, match=re.escape("Toy.lr must be > 0, got 0")):
        Toy.from_dict({"lr": 0})


def test_replace_validates_and_rejects_unknown_fields():
    c = Toy()
    assert c.replace(steps=4) == Toy(steps=4) and c == Toy()  # frozen: the original is unchanged
    with pytest.raises(ConfigError, match=re.escape("Toy.steps must be an integer >= 1, got 0")):
        c.replace(steps=0)
    with pytest.raises(ConfigError, match=re.escape("Toy: unknown fields ['stpes']")):
        c.replace(stpes=4)


def test_configs_stay_hashable_and_comparable():
    # configs are jit static arguments and cache keys: equal configs hash equally
    assert hash(Toy()) == hash(Toy.from_dict(Toy().to_dict())) and Toy() != Toy(steps=2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        Toy().steps = 3  # type: ignore[misc]


def test_rule_needs_a_field_name():
    with pytest.raises(ConfigError, match="cross_rule"):
        rule("  ", lambda x: True, "anything")


def test_predicates():
    assert [is_int(x) for x in (0, -3, True, 1.0, "1", None)] == [
        True,
        True,
        False,
        False,
        False,
        False,
    ]
    checks = [is_finite_number(x) for x in (0, 2.5, float("nan"), float("-inf"), "1", None)]
    assert checks == [True, True, False, False, False, False]
    # NumPy integers are integers, NumPy bools are not; an int too large for a float is not finite
    assert is_int(np.int64(3)) and is_int(np.uint8(3)) and not is_int(np.bool_(True))
    assert is_int(5, 5) and not is_int(4, 5) and not is_int(np.int32(4), 5)
    assert is_finite_number(np.float32(0.5)) and not is_finite_number(np.float64("nan"))
    assert not is_finite_number(10**400) and not is_finite_number(True)


def test_numpy_scalars_and_lists_are_stored_as_plain_values():
    c = Toy(steps=np.int64(3), lr=np.float32(0.5), widths=[2, np.int32(3)], up=np.ones(3))
    assert c == Toy(steps=3, lr=0.5, widths=(2, 3), up=(1.0, 1.0, 1.0))
    assert type(c.steps) is int and type(c.lr) is float and type(c.widths[1]) is int
    json.dumps(c.to_dict())  # plain JSON, no NumPy scalar left
    hash(c)
    import jax.numpy as jnp

    zero_d = Toy(steps=np.array(4), lr=jnp.asarray(0.25, jnp.float32))
    assert zero_d == Toy(steps=4, lr=0.25) and type(zero_d.steps) is int


@pytest.mark.parametrize(
    "hint, good, bad",
    [
        (int, [0, -3, np.int16(2), 2**31 - 1], [2**31, True, 1.5, "1", None]),
        (float, [0, 2.5, np.float32(1.0)], [math.nan, math.inf, 10**400, True, "1", None]),
        (bool, [True, False], [1, 0, "True", None]),
        (str, ["", "a"], [1, None, b"a"]),
        (tuple[int, int], [(1, 2)], [(1,), (1, 2, 3), (1, 1.5), [1, 2], "12"]),
        (tuple[float, ...], [(), (1.0, 2)], [(math.nan,), ("a",), 1.0]),
        (float | tuple[float, ...] | None, [None, 1.0, (1.0,)], ["1", (None,)]),
    ],
)
def test_type_rule(hint, good, bad):
    assert all(type_ok(hint, v) for v in good), [v for v in good if not type_ok(hint, v)]
    assert not any(type_ok(hint, v) for v in bad), [v for v in bad if type_ok(hint, v)]


def test_a_huge_integer_is_shown_by_its_length_in_the_message():
    with pytest.raises(ConfigError) as err:
        Toy.from_dict({"steps": 10**400})
    # the range rule holds (it is >= 1); the type rule that follows bounds it
    assert (
        str(err.value) == "Toy.steps must be an integer below 2**31, got <an integer of 401 digits>"
    )
    with pytest.raises(
        ConfigError, match="must be a finite number, got <an integer of 401 digits>"
    ):
        Toy.from_dict({"hi": 10**400})


# --- every config of the library uses the mechanism -----------------------------------------------

ALL = [PrepareConfig, DGTSConfig, FLVAEConfig, FLDMConfig, MeshMatchConfig, SurfaceCNNConfig]
#: the study switches of each method (``Config.experimental``), sections of the configs above
SECTIONS = [DGTSExperimental, FLExperimental, FLDMExperimental, MeshMatchExperimental]
ALL += SECTIONS


def _fields(cls) -> list:
    """The fields of ``cls`` that hold values (its sections are checked as configs of their own)."""
    hints = typing.get_type_hints(cls)
    return [f for f in dataclasses.fields(cls) if hints[f.name] not in SECTIONS]


@pytest.mark.parametrize("cls", [c for c in ALL if c not in SECTIONS])
def test_each_section_is_the_experimental_field_of_one_method_config(cls):
    hints = typing.get_type_hints(cls)
    sections = {name: hint for name, hint in hints.items() if hint in SECTIONS}
    assert set(sections) <= {"experimental"}
    for section in sections.values():
        assert display_name(section) == display_name(cls).replace("Config", "Experimental")
        assert cls().experimental == section()  # the switches' defaults are the method's
        bad = _cases_of(section)[0]
        with pytest.raises(ConfigError):  # a section's rules hold through its config
            cls().replace(**{bad[1]: bad[2]})


@pytest.mark.parametrize("cls", ALL)
def test_library_configs_round_trip_through_json(cls):
    assert issubclass(cls, ConfigBase)
    c = cls()
    text = json.dumps(c.to_dict())
    assert cls.from_dict(json.loads(text)) == c
    assert cls.from_dict({}) == c
    with pytest.raises(
        ConfigError, match=f"^{re.escape(display_name(cls))}: unknown fields \\['bogus'\\]"
    ):
        cls.from_dict({"bogus": 1})


def test_tuple_valued_library_fields_come_back_as_tuples():
    c = MeshMatchConfig(shape_weight=(1.0, 2.0), up=(0.0, 1.0, 0.0))
    back = MeshMatchConfig.from_dict(json.loads(json.dumps(c.to_dict())))
    assert back == c and back.shape_weight == (1.0, 2.0) and back.up == (0.0, 1.0, 0.0)
    assert MeshMatchConfig.from_dict({"shape_weight": 5.0}).shape_weight == 5.0
    s = SurfaceCNNConfig(layers=("relu1_1", "pool1"))
    assert SurfaceCNNConfig.from_dict(json.loads(json.dumps(s.to_dict()))) == s
    f = FLDMConfig.tiny()
    assert FLDMConfig.from_dict(json.loads(json.dumps(f.to_dict()))).widths == (16, 32)


#: the fl.Config dict the previous shipped FL-VAE (600 steps, until this round) embedded in its weights
#: file, as written before the training-data and loss options existed (field names already migrated)
_OLD_FL_CONFIG = {
    "latent_dim": 8,
    "num_samples": 64,
    "features": 32,
    "num_heads": 4,
    "num_blocks": 2,
    "decoder_features": 64,
    "decoder_layers": 5,
    "decoder": "log",
    "kl_weight": 0.01,
    "log_sigma_max": 2.0,
    "delta": 1e-06,
    "min_vertices": 64,
    "max_vertices": 192,
    "max_image_size": 256,
    "meshes_per_image": 8,
    "batch_size": 2,
    "steps": 600,
    "learning_rate": 0.002,
    "final_lr_fraction": 0.05,
    "warmup_steps": 50,
    "grad_clip": 1.0,
    "checkpoint_every": 50,
    "encode_chunk": 2048,
}


def test_config_dicts_written_before_the_refactor_still_load():
    config = FLVAEConfig.from_dict(_OLD_FL_CONFIG)
    written = config.to_dict()
    # today's to_dict writes the very same values for every stored field ...
    assert {k: v for k, v in written.items() if k in _OLD_FL_CONFIG} == _OLD_FL_CONFIG
    # ... and fields added since (the training-data and loss options) take their defaults, which are
    # the recipe that model was trained with (e.g. loss_normalization="mean")
    added = set(written) - set(_OLD_FL_CONFIG)
    assert added and all(written[k] == FLVAEConfig().to_dict()[k] for k in added), added
    assert written["loss_normalization"] == "mean"


@pytest.mark.parametrize("name", ["fl_vae.npz", "fl_vae_barycentric.npz"])
def test_shipped_weights_store_every_config_field(name):
    # the shipped weights embed the complete fl.Config dict of their training run, read back exactly
    from jmeshtex.io import load_model

    stored = load_model(
        WEIGHTS / name, kind="jmeshtex.fl.Model", format_versions=(FL_FORMAT_VERSION,)
    ).config
    assert set(stored) == set(FLVAEConfig().to_dict())
    assert FLVAEConfig.from_dict(stored).to_dict() == stored


@pytest.mark.parametrize(
    "make, message",
    [
        # messages asserted elsewhere in the suite, word for word
        (
            lambda: DGTSConfig(min_features=64, max_features=32),
            "need min_features <= max_features, got 64, 32",
        ),
        (lambda: PrepareConfig(levels=0), "dgts.PrepareConfig.levels must be >= 1, got 0"),
        (
            lambda: FLVAEConfig(decoder="bary"),
            "decoder must be one of ('log', 'barycentric'), got 'bary'",
        ),
        (
            lambda: FLVAEConfig(features=10, num_heads=4),
            "features (10) must be divisible by num_heads (4)",
        ),
        (
            lambda: FLDMConfig(widths=(4,)),
            "widths must be two positive integers (fine, coarse), got (4,)",
        ),
        (lambda: FLDMConfig(diffusion_steps=1), "diffusion_steps must be >= 2"),
        (
            lambda: MeshMatchConfig(color_weight=-1.0),
            "meshmatch.Config.color_weight must be finite and >= 0, got (-1.0,)",
        ),
        (
            lambda: MeshMatchConfig(shape_weight=(1.0, -1.0)),
            "meshmatch.Config.shape_weight must be finite and >= 0, got (1.0, -1.0)",
        ),
        (
            lambda: MeshMatchConfig(color_weight=0.0, shape_weight=(0.0, 0.0)),
            "color_weight and shape_weight are all 0: the patch distance would be constant",
        ),
        (
            lambda: SurfaceCNNConfig(init_low=0.5, init_high=0.2),
            "surfacecnn.Config needs 0 <= init_low <= init_high <= 1, got 0.5, 0.2",
        ),
        (
            lambda: SurfaceCNNConfig(size=True),
            "surfacecnn.Config.size must be an integer >= 4, got True",
        ),
    ],
)
def test_library_messages_are_unchanged(make, message):
    with pytest.raises(ConfigError) as err:
        make()
    assert str(err.value) == message


# --- every field of every library config rejects values of the wrong kind -------------------------

#: one object per kind of nonsense; a field's bad values are chosen by identity from these
NAN, INF, NINF, HUGE = math.nan, math.inf, -math.inf, 10**400
HALF, ONE, TRUE, NONE = 1.5, 1, True, None
DIGITS, WORD, LIST, DICT = "8", "yes", [1], {"a": 1}
NAN3, DIGITS3, ONE_TUPLE, EMPTY = (NAN, NAN, NAN), ("8", "8", "8"), (1,), ()
NONSENSE = (NAN, INF, NINF, HUGE, HALF, ONE, TRUE, NONE, DIGITS, WORD, LIST, DICT)
RAGGED = [[1], [1, 2]]  # numpy cannot even make an array of it
NONSENSE += (NAN3, DIGITS3, ONE_TUPLE, EMPTY, RAGGED)


def _bad_for(hint) -> list:
    """The values of ``NONSENSE`` that no value of annotation ``hint`` may take, from the type alone."""
    bad = _bad_for_kinds(hint)
    return bad if any(v is RAGGED for v in bad) else [*bad, RAGGED]


def _bad_for_kinds(hint) -> list:
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        bads = [_bad_for_kinds(a) for a in typing.get_args(hint)]
        return [v for v in bads[0] if all(any(v is b for b in other) for other in bads[1:])]
    tuples = (NAN3, DIGITS3, ONE_TUPLE, EMPTY)
    if hint is type(None):
        return [v for v in NONSENSE if v is not None]
    if hint is int:
        return [NAN, INF, NINF, HUGE, HALF, TRUE, NONE, DIGITS, WORD, LIST, DICT, *tuples]
    if hint is float:
        return [NAN, INF, NINF, HUGE, TRUE, NONE, DIGITS, WORD, LIST, DICT, *tuples]
    if hint is bool:
        return [NAN, HUGE, HALF, ONE, NONE, DIGITS, WORD, LIST, DICT, *tuples]
    if hint is str:
        return [NAN, INF, HUGE, HALF, ONE, TRUE, NONE, LIST, DICT, *tuples]
    if origin is tuple:
        args = typing.get_args(hint)
        variadic = len(args) == 2 and args[1] is Ellipsis
        element_bad = _bad_for_kinds(args[0])
        out = [NAN, INF, NINF, HUGE, HALF, ONE, TRUE, NONE, DIGITS, WORD, DICT]
        # a list is read as a tuple: [1] is (1,)
        for t, given in [*((t, t) for t in tuples), (ONE_TUPLE, LIST)]:
            wrong_length = not variadic and len(t) != len(args)
            if wrong_length or any(any(x is b for b in element_bad) for x in t):
                out.append(given)
        return out
    raise AssertionError(f"no bad values known for {hint!r}: extend _bad_for")


def _cases_of(cls) -> list[tuple]:
    hints = typing.get_type_hints(cls)
    return [(cls, f.name, v) for f in _fields(cls) for v in _bad_for(hints[f.name])]


def _cases():
    for cls in ALL:
        for _, name, value in _cases_of(cls):
            yield pytest.param(
                cls, name, value, id=f"{cls.__module__}.{cls.__name__}.{name}={value!r:.20}"
            )


@pytest.mark.parametrize("cls, name, value", list(_cases()))
def test_every_field_of_every_config_rejects_nonsense(cls, name, value):
    with pytest.raises(ConfigError):
        cls(**{name: value})
    with pytest.raises(ConfigError):
        cls.from_dict({name: value})


def test_the_nonsense_table_covers_every_field_with_several_values():
    counts = {
        (cls.__name__, f.name): len(_bad_for(typing.get_type_hints(cls)[f.name]))
        for cls in ALL
        for f in _fields(cls)
    }
    assert min(counts.values()) >= 5, counts


@pytest.mark.parametrize("cls", ALL)
def test_defaults_and_presets_validate(cls):
    names = ("official", "paper", "small", "cpu", "tiny", "intrinsic")
    presets = [getattr(cls, p, None) for p in names]
    for make in [cls, *[p for p in presets if callable(p)]]:
        c = make()
        assert cls.from_dict(json.loads(json.dumps(c.to_dict()))) == c


@pytest.mark.parametrize(
    "cls, changes",
    [
        (DGTSConfig, {"eps": 0.0}),
        (DGTSConfig, {"eps": -1e-5}),
        (DGTSConfig, {"negative_slope": -0.1}),
        (DGTSConfig, {"negative_slope": 1.0}),
        (DGTSConfig, {"reconstruction_start": -1}),
        (DGTSConfig, {"official_axes": 1}),
        (SurfaceCNNConfig, {"content_layer": ""}),
        (FLDMConfig, {"widths": (16, np.bool_(True))}),
    ],
)
def test_fields_that_had_no_rule_now_have_one(cls, changes):
    with pytest.raises(ConfigError):
        cls(**changes)


def test_a_json_list_or_a_string_number_is_a_config_error():
    with pytest.raises(ConfigError, match="needs a dict of fields"):
        FLVAEConfig.from_dict(json.loads("[1, 2]"))
    with pytest.raises(ConfigError, match="latent_dim must be an integer below 2\\*\\*31, got '8'"):
        FLVAEConfig.from_dict(json.loads('{"latent_dim": "8"}'))
    for cls in ALL:
        if "steps" in {f.name for f in dataclasses.fields(cls)}:
            with pytest.raises(ConfigError):
                cls.from_dict({"steps": 10**400})


@pytest.mark.parametrize(
    "text, message",
    [
        ("[1, 2]", "must hold a JSON object of fl.Config fields, got a list"),
        ('{"latent_dim": "8"}', "latent_dim must be an integer below 2**31, got '8'"),
        ('{"steps": 1e400}', "steps must be an integer below 2**31, got inf"),
    ],
)
def test_fl_train_config_file_with_nonsense_is_a_one_line_error(tmp_path, capsys, text, message):
    from jmeshtex.cli import main

    config = tmp_path / "config.json"
    config.write_text(text)
    rc = main(["fl", "train", "--out", str(tmp_path / "out"), "--config", str(config), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2 and message in err and "Traceback" not in err, err


#: numeric fields where a negative value is meaningful
_NEGATIVE_OK = {
    ("fl.Config", "log_sigma_max"),
    ("fl.Experimental", "log_sigma_init"),
}  # log σ values


def _numeric(hint) -> bool:
    args = (
        typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, types.UnionType) else ()
    )
    return hint in (int, float) or int in args or float in args


@pytest.mark.parametrize(
    "cls, name",
    [
        (cls, f.name)
        for cls in ALL
        for f in _fields(cls)
        if _numeric(typing.get_type_hints(cls)[f.name])
        and (display_name(cls), f.name) not in _NEGATIVE_OK
    ],
)
def test_every_numeric_field_has_a_range(cls, name):
    # counts, sizes, rates, weights and factors are all >= 0: -1 breaks a range rule, not the type rule
    with pytest.raises(ConfigError) as err:
        cls(**{name: -1})
    assert "below 2**31" not in str(err.value) and "finite number," not in str(err.value)


@pytest.mark.parametrize(
    "changes", [{"content_layer": "bogus"}, {"layers": ("relu1_1", "relu9_9")}, {"layers": ()}]
)
def test_surfacecnn_layer_names_are_vgg_layers(changes):
    with pytest.raises(ConfigError, match="VGG layer name"):
        SurfaceCNNConfig(**changes)
    assert SurfaceCNNConfig(layers=("conv5_4", "relu1_1", "pool5")).layers[0] == "conv5_4"


# --- sections: a nested config (a method's ``experimental`` switches) --------------------------------


@dataclasses.dataclass(frozen=True)
class Switches(ConfigBase):
    """A section: study switches with their own rules."""

    shift: float = 1.0
    sizes: tuple[int, ...] = (1, 2)

    _RULES = (rule("shift", lambda x: x > 0, "> 0"),)


@dataclasses.dataclass(frozen=True)
class Run(ConfigBase):
    """A config with a section in the middle of its fields."""

    steps: int = 10
    switches: Switches = Switches()
    width: int = 4

    _RESUMABLE = frozenset({"steps", "shift"})
    _RULES = (cross_rule(lambda c: c.switches.shift < c.width, "shift must stay below width"),)


@dataclasses.dataclass(frozen=True)
class Flat(ConfigBase):
    """``Run`` as it was before its switches moved into a section."""

    steps: int = 10
    shift: float = 1.0
    sizes: tuple[int, ...] = (1, 2)
    width: int = 4

    _RESUMABLE = frozenset({"steps", "shift"})


@pytest.mark.parametrize(
    "changes", [{}, {"shift": 2.5}, {"sizes": (3,), "width": 9}, {"steps": 7, "shift": 0.5}]
)
def test_a_section_writes_the_same_dict_and_fingerprint_as_the_flat_config_it_replaced(changes):
    run, flat = Run().replace(**changes), Flat(**changes)
    assert run.to_dict() == flat.to_dict()
    assert list(run.to_dict()) == ["steps", "shift", "sizes", "width"]  # the section in its place
    assert run.fingerprint() == flat.fingerprint() and "shift" not in run.fingerprint()
    assert Run.from_dict(flat.to_dict()) == run
    assert Run.from_dict(json.loads(json.dumps(run.to_dict()))) == run


def test_a_section_field_is_set_by_its_name_its_dotted_path_or_the_whole_section():
    want = Run(switches=Switches(shift=2.0))
    assert Run().replace(shift=2.0) == want
    assert Run().replace(**{"switches.shift": 2.0}) == want
    assert Run().replace(switches=Switches(shift=2.0)) == want
    assert Run().replace(switches={"shift": 2.0}) == want
    assert Run(switches={"shift": 2.0}) == want
    assert Run.from_dict({"shift": 2.0}) == want
    assert Run.from_dict({"switches.shift": 2.0}) == want
    assert Run.from_dict({"switches": {"shift": 2.0}}) == want
    # a name changes one field: the rest of the section is kept
    two = Run().replace(sizes=[5, 6]).replace(shift=3.0)
    assert two.switches == Switches(shift=3.0, sizes=(5, 6)) and two.switches.sizes == (5, 6)
    # a whole section and a name of one of its fields: the name wins, the rest from the section
    both = Run.from_dict({"switches": {"sizes": [7]}, "shift": 0.5})
    assert both.switches == Switches(shift=0.5, sizes=(7,))
    assert hash(want) == hash(Run().replace(shift=2.0)) and len({want, Run(), want}) == 2


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: Run().replace(shift=0.0), "Switches.shift must be > 0, got 0.0"),
        (lambda: Run.from_dict({"switches.shift": -1}), "Switches.shift must be > 0, got -1"),
        (lambda: Run(switches={"shift": "x"}), "Switches.shift must be > 0, got 'x'"),
        (lambda: Run().replace(shift=5.0), "shift must stay below width"),
        (
            lambda: Run(switches=Flat()),
            "Run.switches must be a Switches (or a dict of its fields), got Flat(",
        ),
        (lambda: Run(switches=None), "Run.switches must be a Switches (or a dict of its fields)"),
        (
            lambda: Run().replace(shfit=2.0),
            "Run: unknown fields ['shfit']; known: ['shift', 'sizes', 'steps', 'width']",
        ),
        (lambda: Run.from_dict({"switches.bogus": 1}), "Switches: unknown fields ['bogus']"),
        (lambda: Run.from_dict({"width.shift": 1}), "Run: unknown fields ['width.shift']"),
        (lambda: Run.from_dict({"switches": {"bogus": 1}}), "Switches: unknown fields ['bogus']"),
    ],
)
def test_a_section_is_refused_with_a_message_naming_the_field(make, message):
    with pytest.raises(ConfigError) as err:
        make()
    assert str(err.value).startswith(message), str(err.value)


@dataclasses.dataclass(frozen=True)
class Clash(ConfigBase):
    """A section field named like a field of the config: refused (the flat names would clash)."""

    shift: float = 1.0
    switches: Switches = Switches()


def test_a_section_field_named_like_another_field_is_refused():
    with pytest.raises(ConfigError, match="'shift' occurs twice"):
        Clash()
    assert flat_names(Run) == ("steps", "shift", "sizes", "width")


def test_a_stored_config_lacking_a_section_field_is_refused():
    stored = Run().to_dict()
    assert stored_config(Run, stored, "m.npz") == Run()
    del stored["sizes"]
    with pytest.raises(ConfigError, match=r"m.npz: its stored Run lacks fields \['sizes'\]"):
        stored_config(Run, stored, "m.npz")


# --- what a config writes stays the same for the same values ------------------------------------------

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: sha256 (first 16 hex digits) of ``json.dumps(d, sort_keys=True)`` for ``d`` the fingerprint and
#: the to_dict of each method's default config and presets, computed on main before the study
#: switches moved into ``experimental`` sections: checkpoints and model files written before keep
#: loading and resuming
PINNED = {
    "fl": {
        "__init__": ("ec5ac7bb8ed1a165", "c4ae774675b20047"),
        "paper": ("8d20184db973292a", "4dac6f84f7a51971"),
        "small": ("7b664e2b064e97c3", "154d0e7cbd0b97f6"),
    },
    "fldm": {
        "__init__": ("eb6bc929f31a043b", "4ac7af7301096c33"),
        "paper": ("cea85ad7e71d311e", "5621602ee6b53b36"),
        "cpu": ("dfb975cffdd01bdd", "b237a9ed75b95d53"),
        "tiny": ("110e8cfabcf4f5df", "eaebbf78f4fa7d50"),
        "demo": ("b28589f590b7f79e", "6bef817857263fc0"),
    },
    "meshmatch": {"__init__": ("cc0d7bf8e1ad1f33", "cc0d7bf8e1ad1f33")},
    "surfacecnn": {
        "__init__": ("82dfa5dc4fb9e26d", "c03f17acfa91dfd3"),
        "paper": ("8923bbacd2594412", "fd8e7914ddb5cb29"),
        "cpu": ("82dfa5dc4fb9e26d", "c03f17acfa91dfd3"),
        "tiny": ("30e5aef6ce63de9c", "d65a414fb70d236d"),
    },
    "dgts": {
        "__init__": ("02d26aa8e23476dd", "92fb9f84f8135ce7"),
        "tiny": ("c877ef8fdd195be2", "59eb2f53cc124837"),
    },
}


#: fields added after the pin, at their defaults: compared here without them (the surface CNN's
#: frame smoothing is in its fingerprint, so checkpoints of unknown frames are refused)
ADDED_SINCE_PIN = {"surfacecnn": {"frame_smoothing": 4.0}}


def _digest(d: dict) -> str:
    import hashlib

    return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


@pytest.mark.parametrize(
    "method, preset", [(m, p) for m, presets in PINNED.items() for p in presets]
)
def test_fingerprints_and_stored_configs_are_unchanged(method, preset):
    import importlib

    cls = importlib.import_module(f"jmeshtex.{method}").Config
    config = cls() if preset == "__init__" else getattr(cls, preset)()
    fingerprint, stored = config.fingerprint(), config.to_dict()
    added = ADDED_SINCE_PIN.get(method, {})
    assert {k: stored.pop(k) for k in added} == added
    assert {k: fingerprint.pop(k) for k in added} == added
    assert (_digest(fingerprint), _digest(stored)) == PINNED[method][preset]
    assert list(config.to_dict()) == list(flat_names(cls))


def _committed_models() -> list[pathlib.Path]:
    """Every ``.npz`` in the repository whose header says it is a jmeshtex model."""
    from jmeshtex.io._model_file import HEADER

    found = []
    for path in sorted(ROOT.glob("**/*.npz")):
        if ".venv" in path.parts or "runs" in path.parts:
            continue
        with np.load(path) as z:
            if HEADER in z.files:
                found.append(path.relative_to(ROOT))
    return found


def test_the_committed_model_files_are_found():
    names = {str(p) for p in _committed_models()}
    assert {
        "jmeshtex/fl/weights/fl_vae.npz",
        "jmeshtex/fl/weights/fl_vae_barycentric.npz",
        "jmeshtex/dgts/weights/knobs.npz",
        "jmeshtex/fldm/weights/spot/model.npz",
    } <= names, names


@pytest.mark.parametrize("rel", _committed_models(), ids=str)
def test_every_committed_model_file_loads_with_its_stored_config(rel):
    import importlib

    from jmeshtex.io._model_file import HEADER

    path = ROOT / rel
    with np.load(path) as z:
        header = json.loads(str(z[HEADER]))
    method = importlib.import_module(header["kind"].rsplit(".", 1)[0])
    model = method.load(path if method.__name__ != "jmeshtex.fldm" else path.parent)
    written = model.config.to_dict()
    assert written == header["config"]  # every field stored, read back as stored


def test_the_fl_config_repr_is_unchanged():
    # the FLDM copies' cache names its encoder by the FL-VAE config's repr (fldm.fl_vae_encoder):
    # the flat repr keeps the caches of runs in progress valid (hashes computed before the move)
    from jmeshtex.fl import load_pretrained

    configs = [FLVAEConfig(), FLVAEConfig.small()]
    configs += [load_pretrained(decoder=d).config for d in ("log", "barycentric")]
    want = ["ec0f9ce7013923cc", "1d8ae3dde7317d99", "9158dd451d658af1", "0d81f6336cb55fd9"]
    assert [_digest_text(repr(c)) for c in configs] == want
    assert repr(FLVAEConfig()).startswith("Config(latent_dim=8, num_samples=64,")


def _digest_text(text: str) -> str:
    import hashlib

    return hashlib.sha256(text.encode()).hexdigest()[:16]


_SECTIONED_MODULE = """
from __future__ import annotations

import dataclasses

from jmeshtex._config import ConfigBase


@dataclasses.dataclass(frozen=True)
class Knobs(ConfigBase):
    shift: float = 1.0


@dataclasses.dataclass(frozen=True)
class Job(ConfigBase):
    width: int = 8
    knobs: Knobs = Knobs()
"""


def test_a_second_copy_of_a_config_module_leaves_the_first_ones_section_type(tmp_path, monkeypatch):
    # pytest --import-mode=importlib runs a module file of the doctests a second time under its
    # own name, so sys.modules names the copy when the first module's config is first built
    import importlib
    import importlib.util
    import sys

    (tmp_path / "h59_sectioned.py").write_text(_SECTIONED_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    first = importlib.import_module("h59_sectioned")
    spec = importlib.util.spec_from_file_location("h59_sectioned", first.__file__)
    copy = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "h59_sectioned", copy)
    spec.loader.exec_module(copy)
    assert copy.Knobs is not first.Knobs
    assert first.Job(shift=2.0).knobs == first.Knobs(shift=2.0)
    assert copy.Job(shift=3.0).knobs == copy.Knobs(shift=3.0)
    with pytest.raises(ConfigError, match=r"Job.knobs must be a Knobs"):
        first.Job(knobs=copy.Knobs())


def test_the_constructor_takes_a_section_field_by_its_name():
    assert Run(shift=2.0, width=5) == Run(switches=Switches(shift=2.0), width=5)
    assert Run(**{"switches.sizes": [3]}).switches.sizes == (3,)
    with pytest.raises(ConfigError, match=r"Run: unknown fields \['shfit'\]"):
        Run(shfit=2.0)
    with pytest.raises(TypeError):  # a config without sections keeps the dataclass's own check
        Flat(bogus=1)

"""DGTS configuration: the reference code's width schedule, JSON round trip, typed errors."""

from __future__ import annotations

import pytest

from jmeshtex import ConfigError
from jmeshtex.dgts import Config, PrepareConfig


def test_width_schedule_matches_the_reference_code():
    c = Config()
    # reference num_fe: max(min(32·2^l, 128) // 2^(i-1), 32) for i = 1..5, then 3 (G) or 1 (D)
    assert c.level_features(0, generator=True) == (32, 32, 32, 32, 32, 3)
    assert c.level_features(1, generator=True) == (64, 32, 32, 32, 32, 3)
    assert c.level_features(2, generator=False) == (128, 64, 32, 32, 32, 1)
    assert c.level_features(5, generator=True) == c.level_features(2, generator=True)


def test_paper_defaults():
    c = Config()
    assert (c.learning_rate, c.beta1, c.beta2, c.reconstruction_weight, c.penalty_weight) == (
        5e-4,
        0.5,
        0.99,
        5.0,
        0.1,
    )
    assert (
        c.discriminator_steps,
        c.generator_steps,
        c.learning_rate_decay,
        c.learning_rate_decay_every,
    ) == (2, 3, 0.5, 500)
    assert c.steps == 2000


@pytest.mark.parametrize("cls", [PrepareConfig, Config])
def test_json_round_trip(cls):
    c = cls(steps=7, learning_rate=0.25)
    assert cls.from_dict(c.to_dict()) == c and c != cls()


@pytest.mark.parametrize("cls", [PrepareConfig, Config])
def test_shared_field_names_and_no_seed(cls):
    names = set(cls().to_dict())
    assert {"steps", "learning_rate"} <= names
    assert not names & {
        "seed",
        "iterations",
        "lr",
        "num_levels",
    }  # randomness is the functions' key=


@pytest.mark.parametrize(
    "make",
    [
        lambda: Config(num_layers=2),
        lambda: Config(min_features=64, max_features=32),
        lambda: Config(learning_rate_decay=0.0),
        lambda: Config(generator_steps=0),
        lambda: Config(steps=-1),
        lambda: Config(learning_rate=0.0),
        lambda: PrepareConfig(levels=0),
        lambda: PrepareConfig(steps=-1),
        lambda: PrepareConfig(learning_rate=-1.0),
        lambda: PrepareConfig(weight_s2t=-1.0),
        lambda: Config.from_dict({"no_such_field": 1}),
        lambda: Config.from_dict({"seed": 0}),
    ],
)
def test_bad_values_raise_config_error(make):
    with pytest.raises(ConfigError):
        make()

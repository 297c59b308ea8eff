"""``jmeshtex meshmatch`` flags -> :class:`jmeshtex.meshmatch.Config` (the aligned default,
``--no-aligned`` for the pose-free features, the propagation option)."""

from __future__ import annotations

import argparse

import pytest

from jmeshtex import ConfigError, InputError
from jmeshtex.cli import _meshmatch


def _config(*flags, action="transfer"):
    parser = argparse.ArgumentParser()
    _meshmatch.register(parser.add_subparsers())
    inputs = (
        ["--source", "s", "--target", "t"]
        if action == "transfer"
        else ["--mesh", "m", "--mask", "k.npy"]
    )
    args = parser.parse_args(["meshmatch", action, *inputs, "--out", "o", *flags])
    return _meshmatch._config(args, aligned=action != "paint")


def test_the_default_is_aligned_and_no_aligned_is_intrinsic():
    from jmeshtex.meshmatch import Config

    assert _config() == Config()
    assert _config().aligned
    assert _config("--no-aligned") == Config.intrinsic()
    c = _config("--no-aligned", "--up", "y", "--side", "z")
    assert (c.aligned, c.up_vector(), c.side_vector()) == (False, (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    c = _config("--position-weight", "4", "--normal-weight", "1", "--propagation", "sequential")
    assert (
        c.normal_axes()["position_weight"],
        c.normal_axes()["normal_weight"],
        c.propagation,
    ) == (4.0, 1.0, "sequential")
    c = _config("--vote", "fan", "--upsample", "offset")
    assert (
        (c.vote, c.upsample) == ("fan", "offset")
        and _config().vote == "ring"
        and _config().upsample == "copy"
    )


def test_pose_free_flags_without_no_aligned_are_refused():
    with pytest.raises(InputError, match="--no-aligned"):
        _config("--up", "y")
    with pytest.raises(InputError, match="--no-aligned"):
        _config("--aligned", "--side", "x")
    with pytest.raises(ConfigError, match="aligned=True"):
        _config("--no-aligned", "--position-weight", "8")


def test_paint_defaults_to_the_intrinsic_features():
    from jmeshtex.meshmatch import Config

    assert _config(action="paint") == Config.intrinsic()
    assert _config("--up", "y", action="paint").up_vector() == (0.0, 1.0, 0.0)
    assert _config("--aligned", action="paint") == Config()

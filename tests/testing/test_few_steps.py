"""The suite's ``few_steps`` marker (``conftest.py``): a marked module's fixtures and tests build
their loop programs as the programs that run once (level 0 per compilation); an unmarked test keeps the loops' full level
(``tests/test_jit.py::test_the_suite_compiles_its_loops_fully``)."""

from __future__ import annotations

import pathlib

import pytest

from jmeshtex import _jit

pytestmark = pytest.mark.few_steps


@pytest.fixture(scope="module")
def options_in_a_module_fixture():
    return {"loop": _jit.loop_options(), "once": _jit._OPTIONS["once"]}


def test_a_marked_module_s_fixtures_and_tests_compile_their_loops_at_the_quick_level(
    options_in_a_module_fixture,
):
    once = options_in_a_module_fixture["once"]
    assert once["xla_backend_optimization_level"] == 0
    assert options_in_a_module_fixture == {"loop": once, "once": once}
    assert _jit.loop_options() == once


def _root_conftest(config: pytest.Config):
    """The repository's ``conftest.py`` as pytest loaded it (a plugin; importing it again would run
    it twice)."""
    root = config.rootpath / "conftest.py"
    return next(
        p
        for p in config.pluginmanager.get_plugins()
        if getattr(p, "__file__", None) and pathlib.Path(p.__file__) == root
    )


def test_the_loops_full_level_is_restored_after_a_marked_test(request):
    """A marked test's fixture restores what it found (here: the module's setting, itself set over
    the suite's full level)."""
    conftest = _root_conftest(request.config)
    once = _jit._OPTIONS["once"]
    with conftest._quick_level_loops():
        assert _jit.loop_options() == once
    assert _jit.loop_options() == once  # the module's own setting, still in force
    before = _jit.set_compiler_options(once=once, loop=_jit.FULL_OPTIMISATION)
    try:
        with conftest._quick_level_loops():
            assert _jit.loop_options() == once
        assert _jit.loop_options() == _jit.FULL_OPTIMISATION
    finally:
        _jit.set_compiler_options(**before)

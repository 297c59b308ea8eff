"""``jmeshtex._jit``: plain ``jax.jit`` unless the process sets options per kind of program (the test
suite does, in ``conftest.py``), with the values of plain ``jax.jit`` either way."""

from __future__ import annotations

import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import _jit
from jmeshtex._jit import FAST_COMPILE, FULL_OPTIMISATION, jit_loop, jit_once, set_compiler_options


def _f(x, *, power: int = 2):
    return jnp.sum(jnp.sin(x) ** power)


@pytest.fixture(params=[None, FAST_COMPILE, FULL_OPTIMISATION], ids=["plain", "fast", "full"])
def options(request):
    """Both kinds compiled with these options (None: plain jax.jit), restored afterwards."""
    before = set_compiler_options(once=request.param, loop=request.param)
    yield request.param
    set_compiler_options(**before)


@pytest.mark.parametrize("wrap", [jit_once, jit_loop])
def test_values_match_plain_jit_at_top_level_and_inside_transforms(wrap, options):
    x = jnp.linspace(0.0, 1.0, 7)
    fast, plain = wrap(_f, static_argnames="power"), jax.jit(_f, static_argnames="power")
    np.testing.assert_allclose(fast(x, power=3), plain(x, power=3), rtol=1e-12)
    # traced arguments (grad, vmap, an enclosing jit) take the plain jit, which accepts them
    np.testing.assert_allclose(jax.grad(fast)(x), jax.grad(plain)(x), rtol=1e-12)
    np.testing.assert_allclose(jax.vmap(fast)(x[:, None]), jax.vmap(plain)(x[:, None]), rtol=1e-12)
    np.testing.assert_allclose(jax.jit(fast)(x), plain(x), rtol=1e-12)
    # the decorator form, and lower() for ahead-of-time compilation
    decorated = wrap(static_argnames="power")(_f)
    assert float(decorated.lower(x, power=2).compile()(x)) == pytest.approx(float(plain(x)))


@pytest.mark.parametrize("wrap", [jit_once, jit_loop])
def test_without_options_the_decorators_are_jax_jit_itself(wrap):
    """No per-call wrapper (no argument flattening) and nothing over the user's XLA_FLAGS."""
    before = set_compiler_options()
    try:
        assert type(wrap(_f)) is type(jax.jit(_f))
    finally:
        set_compiler_options(**before)


def test_the_library_sets_no_options_of_its_own():
    """Importing the modules that jit loops and initialisers leaves the process's options unset:
    only a process owner (this suite's conftest.py) sets them."""
    code = (
        "import jmeshtex.fl, jmeshtex.fldm, jmeshtex.meshmatch, jmeshtex.surfacecnn, jmeshtex.dgts\n"
        "from jmeshtex import _jit, parallel\n"
        "print(_jit._OPTIONS)"
    )
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"} | {"JAX_PLATFORMS": "cpu"}
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "{'once': None, 'loop': None}"


@pytest.mark.parametrize("options", [FAST_COMPILE, FULL_OPTIMISATION], ids=["fast", "full"])
def test_every_option_is_one_xla_accepts(options):
    x = jnp.ones(3)
    lowered = jax.jit(_f).lower(x)
    assert float(lowered.compile(options)(x)) == pytest.approx(float(_f(x)))
    # a misspelt option is refused, so the line above would catch one
    with pytest.raises(Exception, match="xla_backend_optimisation_level"):
        lowered.compile({"xla_backend_optimisation_level": 0})


@pytest.mark.parametrize("loop", [None, FULL_OPTIMISATION], ids=["plain", "full"])
def test_the_training_driver_compiles_its_step_with_the_process_loop_options(monkeypatch, loop):
    from jmeshtex import _training

    monkeypatch.setitem(_jit._OPTIONS, "loop", loop)
    seen = []
    real = jax.stages.Lowered.compile

    def spy(self, compiler_options=None, **kw):
        seen.append(compiler_options)
        return real(self, compiler_options, **kw)

    monkeypatch.setattr(jax.stages.Lowered, "compile", spy)
    step = jax.jit(lambda s, b: (s + b, s))
    fn, seconds = _training._compiled_step(step, jnp.zeros(2), jnp.ones(2), {})
    assert seen == [loop] and seconds is not None
    np.testing.assert_array_equal(fn(jnp.zeros(2), jnp.ones(2))[0], [1.0, 1.0])


def test_the_suite_compiles_its_loops_fully():
    """This suite's trade-off (conftest.py): XLA_FLAGS lower everything, loops get the full level,
    programs that run once the quickest (level 0, per compilation)."""
    assert _jit.loop_options() == FULL_OPTIMISATION
    assert _jit._OPTIONS["once"]["xla_backend_optimization_level"] == 0

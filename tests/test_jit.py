"""``jmeshtex._jit``: programs compiled by how often they run, with the values of plain ``jax.jit``."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex._jit import FAST_COMPILE, FULL_OPTIMISATION, jit_loop, jit_once


def _f(x, *, power: int = 2):
    return jnp.sum(jnp.sin(x) ** power)


@pytest.mark.parametrize("wrap", [jit_once, jit_loop])
def test_values_match_plain_jit_at_top_level_and_inside_transforms(wrap):
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


@pytest.mark.parametrize("options", [FAST_COMPILE, FULL_OPTIMISATION], ids=["fast", "full"])
def test_every_option_is_one_xla_accepts(options):
    x = jnp.ones(3)
    lowered = jax.jit(_f).lower(x)
    assert float(lowered.compile(options)(x)) == pytest.approx(float(_f(x)))
    # a misspelt option is refused, so the line above would catch one
    with pytest.raises(Exception, match="xla_backend_optimisation_level"):
        lowered.compile({"xla_backend_optimisation_level": 0})


def test_the_training_driver_compiles_its_step_with_full_optimisation(monkeypatch):
    from jmeshtex import _training

    seen = []
    real = jax.stages.Lowered.compile

    def spy(self, compiler_options=None, **kw):
        seen.append(compiler_options)
        return real(self, compiler_options, **kw)

    monkeypatch.setattr(jax.stages.Lowered, "compile", spy)
    step = jax.jit(lambda s, b: (s + b, s))
    fn, seconds = _training._compiled_step(step, jnp.zeros(2), jnp.ones(2), {})
    assert seen == [FULL_OPTIMISATION] and seconds is not None
    np.testing.assert_array_equal(fn(jnp.zeros(2), jnp.ones(2))[0], [1.0, 1.0])

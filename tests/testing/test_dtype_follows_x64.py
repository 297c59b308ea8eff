"""Without x64 the harness checks in float32 against the float32 bound, and a float64 request is a
typed error naming the fix — never a float32 run judged by the float64 bound (a false alarm)."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import jax
import jax.numpy as jnp
import pytest

from jmeshtex import ConfigError
from jmeshtex.testing import Entry, Field, check, check_dtype

ROOT = pathlib.Path(__file__).resolve().parents[2]

SCRIPT = """
import jax, jax.numpy as jnp
from jmeshtex import ConfigError, ops
from jmeshtex.testing import Entry, Field, assert_equivariant, check

params = ops.init_field_conv(jax.random.key(0), 2, 3, hdim=4)
def apply(state, p, x):
    return Field("vertex_tangent", ops.field_conv(x, state.one_ring(), p))
entry = Entry("x64_off.conv", apply, {"x": ("vertex_tangent", 2)}, ("gauge",),
              init=lambda key, dtype: params)
r = check(entry, "gauge")
print("RESULT", r.dtype, r.tolerance, r.passed, r.error)
try:
    check(entry, "gauge", dtype=jnp.float64)
except ConfigError as e:
    print("REFUSED", e)
errors = assert_equivariant(lambda s, x: apply(s, params, x), 0, {"x": ("vertex_tangent", 2)},
                            transforms=("gauge",))
print("ASSERTED", errors["gauge"] < 1e-5)
"""


def test_without_x64_checks_run_in_float32_and_float64_is_refused(tmp_path):
    env = {k: v for k, v in os.environ.items() if not k.startswith("JAX_")}
    env["PYTHONPATH"] = str(ROOT)
    run = subprocess.run(
        [sys.executable, "-c", SCRIPT], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr[-3000:]
    lines = dict(line.split(" ", 1) for line in run.stdout.splitlines() if " " in line)
    dtype, tol, passed, error = lines["RESULT"].split()
    assert (dtype, float(tol), passed) == ("float32", 1e-5, "True")
    assert 0 < float(error) < 1e-5  # float32 round-off: the float64 bound would have failed it
    assert "jax_enable_x64" in lines["REFUSED"] and "dtype=None" in lines["REFUSED"]
    assert lines["ASSERTED"] == "True"


def test_with_x64_the_default_is_float64():
    assert jax.config.jax_enable_x64  # the suite's conftest turns it on
    assert check_dtype(None, "t").name == "float64"
    entry = Entry(
        "x64_on.double",
        lambda s, p, x: Field("vertex_scalar", 2 * x),
        {"x": ("vertex_scalar", 1)},
        ("rigid",),
    )
    result = check(entry, "rigid")
    assert result.dtype == "float64" and result.tolerance == 1e-10 and result.passed


def test_a_dtype_outside_the_bounds_is_refused():
    with pytest.raises(ConfigError, match="float32, float64 or None"):
        check_dtype(jnp.float16, "check")

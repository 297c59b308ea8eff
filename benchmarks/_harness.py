"""Shared benchmark harness: machine info, timing, ceilings measured in the same run, JSON + markdown.

Every benchmark script reports each figure next to a ceiling measured in the same process (matmul
GFLOP/s for compute-bound ops, copy bandwidth GB/s for memory-bound ones), warms up before timing,
calls ``block_until_ready`` and reports compile time apart from run time.

Usage in a script::

    from _harness import Report, Size, size_label, time_jax, time_host
    report = Report("ops_field_conv")
    size = Size(size_label(v), vertices=v)   # the label "30K" and the true count 30000
    report.add(name="field_conv fwd", size=size, seconds=t, flops=n, bound="flops")
    report.write()   # benchmarks/results/ops_field_conv.{json,md}

A row's ``size`` is a label for people; the runner (``python -m benchmarks``) fits and interpolates
over the count a row records in one of :data:`SIZE_UNITS` (``Size`` writes it), and parses the label
only for rows that record none.
"""

from __future__ import annotations

import dataclasses
import json
import operator
import os
import pathlib
import platform
import statistics
import sys
import time
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jmeshtex.io import atomic_write

RESULTS = pathlib.Path(__file__).resolve().parent / "results"

#: the count fields a row's size is recorded in (the runner's ``_SIZE_KEYS`` without its ``n``)
SIZE_UNITS = ("texels", "pixels", "vertices", "faces", "points")


def size_label(n: int) -> str:
    """A count as a short label: ``500``, ``1.5K``, ``20K``, ``1.2M``.

    Below 10 of a unit one decimal is kept; digits are truncated, never rounded, so a label never
    claims more than the count, and from 10K up a label reads as the scripts wrote it before this
    helper (``f"{n // 1000}K"``), so committed results keep their figures' names. The label is for
    people: record the count itself with :class:`Size`.

    Raises:
      TypeError: ``n`` is not an integer; ValueError: it is negative.

    Example:
      >>> [size_label(n) for n in (0, 500, 999, 1000, 1536, 20480, 327680, 1_234_567, 12_000_000)]
      ['0', '500', '999', '1K', '1.5K', '20K', '327K', '1.2M', '12M']
    """
    n = operator.index(n)
    if n < 0:
        raise ValueError(f"size_label: a count is not negative, got {n}")
    for unit, scale in (("M", 1_000_000), ("K", 1_000)):
        if n >= scale:
            whole, tenths = n // scale, n * 10 // scale % 10
            return f"{whole}.{tenths}{unit}" if whole < 10 and tenths else f"{whole}{unit}"
    return str(n)


class Size(str):
    """A row's size label that carries the true count it stands for.

    ``Report.add(size=Size("20K faces", faces=20480))`` writes the row with ``size="20K faces"`` and
    ``faces=20480``, so every row of a script records its count through the one line that builds
    the label. Exactly one count, named by one of :data:`SIZE_UNITS` (the quantity the figure's
    time grows with).

    Raises:
      TypeError: not exactly one count, an unknown unit, or a count that is not an integer.

    Example:
      >>> s = Size(f"{size_label(20480)} faces", faces=20480)
      >>> s, s.unit, s.count
      ('20K faces', 'faces', 20480)
    """

    unit: str
    count: int

    def __new__(cls, label: str, **count: int) -> Size:
        if len(count) != 1 or next(iter(count)) not in SIZE_UNITS:
            raise TypeError(
                f"Size({label!r}, ...): give exactly one count, one of {', '.join(SIZE_UNITS)} "
                f"(got {', '.join(count) or 'none'})"
            )
        ((unit, n),) = count.items()
        self = super().__new__(cls, label)
        self.unit, self.count = unit, operator.index(n)
        return self


def machine_info() -> dict[str, Any]:
    """Versions and machine facts printed at the top of every report."""
    import flax
    import optax

    return {
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "jax": jax.__version__,
        "jaxlib": jax.lib.__version__ if hasattr(jax.lib, "__version__") else "",
        "flax": flax.__version__,
        "optax": optax.__version__,
        "numpy": np.__version__,
        "devices": [str(d) for d in jax.devices()],
        "x64": bool(jax.config.jax_enable_x64),
    }


@dataclasses.dataclass
class Timing:
    compile_s: float
    run_s: float  # median over repeats
    runs: list[float]


def _block(x):
    return jax.tree.map(
        lambda a: a.block_until_ready() if hasattr(a, "block_until_ready") else a, x
    )


def time_jax(fn: Callable, *args, repeats: int = 5, min_time: float = 0.2) -> Timing:
    """Time a jitted callable: first call (compile + run) apart from the median of later calls."""
    t0 = time.perf_counter()
    _block(fn(*args))
    first = time.perf_counter() - t0
    runs: list[float] = []
    total = 0.0
    while len(runs) < repeats or (total < min_time and len(runs) < 50):
        t0 = time.perf_counter()
        _block(fn(*args))
        dt = time.perf_counter() - t0
        runs.append(dt)
        total += dt
    run = statistics.median(runs)
    return Timing(compile_s=max(first - run, 0.0), run_s=run, runs=runs)


def time_host(fn: Callable, *args, repeats: int = 3) -> Timing:
    """Time a host (NumPy) function: median of ``repeats`` calls after one warm-up call."""
    t0 = time.perf_counter()
    fn(*args)
    first = time.perf_counter() - t0
    runs = []
    for _ in range(max(repeats - 1, 0)):
        t0 = time.perf_counter()
        fn(*args)
        runs.append(time.perf_counter() - t0)
    runs = runs or [first]
    return Timing(compile_s=0.0, run_s=statistics.median(runs), runs=[first, *runs])


def matmul_ceiling(n: int = 2048, dtype=jnp.float32) -> float:
    """Achieved GFLOP/s of a jitted ``n×n @ n×n`` matmul on the default device (the compute ceiling)."""
    a = jnp.ones((n, n), dtype)
    b = jnp.ones((n, n), dtype)
    f = jax.jit(jnp.matmul)
    t = time_jax(f, a, b, repeats=5)
    return 2.0 * n**3 / t.run_s / 1e9


def bandwidth_ceiling(mbytes: int = 256) -> float:
    """Achieved GB/s of a jitted streaming ``y = 2x + 1`` (read + write) over ``mbytes`` of float32."""
    n = mbytes * 2**20 // 4
    x = jnp.ones((n,), jnp.float32)
    f = jax.jit(lambda v: 2.0 * v + 1.0)
    t = time_jax(f, x, repeats=5)
    return 2 * n * 4 / t.run_s / 1e9


def activation_ceiling(activation: str, *, n: int = 1 << 20, responses: int = 16) -> float:
    """Achieved G evaluations/s of a filter activation (``"silu"`` or ``"relu"``) inside one fusion.

    The shape of a field convolution's inner loop, through the responses function the evaluation
    path uses (:func:`jmeshtex.ops.field_conv_responses`): ``Σ_h act(x·a_h + b_h)`` over
    ``responses`` ridge functions of ``n`` float32 inputs (4 MiB, cache-resident), so the figure is
    the activation's arithmetic throughput, not memory bandwidth. A SiLU costs a tanh (a rational function with a division), which a FLOP count of
    multiply-adds does not see.
    """
    from jmeshtex.ops import FieldConvParams, field_conv_responses

    x = jnp.linspace(-4.0, 4.0, n, dtype=jnp.float32).reshape(n, 1, 1)  # [V, K, C] = [n, 1, 1]
    zero = jnp.zeros_like(x)
    mix = jnp.zeros((1, 1, 1), jnp.complex64)  # not used by the responses

    def f(v):
        acc = jnp.zeros_like(v)
        for h in range(responses):  # one ridge function a_h x + b_h per response, summed unrolled
            p = FieldConvParams(
                filter_weight=jnp.array([[1.0 + 0.01 * h], [0.0]], jnp.float32),
                filter_bias=jnp.full((1,), 0.1 * h, jnp.float32),
                mix=mix,
            )
            acc = acc + field_conv_responses(v, zero, p, activation=activation)[:, :, 0]
        return acc

    t = time_jax(jax.jit(f), x, repeats=5)
    return n * responses / t.run_s / 1e9


def roofline(report: Report, flops: float, nbytes: float, seconds: float) -> dict:
    """Which ceiling of this run bounds a row (FLOPs at matmul speed or bytes at copy bandwidth),
    the time that bound allows, and the share of it reached."""
    t_flops = flops / (report.ceilings["matmul_gflops"] * 1e9)
    t_bytes = nbytes / (report.ceilings["bandwidth_gbs"] * 1e9)
    bound_s = max(t_flops, t_bytes)
    return {
        "bound": "flops" if t_flops >= t_bytes else "bytes",
        "bound_s": bound_s,
        "pct_of_bound": 100.0 * bound_s / seconds,
    }


def timed(t: Timing) -> dict[str, float]:
    """A row's timing columns: ``seconds`` (the median run) and ``compile_s``."""
    return {"seconds": t.run_s, "compile_s": t.compile_s}


def rated(report: Report, t: Timing, flops: float, nbytes: float) -> dict:
    """A row's timing, work and :func:`roofline` columns (``flops`` left out when 0: a row that
    only moves memory)."""
    work = {"flops": flops} if flops else {}
    return {**timed(t), **work, "bytes": nbytes, **roofline(report, flops, nbytes, t.run_s)}


class Report:
    """Collects rows and writes ``results/<name>.json`` and ``results/<name>.md`` atomically."""

    def __init__(self, name: str, *, ceilings: bool = True):
        self.name = name
        self.info = machine_info()
        self.ceilings: dict[str, float] = {}
        if ceilings:
            self.ceilings["matmul_gflops"] = matmul_ceiling()
            self.ceilings["bandwidth_gbs"] = bandwidth_ceiling()
        self.rows: list[dict[str, Any]] = []
        self.config: dict[str, Any] = {}  # what the run used, written to the JSON when set
        self.notes: list[str] = []  # lines below the markdown table
        print(f"# {name}\n{json.dumps(self.info)}\nceilings: {self.ceilings}", flush=True)

    def add(self, **row: Any) -> dict[str, Any]:
        """Add a row; ``flops`` / ``bytes`` with ``seconds`` give achieved rates and % of ceiling.

        A ``size`` given as a :class:`Size` is written as its label followed by its count field
        (``size="20K faces", faces=20480``); a different value already in that field is an error.
        """
        size = row.get("size")
        if isinstance(size, Size):
            if size.unit in row and row[size.unit] != size.count:
                raise ValueError(
                    f"row {row.get('name')!r}: {size.unit}={row[size.unit]!r} but its size "
                    f"{str(size)!r} counts {size.count}"
                )
            items: list[tuple[str, Any]] = []
            for k, v in row.items():
                if k == "size":
                    items += [(k, str(v)), (size.unit, size.count)]
                elif k != size.unit:
                    items.append((k, v))
            row = dict(items)
        s = row.get("seconds")
        if s and row.get("flops"):
            row["gflops"] = row["flops"] / s / 1e9
            if "matmul_gflops" in self.ceilings:
                row["pct_matmul"] = 100.0 * row["gflops"] / self.ceilings["matmul_gflops"]
        if s and row.get("bytes"):
            row["gbs"] = row["bytes"] / s / 1e9
            if "bandwidth_gbs" in self.ceilings:
                row["pct_bandwidth"] = 100.0 * row["gbs"] / self.ceilings["bandwidth_gbs"]
        self.rows.append(row)
        print("  " + ", ".join(f"{k}={_fmt(v)}" for k, v in row.items()), flush=True)
        return row

    def write(self, directory: pathlib.Path | None = None) -> pathlib.Path:
        out = pathlib.Path(directory) if directory else RESULTS
        out.mkdir(parents=True, exist_ok=True)
        payload = {
            "name": self.name,
            "machine": self.info,
            "ceilings": self.ceilings,
            **({"config": self.config} if self.config else {}),
            "rows": self.rows,
        }
        atomic_write(out / f"{self.name}.json", json.dumps(payload, indent=2, default=float))
        atomic_write(out / f"{self.name}.md", self.markdown())
        print(f"wrote {out / self.name}.json and .md", flush=True)
        return out / f"{self.name}.json"

    def markdown(self) -> str:
        keys: list[str] = []
        for r in self.rows:
            keys += [k for k in r if k not in keys]
        lines = [f"# {self.name}", "", f"machine: `{json.dumps(self.info)}`", ""]
        lines += [
            "ceilings (same run): "
            + ", ".join(f"{k} = {_fmt(v)}" for k, v in self.ceilings.items()),
            "",
        ]
        lines += ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
        lines += ["| " + " | ".join(_fmt(r.get(k, "")) for k in keys) + " |" for r in self.rows]
        if self.notes:
            lines += ["", *self.notes]
        return "\n".join(lines) + "\n"


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)

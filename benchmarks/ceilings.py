"""Benchmark: the machine's ceilings per dtype — jitted square matmul GFLOP/s and streaming copy GB/s.

Run: ``.venv/bin/python benchmarks/ceilings.py [--sizes 1024 2048] [--dtype float32] [--out DIR]``.
The ceilings every other report measures at float32 (``_harness.matmul_ceiling``,
``bandwidth_ceiling``), over sizes and dtypes, so a sweep shows where a machine reaches its peak
and what float64 / bfloat16 cost. ``matmul n`` multiplies two ``n × n`` matrices (``2n³`` FLOPs);
``copy n`` streams ``y = 2x + 1`` over ``n²`` elements (reads and writes ``2n²`` elements). Each
row's ratio is to the harness ceilings measured at the start of the same run (float32 2048²
matmul, 256 MiB float32 copy).
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
from _harness import Report, time_jax, timed

jax.config.update("jax_enable_x64", True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[512, 1024, 2048])
    ap.add_argument(
        "--dtype", default="float32", choices=["float32", "float64", "bfloat16", "float16"]
    )
    ap.add_argument("--out", default=None, help="results folder (default benchmarks/results)")
    args = ap.parse_args(argv)
    report = Report("ceilings")
    dtype = jnp.dtype(args.dtype)
    matmul, copy = jax.jit(jnp.matmul), jax.jit(lambda v: 2 * v + 1)
    for n in args.sizes:
        a = jnp.ones((n, n), dtype)
        t = time_jax(matmul, a, a)
        report.add(
            name="matmul",
            size=f"{n}x{n}",
            dtype=args.dtype,
            **timed(t),
            flops=2.0 * n**3,
            bound="flops",
        )
        t = time_jax(copy, a)
        report.add(
            name="copy",
            size=f"{n}x{n}",
            dtype=args.dtype,
            **timed(t),
            bytes=2.0 * n * n * dtype.itemsize,
            bound="bytes",
        )
    report.write(args.out)


if __name__ == "__main__":
    main()

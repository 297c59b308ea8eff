"""Benchmark: field convolution forward and forward+backward at 5K / 30K / 80K vertices.

Setting (the FLDM's layers): k = 8 neighbours, C = D = 96 complex channels, hdim = 16 filter
responses, complex64, synthetic random k-NN neighbourhoods with the right shapes (slot 0 = self).

What is counted. The dense part of the op is the complex mix, a ``[V, C·H] × [C·H, D]`` complex GEMM
(``8·V·C·H·D`` real FLOPs; forward+backward adds ``∂sums = ∂y Mᴴ`` and ``∂M = sumsᴴ ∂y``, 3× in all).
Achieved GFLOP/s = those FLOPs / the whole op's time, next to the matmul ceiling measured in the same
run. The rest of the op does not run on the GEMM units: ``V·K·C·H`` filter evaluations (one per
neighbour, channel and response; each an activation plus ~6 FMAs, done 2× in the forward for the
real/imaginary sums, ~7× in the backward) and the neighbour gather / scatter. ``filter_gevals`` is
that count per second. Rows also split the forward into its stages (gather + filter argument, filter
sums, mix GEMM) so the bound is visible.

Usage::

    python benchmarks/ops_field_conv.py                 # default: 5K, 30K, 80K, both activations
    python benchmarks/ops_field_conv.py --sizes 5000 --activations silu

Writes ``benchmarks/results/ops_field_conv.{json,md}``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _harness import Report, time_jax  # noqa: E402

from jmeshtex.geometry import VertexNeighborhood  # noqa: E402
from jmeshtex.ops import (  # noqa: E402
    field_conv,
    field_conv_filter_sums,
    field_conv_mix,
    field_conv_terms,
    init_field_conv,
)

K, C, D, H = 8, 96, 96, 16


def synthetic_nbhd(v: int, k: int = K, seed: int = 0) -> VertexNeighborhood:
    """Random k-NN-shaped neighbourhoods: slot 0 is the vertex itself, the others random vertices."""
    rng = np.random.default_rng(seed)
    index = rng.integers(0, v, (v, k)).astype(np.int32)
    index[:, 0] = np.arange(v)
    log = (rng.uniform(0.2, 1.0, (v, k)) * np.exp(1j * rng.uniform(-np.pi, np.pi, (v, k)))).astype(np.complex64)
    log[:, 0] = 0
    transport = np.exp(1j * rng.uniform(-np.pi, np.pi, (v, k))).astype(np.complex64)
    transport[:, 0] = 1
    return VertexNeighborhood(
        index=jnp.asarray(index), mask=jnp.ones((v, k), bool), log=jnp.asarray(log),
        transport=jnp.asarray(transport), weight=jnp.asarray(rng.uniform(0.5, 1.5, (v, k)), jnp.float32),
        area=jnp.ones((v,), jnp.float32), vertex_mask=jnp.ones((v,), bool),
    )


def run(sizes, activations, repeats: int) -> Report:
    report = Report("ops_field_conv")
    params = init_field_conv(jax.random.key(0), C, D, hdim=H)
    for v in sizes:
        nb = synthetic_nbhd(v)
        x = jax.random.normal(jax.random.key(1), (v, C), jnp.complex64)
        cot = jax.random.normal(jax.random.key(2), (v, D), jnp.complex64)
        gemm_flops = 8.0 * v * C * H * D
        evals = float(v * K * C * H)
        size = f"{v // 1000}K"
        for act in activations:
            fwd = jax.jit(lambda x, nb, p, act=act: field_conv(x, nb, p, activation=act))

            def loss(x, p, nb, act=act, cot=cot):
                y = field_conv(x, nb, p, activation=act)
                return jnp.sum(y.real * cot.real + y.imag * cot.imag)

            fwd_bwd = jax.jit(jax.value_and_grad(loss, argnums=(0, 1)))
            t = time_jax(fwd, x, nb, params, repeats=repeats)
            report.add(name=f"field_conv fwd ({act})", size=size, seconds=t.run_s, compile_s=t.compile_s,
                       flops=gemm_flops, filter_gevals=evals / t.run_s / 1e9)
            t = time_jax(fwd_bwd, x, params, nb, repeats=repeats)
            report.add(name=f"field_conv fwd+bwd ({act})", size=size, seconds=t.run_s, compile_s=t.compile_s,
                       flops=3 * gemm_flops, filter_gevals=evals / t.run_s / 1e9)
            if v == 30000:  # stage split of the forward at the target size
                _stages(report, x, nb, params, act, size, repeats)
    return report


def _stages(report, x, nb, params, act, size, repeats):
    """The forward split into its stages (the public stage functions of ``jmeshtex.ops``)."""
    v = x.shape[0]
    terms = jax.jit(lambda x, nb: field_conv_terms(x, nb))
    t = time_jax(terms, x, nb, repeats=repeats)
    nbytes = 4.0 * v * K * C * (2 + 4) + 8.0 * v * C  # gather reads ~2 [V,K,C] f32, writes 4, plus x
    report.add(name="  stage: gather + argument", size=size, seconds=t.run_s, bytes=nbytes)
    gathered = terms(x, nb)
    sums = jax.jit(lambda terms, p: field_conv_filter_sums(terms, p, activation=act))
    t = time_jax(sums, gathered, params, repeats=repeats)
    report.add(name=f"  stage: filter sums ({act})", size=size, seconds=t.run_s,
               filter_gevals=v * K * C * H / t.run_s / 1e9)
    filtered = sums(gathered, params)  # the mix stage also splits M ([C, H, D], small) into its halves
    t = time_jax(jax.jit(field_conv_mix), filtered, params, repeats=repeats)
    report.add(name="  stage: mix GEMM", size=size, seconds=t.run_s, flops=8.0 * v * C * H * D)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[5000, 30000, 80000])
    ap.add_argument("--activations", nargs="+", default=["silu", "relu"], choices=["silu", "relu"])
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--no-write", action="store_true", help="print only")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    report = run(args.sizes, args.activations, args.repeats)
    if not args.no_write:
        report.write()
    print(f"total {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()

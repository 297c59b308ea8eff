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

Side by side (``--side-by-side``): the reference layer's configuration (google-research
``mesh_diffusion/latents/layers.py`` ``FieldConv``: k = 8, C = D = 64, h = 8, two hidden filter layers,
SiLU) at each size, jmeshtex's two-hidden-layer ``field_conv`` next to the reference *formula* written
here as a plain-``jnp`` oracle (:func:`reference_formula`: filter MLP on every ``[V, K, C, 2]``
argument, materialised, then the weighted sum and the complex dense layer; the reference code itself
is not copied). Both run on the same neighbourhoods, forward and value-and-grad, with XLA's
temporary-buffer size of each compiled program as the memory figure; the oracle's output is checked
against ``field_conv(..., argument="untransported")`` (the reference pairs the log map with the
untransported direction). Also the one-hidden-layer form and the released 96 / h = 16 configuration.
Columns ``x_*`` are the oracle's figure over the row's (> 1: faster than the oracle), ``temp_vs_oracle``
the value-and-grad temporary memory over the oracle's.

Loaded machines: every row also gives the least *process CPU time* of three calls (``cpu_ms``,
``fwd_cpu_ms``, ``fwd_bwd_cpu_ms``: all threads, i.e. the work done, where wall time also counts the
wait for a core), the one-minute load average when the row was measured, and (side by side) every
timed wall-clock run, so a reader can see how much the medians spread.

Usage::

    python benchmarks/ops_field_conv.py                 # default: 5K, 30K, 80K, both activations, 1 and 2 hidden
    python benchmarks/ops_field_conv.py --sizes 5000 --activations silu
    python benchmarks/ops_field_conv.py --side-by-side --sizes 30000

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
from _harness import Report, Size, size_label, time_jax  # noqa: E402

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
    log = (rng.uniform(0.2, 1.0, (v, k)) * np.exp(1j * rng.uniform(-np.pi, np.pi, (v, k)))).astype(
        np.complex64
    )
    log[:, 0] = 0
    transport = np.exp(1j * rng.uniform(-np.pi, np.pi, (v, k))).astype(np.complex64)
    transport[:, 0] = 1
    return VertexNeighborhood(
        index=jnp.asarray(index),
        mask=jnp.ones((v, k), bool),
        log=jnp.asarray(log),
        transport=jnp.asarray(transport),
        weight=jnp.asarray(rng.uniform(0.5, 1.5, (v, k)), jnp.float32),
        area=jnp.ones((v,), jnp.float32),
        vertex_mask=jnp.ones((v,), bool),
    )


def run(sizes, activations, repeats: int, hidden_layers=(1, 2)) -> Report:
    report = Report("ops_field_conv")
    report.config = {
        "K": K,
        "C": C,
        "D": D,
        "H": H,
        "hidden_layers": list(hidden_layers),
        "repeats": repeats,
    }
    for v in sizes:
        nb = synthetic_nbhd(v)
        x = jax.random.normal(jax.random.key(1), (v, C), jnp.complex64)
        cot = jax.random.normal(jax.random.key(2), (v, D), jnp.complex64)
        gemm_flops = 8.0 * v * C * H * D
        evals = float(v * K * C * H)
        size = Size(size_label(v), vertices=v)
        for act, layers in [(a, n) for n in hidden_layers for a in activations]:
            params = init_field_conv(jax.random.key(0), C, D, hdim=H, hidden_layers=layers)
            label = f"{act}" + ("" if layers == 1 else ", 2 hidden")
            fwd = jax.jit(lambda x, nb, p, act=act: field_conv(x, nb, p, activation=act))

            def loss(x, p, nb, act=act, cot=cot):
                y = field_conv(x, nb, p, activation=act)
                return jnp.sum(y.real * cot.real + y.imag * cot.imag)

            fwd_bwd = jax.jit(jax.value_and_grad(loss, argnums=(0, 1)))
            t = time_jax(fwd, x, nb, params, repeats=repeats)
            tf = t.run_s
            report.add(
                name=f"field_conv fwd ({label})",
                size=size,
                seconds=t.run_s,
                compile_s=t.compile_s,
                cpu_ms=cpu_ms(fwd, x, nb, params),
                flops=gemm_flops,
                filter_gevals=evals / t.run_s / 1e9,
                load_avg=os.getloadavg()[0],
            )
            t = time_jax(fwd_bwd, x, params, nb, repeats=repeats)
            report.add(
                name=f"field_conv fwd+bwd ({label})",
                size=size,
                seconds=t.run_s,
                compile_s=t.compile_s,
                cpu_ms=cpu_ms(fwd_bwd, x, params, nb),
                bwd_over_fwd=t.run_s / tf,
                flops=3 * gemm_flops,
                filter_gevals=evals / t.run_s / 1e9,
                load_avg=os.getloadavg()[0],
            )
            if v == 30000 and layers == 1:  # stage split of the forward at the target size
                _stages(report, x, nb, params, act, size, repeats)
    return report


def _stages(report, x, nb, params, act, size, repeats):
    """The forward split into its stages (the public stage functions of ``jmeshtex.ops``)."""
    v = x.shape[0]
    terms = jax.jit(lambda x, nb: field_conv_terms(x, nb))
    t = time_jax(terms, x, nb, repeats=repeats)
    nbytes = (
        4.0 * v * K * C * (2 + 4) + 8.0 * v * C
    )  # gather reads ~2 [V,K,C] f32, writes 4, plus x
    report.add(name="  stage: gather + argument", size=size, seconds=t.run_s, bytes=nbytes)
    gathered = terms(x, nb)
    sums = jax.jit(lambda terms, p: field_conv_filter_sums(terms, p, activation=act))
    t = time_jax(sums, gathered, params, repeats=repeats)
    report.add(
        name=f"  stage: filter sums ({act})",
        size=size,
        seconds=t.run_s,
        filter_gevals=v * K * C * H / t.run_s / 1e9,
    )
    filtered = sums(
        gathered, params
    )  # the mix stage also splits M ([C, H, D], small) into its halves
    t = time_jax(jax.jit(field_conv_mix), filtered, params, repeats=repeats)
    report.add(name="  stage: mix GEMM", size=size, seconds=t.run_s, flops=8.0 * v * C * H * D)


def reference_formula(x, index, log, transport, weight, w1, b1, w2, b2, mix):
    """The reference ``FieldConv`` as a formula in plain ``jnp`` (everything materialised).

    ``rel_{pqc} = log_p(q) · conj(x_q / |x_q|)`` (the untransported direction; angle 0 where
    ``|x_q| ≤ 1e-4``), ``φ = SiLU(SiLU([Re rel, Im rel] W₁ + b₁) W₂ + b₂)`` ``[V, K, C, h]``,
    ``S_{pch} = Σ_q x_q ŵ_{pq} ρ_{q→p} φ_{pqch}`` with ``ŵ = w / Σ|w|``, ``y = S M``.
    """
    mag = jnp.abs(x)
    keep = mag > 1e-4
    frame = jnp.where(keep, x / jnp.where(keep, mag, 1), 1)
    rel = log[..., None] * jnp.conj(frame)[index]  # [V, K, C]
    inp = jnp.stack([rel.real, rel.imag], axis=-1)  # [V, K, C, 2]
    phi = jax.nn.silu(jax.nn.silu(inp @ w1 + b1) @ w2 + b2)  # [V, K, C, h]
    wts = weight * transport
    wts = wts / jnp.sum(jnp.abs(wts), axis=1, keepdims=True)
    feat = jnp.sum(x[index][..., None] * wts[..., None, None] * phi, axis=1)  # [V, C, h] complex
    return feat.reshape(x.shape[0], -1) @ mix


def cpu_ms(jitted, *args, repeats: int = 3) -> float:
    """Least process CPU time (all threads) of ``repeats`` calls, ms: on a loaded machine the work done,
    where wall time also counts the time spent waiting for a core."""
    jax.block_until_ready(jitted(*args))
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        jax.block_until_ready(jitted(*args))
        best = min(best, time.process_time() - t0)
    return 1e3 * best


def _temp_bytes(jitted, *args) -> float:
    try:
        return float(jitted.lower(*args).compile().memory_analysis().temp_size_in_bytes)
    except Exception:  # noqa: BLE001 -- not every backend reports it
        return float("nan")


CONFIGS = {
    "reference": ("reference layer C=64 h=8", 64, 8),
    "released": ("released 96 / h=16", 96, 16),
}


def side_by_side(
    sizes, repeats: int, report: Report | None = None, configs=("reference", "released")
) -> Report:
    """jmeshtex vs the reference formula (module docstring), forward and value-and-grad."""
    report = report or Report("ops_field_conv_side_by_side")
    for label, c, h in (CONFIGS[name] for name in configs):
        two = init_field_conv(jax.random.key(0), c, c, hdim=h, hidden_layers=2)
        one = init_field_conv(jax.random.key(0), c, c, hdim=h)
        for v in sizes:
            nb = synthetic_nbhd(v)
            x = jax.random.normal(jax.random.key(1), (v, c), jnp.complex64)
            cot = jax.random.normal(jax.random.key(2), (v, c), jnp.complex64)
            size = Size(size_label(v), vertices=v)
            ref_args = (
                two.filter_weight,
                two.filter_bias,
                two.hidden_weight,
                two.hidden_bias,
                two.mix.reshape(c * h, c),
            )

            def ref(x, p, nb=nb):
                return reference_formula(x, nb.index, nb.log, nb.transport, nb.weight, *p)

            def ours(x, p, nb=nb, argument="transported"):
                return field_conv(x, nb, p, argument=argument)

            check = float(
                jnp.max(
                    jnp.abs(
                        jax.jit(ref)(x, ref_args)
                        - jax.jit(lambda x, p: ours(x, p, argument="untransported"))(x, two)
                    )
                )
            )
            rows = [
                ("reference formula (plain jnp), 2 hidden", ref, ref_args),
                ("jmeshtex field_conv, 2 hidden", ours, two),
                ("jmeshtex field_conv, 1 hidden", ours, one),
            ]
            oracle = None
            for name, fn, p in rows:

                def loss(x, p, fn=fn, cot=cot):
                    y = fn(x, p)
                    return jnp.sum(y.real * cot.real + y.imag * cot.imag)

                fwd, vg = jax.jit(fn), jax.jit(jax.value_and_grad(loss, argnums=(0, 1)))
                tf = time_jax(fwd, x, p, repeats=repeats)
                tb = time_jax(vg, x, p, repeats=repeats)
                row = dict(
                    fwd_ms=1e3 * tf.run_s,
                    fwd_bwd_ms=1e3 * tb.run_s,
                    bwd_over_fwd=tb.run_s / tf.run_s,
                    fwd_cpu_ms=cpu_ms(fwd, x, p),
                    fwd_bwd_cpu_ms=cpu_ms(vg, x, p),
                    fwd_temp_mb=_temp_bytes(fwd, x, p) / 2**20,
                    fwd_bwd_temp_mb=_temp_bytes(vg, x, p) / 2**20,
                )
                row["cpu_bwd_over_fwd"] = row["fwd_bwd_cpu_ms"] / row["fwd_cpu_ms"]
                oracle = oracle or row
                for key in (
                    "fwd_ms",
                    "fwd_bwd_ms",
                    "fwd_cpu_ms",
                    "fwd_bwd_cpu_ms",
                ):  # > 1: faster than the oracle
                    row[f"x_{key}"] = oracle[key] / row[key]
                row["temp_vs_oracle"] = row["fwd_bwd_temp_mb"] / oracle["fwd_bwd_temp_mb"]
                report.add(
                    name=f"[{label}] {name}",
                    size=size,
                    **row,
                    compile_s=tf.compile_s + tb.compile_s,
                    seconds=tf.run_s,
                    oracle_max_abs_diff=check,
                    load_avg=os.getloadavg()[0],
                    fwd_runs_ms=[round(1e3 * r) for r in tf.runs],
                    fwd_bwd_runs_ms=[round(1e3 * r) for r in tb.runs],
                )
    return report


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[5000, 30000, 80000])
    ap.add_argument("--activations", nargs="+", default=["silu", "relu"], choices=["silu", "relu"])
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--no-write", action="store_true", help="print only")
    ap.add_argument(
        "--side-by-side",
        action="store_true",
        help="only the comparison with the reference formula (module docstring)",
    )
    ap.add_argument(
        "--configs",
        nargs="+",
        default=list(CONFIGS),
        choices=list(CONFIGS),
        help="side by side: which configurations (default: both)",
    )
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    report = (
        side_by_side(args.sizes, args.repeats, configs=args.configs)
        if args.side_by_side
        else run(args.sizes, args.activations, args.repeats)
    )
    if not args.no_write:
        report.write()
    print(f"total {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()

"""Benchmark: bidirectional Chamfer distance at 20K × 20K points (forward and forward+backward).

Run: ``.venv/bin/python benchmarks/ops_chamfer.py [--points 20000] [--chunks 128 512 2048]``.
Writes ``benchmarks/results/ops_chamfer.{json,md}``.

Points are uniform on the unit sphere (P) and on a slightly larger, rotated sphere (Q), float32,
with normals. Measured, jitted, compile time apart:

- ``chamfer fwd`` (distance + normal term) and ``fwd+bwd`` (gradient w.r.t. both point sets) at the
  default chunk size, and the forward at other chunk sizes;
- ``min-reduce only (ceiling)``: the same ``N × M`` squared distances reduced by a plain min in
  both directions, no index, no gradient — the cheapest possible exact brute-force pass.

The search is a brute-force pass over all ``N·M`` pairs in each direction, bound by elementwise
vector throughput (subtract, square, add, compare, select — no FMA-friendly GEMM), so the relevant
ceiling is the min-reduce row, reported as ``pct_of_min_reduce``; the matmul / bandwidth columns
are given for reference. FLOPs count ``3D - 1 = 8`` per pair for the distance and 3 per pair for the
two reductions (min, compare-select-min), both directions. Bytes are the data read once (points,
masks) plus the chunk blocks if they were written to memory: ``N·M·4`` per direction.
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np
from _harness import Report, Size, size_label, time_jax, timed

from jmeshtex.ops import chamfer_distance


def sphere_points(n: int, key) -> jax.Array:
    x = jax.random.normal(key, (n, 3), jnp.float32)
    return x / jnp.linalg.norm(x, axis=1, keepdims=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", type=int, default=20_000, help="N = M")
    ap.add_argument(
        "--chunks",
        type=int,
        nargs="+",
        default=[128, 512, 2048],
        help="chunk sizes (first: fwd+bwd)",
    )
    ap.add_argument("--out", default=None, help="results folder (default benchmarks/results)")
    args = ap.parse_args()
    N = M = args.points
    size = Size(f"{size_label(N)} x {size_label(M)}", points=N)

    report = Report("ops_chamfer")
    p = sphere_points(N, jax.random.key(0))
    c, s = np.cos(0.3), np.sin(0.3)
    rot = jnp.asarray([[c, -s, 0], [s, c, 0], [0, 0, 1]], jnp.float32)
    q = 1.01 * sphere_points(M, jax.random.key(1)) @ rot.T
    pn, qn = p, q / 1.01

    pairs = 2.0 * N * M
    flops = pairs * (8 + 3)
    nbytes = 4.0 * 2 * (N + M) * 3 + 4.0 * pairs

    chunk0 = args.chunks[0]

    @jax.jit
    def min_only(p, q):
        def one_way(a, b):
            def block(c):
                d2 = sum((c[:, k, None] - b[None, :, k]) ** 2 for k in range(3))
                return jnp.min(d2, axis=1)

            n = a.shape[0]
            a = jnp.pad(a, ((0, -n % chunk0), (0, 0)))
            return jax.lax.map(block, a.reshape(-1, chunk0, 3)).reshape(-1)[:n].sum()

        return one_way(p, q) + one_way(q, p)

    t = time_jax(min_only, p, q, repeats=3)
    ceiling_s = t.run_s
    report.add(
        name="min-reduce only (ceiling)",
        size=size,
        chunk=chunk0,
        **timed(t),
        flops=pairs * 9,
        bytes=nbytes,
        bound="elementwise",
    )

    def chamfer_row(name: str, chunk: int, t) -> None:
        report.add(
            name=name,
            size=size,
            chunk=chunk,
            **timed(t),
            flops=flops,
            bytes=nbytes,
            bound="elementwise",
            pct_of_min_reduce=100.0 * ceiling_s / t.run_s,
        )

    for i, chunk in enumerate(args.chunks):
        fwd = jax.jit(
            lambda p, q, pn, qn, chunk=chunk: chamfer_distance(
                p, q, p_normals=pn, q_normals=qn, chunk_size=chunk
            )
        )
        t = time_jax(fwd, p, q, pn, qn, repeats=3)
        chamfer_row("chamfer fwd", chunk, t)
        if i == 0:

            def loss(p, q, chunk=chunk):
                cd = chamfer_distance(p, q, p_normals=pn, q_normals=qn, chunk_size=chunk)
                return cd.distance + 0.1 * cd.normal

            bwd = jax.jit(jax.value_and_grad(loss, argnums=(0, 1)))
            t = time_jax(bwd, p, q, repeats=3)
            chamfer_row("chamfer fwd+bwd", chunk, t)

    report.write(args.out)


if __name__ == "__main__":
    main()

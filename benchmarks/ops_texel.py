"""Benchmark: surface-CNN texel convolution + pooling on a 512×512 texture (262K texels, 64→64).

Run: ``.venv/bin/python benchmarks/ops_texel.py [--size 512] [--channels 64]``. Writes
``benchmarks/results/ops_texel.{json,md}``.

Taps are bilinear (``J = 4`` texels per tap, as the exp-map sampler produces them): every texel's
nine taps sit at its image neighbours shifted by a random sub-texel offset, so the index pattern is
local like on a real atlas. Measured, float32, jitted, compile time apart:

- ``texel_conv fwd`` and ``fwd+bwd`` (gradient w.r.t. the features and the kernel);
- ``grouped_pool`` 2×2 mean and max, forward and forward+backward;
- ``lax.conv 3×3 (ceiling)``: XLA's dense convolution of the same layer on the image grid
  (``conv_general_dilated``, SAME) — what a 2D CNN pays for this layer on this machine.

FLOPs: the GEMM ``2·N·9C·D`` plus the bilinear gather-reduce ``2·N·9·J·C``; backward is 2× the
GEMM plus the transposed gather. Bytes (minimum float32 traffic): read the features once, the
indices and weights, write and read back the ``[N, 9C]`` sampled block, write the output.
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np
from _harness import Report, Size, rated, size_label, time_jax

from jmeshtex.ops import TexelNeighborhood, grouped_pool, image_pool_groups, texel_conv


def bilinear_taps(size: int, *, seed: int = 0) -> TexelNeighborhood:
    """Nine bilinear taps per texel of a ``size × size`` image, jittered by a sub-texel offset."""
    rng = np.random.default_rng(seed)
    N = size * size
    rows, cols = np.divmod(np.arange(N), size)
    dy, dx = np.divmod(np.arange(9), 3)
    jit_r, jit_c = rng.random((2, N, 9))
    r = rows[:, None] + dy[None] - 1 + jit_r
    c = cols[:, None] + dx[None] - 1 + jit_c
    r0, c0 = np.floor(r).astype(np.int64), np.floor(c).astype(np.int64)
    fr, fc = r - r0, c - c0
    corners = [
        (0, 0, (1 - fr) * (1 - fc)),
        (0, 1, (1 - fr) * fc),
        (1, 0, fr * (1 - fc)),
        (1, 1, fr * fc),
    ]
    index = np.zeros((N, 9, 4), np.int32)
    weight = np.zeros((N, 9, 4), np.float32)
    for j, (a, b, w) in enumerate(corners):  # 4 corners, vectorised over all texels and taps
        rr, cc = r0 + a, c0 + b
        inside = (rr >= 0) & (rr < size) & (cc >= 0) & (cc < size)
        index[..., j] = np.where(inside, rr * size + cc, 0)
        weight[..., j] = np.where(inside, w, 0)
    return TexelNeighborhood(index, weight, np.ones(N, bool))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=512, help="texture side in texels")
    ap.add_argument("--channels", type=int, default=64, help="C = D")
    ap.add_argument("--out", default=None, help="results folder (default benchmarks/results)")
    args = ap.parse_args()
    S, C = args.size, args.channels
    D, N, J = C, S * S, 4
    size = Size(f"{S}x{S} ({size_label(N)} texels), {C}->{D}", texels=N)

    report = Report("ops_texel")
    key = jax.random.key(0)
    x = jax.random.normal(key, (N, C), jnp.float32)
    kernel = jax.random.normal(jax.random.key(1), (3, 3, C, D), jnp.float32) / np.sqrt(9 * C)
    bias = jnp.zeros((D,), jnp.float32)
    taps = jax.tree.map(jnp.asarray, bilinear_taps(S))
    groups = jax.tree.map(jnp.asarray, image_pool_groups(S, S))

    gemm = 2.0 * N * 9 * C * D
    gather = 2.0 * N * 9 * J * C
    io = 4.0 * (N * C + N * D) + N * 9 * J * (4 + 4)
    block = 4.0 * 2 * N * 9 * C

    fwd = jax.jit(texel_conv)
    t = time_jax(fwd, x, taps, kernel, bias)
    report.add(name="texel_conv fwd", size=size, **rated(report, t, gemm + gather, io + block))
    bwd = jax.jit(
        jax.grad(lambda x, k, taps: jnp.sum(texel_conv(x, taps, k, bias) ** 2), argnums=(0, 1))
    )
    t = time_jax(bwd, x, kernel, taps)
    report.add(
        name="texel_conv fwd+bwd",
        size=size,
        **rated(report, t, 3 * gemm + 2 * gather, 3 * (io + block)),
    )

    img = x.reshape(1, S, S, C)
    dense = jax.jit(
        lambda img, k: jax.lax.conv_general_dilated(
            img, k, (1, 1), "SAME", dimension_numbers=("NHWC", "HWIO", "NHWC")
        )
    )
    t = time_jax(dense, img, kernel)
    report.add(
        name="lax.conv 3x3 (ceiling)", size=size, **rated(report, t, gemm, 4.0 * (N * C + N * D))
    )
    dense_bwd = jax.jit(jax.grad(lambda img, k: jnp.sum(dense(img, k) ** 2), argnums=(0, 1)))
    t = time_jax(dense_bwd, img, kernel)
    report.add(
        name="lax.conv 3x3 fwd+bwd (ceiling)",
        size=size,
        **rated(report, t, 3 * gemm, 3 * 4.0 * (N * C + N * D)),
    )

    G = groups.index.shape[0]
    pool_bytes = 4.0 * (N * C + G * C) + G * 4 * (4 + 1)
    for mode in ("mean", "max"):
        pool = jax.jit(lambda x, g, mode=mode: grouped_pool(x, g, mode=mode))
        t = time_jax(pool, x, groups)
        report.add(
            name=f"grouped_pool 2x2 {mode} fwd", size=size, **rated(report, t, 0.0, pool_bytes)
        )
        pool_bwd = jax.jit(
            jax.grad(lambda x, g, mode=mode: jnp.sum(grouped_pool(x, g, mode=mode) ** 2))
        )
        t = time_jax(pool_bwd, x, groups)
        report.add(
            name=f"grouped_pool 2x2 {mode} fwd+bwd",
            size=size,
            **rated(report, t, 0.0, 2 * pool_bytes + 4.0 * N * C),
        )
    ceiling = jax.jit(
        lambda img: jax.lax.reduce_window(
            img, -jnp.inf, jax.lax.max, (1, 2, 2, 1), (1, 2, 2, 1), "VALID"
        )
    )
    t = time_jax(ceiling, img)
    report.add(
        name="lax.reduce_window 2x2 max (ceiling)",
        size=size,
        **rated(report, t, 0.0, 4.0 * (N * C + G * C)),
    )
    report.write(args.out)


if __name__ == "__main__":
    main()

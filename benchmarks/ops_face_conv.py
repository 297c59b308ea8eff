"""Benchmark: the DGTS face-convolution stack (6 layers, 128 channels) forward and forward+backward.

Run: ``.venv/bin/python benchmarks/ops_face_conv.py [--sizes 5 6 7]`` (icosphere subdivision levels:
20K, 80K, 320K faces). Writes ``benchmarks/results/ops_face_conv.{json,md}``.

What is measured (float32, jitted, compile time apart):

- ``stack fwd``: :func:`face_features` + :func:`face_conv_stack` (embedding 4→128, then 5 face
  convolutions 128→128 with instance norm + leaky ReLU in between);
- ``stack fwd+bwd``: value and gradient of a sum of squares w.r.t. all parameters;
- ``GEMMs only``: the same 5 ``[F, 128] @ [128, 256]`` products alone, measured in the same run:
  the FLOP ceiling the stack could reach on this machine with its own matrix shapes.

FLOPs count the dense part only (the GEMMs: ``2·3F·4·128`` for the embedding, ``2·F·128·256`` per
convolution (two ``[F, 128] @ [128, 128]``); backward = 2× forward). Bytes are the minimum float32 traffic of the forward pass: per
convolution layer read the input and write ``[F, 2D]``, gather ``3F`` rows of ``D``, write the
output, and instance norm reads twice and writes once; backward is counted as 2× forward.
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
from _harness import Report, Size, rated, size_label, time_host, time_jax

from jmeshtex.data import icosphere
from jmeshtex.geometry import face_neighborhood
from jmeshtex.ops import face_conv_stack, face_features, init_face_conv_stack

WIDTH = 128
LAYERS = 6  # embedding + 5 face convolutions


def dense_flops(F: int) -> float:
    return 2.0 * 3 * F * 4 * WIDTH + (LAYERS - 1) * 2.0 * F * WIDTH * 2 * WIDTH


def forward_bytes(F: int) -> float:
    C = D = WIDTH
    per_conv = F * (C + 2 * D + 3 * D + D) * 4 + F * 3 * (4 + 4 + 1)  # + neighbours, mask
    per_norm = F * 3 * C * 4
    embed = F * (3 * 4 + WIDTH) * 4
    return embed + (LAYERS - 1) * (per_conv + per_norm)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--sizes", type=int, nargs="+", default=[5, 6, 7], help="icosphere subdivision levels"
    )
    ap.add_argument("--out", default=None, help="results folder (default benchmarks/results)")
    args = ap.parse_args()

    report = Report("ops_face_conv")
    params = init_face_conv_stack(jax.random.key(0), (WIDTH,) * LAYERS, dtype=jnp.float32)

    def forward(v, nb, params):
        return face_conv_stack(face_features(v, nb), nb, params)

    fwd = jax.jit(forward)
    fwd_bwd = jax.jit(jax.value_and_grad(lambda p, v, nb: jnp.sum(forward(v, nb, p) ** 2)))
    w = jnp.asarray(jax.random.normal(jax.random.key(1), (WIDTH, 2 * WIDTH)), jnp.float32)

    @jax.jit
    def gemms_only(x):
        for _ in range(LAYERS - 1):
            x = (x @ w)[:, :WIDTH]
        return x

    for s in args.sizes:
        v, f = icosphere(s)
        F = len(f)
        size = Size(f"{size_label(F)} faces", faces=F)
        t_host = time_host(face_neighborhood, f, repeats=2)
        report.add(
            name="face_neighborhood (host, NumPy)", size=size, seconds=t_host.run_s, bound="host"
        )
        nb = jax.tree.map(jnp.asarray, face_neighborhood(f))
        vj = jnp.asarray(v, jnp.float32)
        repeats = 1 if F > 200_000 else 3 if F > 50_000 else 5  # keeps the default run ~3 min
        t = time_jax(fwd, vj, nb, params, repeats=repeats, min_time=0.0)
        report.add(
            name="stack fwd", size=size, **rated(report, t, dense_flops(F), forward_bytes(F))
        )
        t = time_jax(fwd_bwd, params, vj, nb, repeats=repeats, min_time=0.0)
        report.add(
            name="stack fwd+bwd",
            size=size,
            **rated(report, t, 3 * dense_flops(F), 3 * forward_bytes(F)),
        )
        x = jnp.ones((F, WIDTH), jnp.float32)
        t = time_jax(gemms_only, x, repeats=repeats)
        report.add(
            name="GEMMs only (ceiling)",
            size=size,
            seconds=t.run_s,
            compile_s=t.compile_s,
            flops=(LAYERS - 1) * 2.0 * F * WIDTH * 2 * WIDTH,
            bound="flops",
        )
        del nb, vj, x
    report.write(args.out)


if __name__ == "__main__":
    main()

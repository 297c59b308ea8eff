"""Benchmark of the surface CNN: host precomputation and optimisation step time.

Mesh: Spot (../shared/data/spot, 5856 faces, its own UV atlas); without the shared data a
procedural icosphere(4) unwrapped with xatlas stands in (reported in the row names). Reports

- precomputation (atlas, level-0 exp-map taps, pooling pyramid with 5 levels) at 512² and 1024²,
  next to the target (≤ 15 s at 1024² on 2 cores; the paper: 1:44 for a 5K-triangle bunny at 1024²
  on a GPU workstation);
- one optimisation step (forward + backward of the full VGG-16 on the mesh, every ReLU and pool
  output in the Gram loss, Adam update) at 256² and 512², compile time apart, with the convolution
  FLOPs against the matmul ceiling of the same run;
- peak resident memory of the process and the bytes of the network arrays.

The machine is shared; record ``uptime`` with the numbers and re-run on a quiet machine. The
precomputation is single-threaded NumPy, so its process CPU time (``cpu_s``) approximates the wall
time of a quiet machine.

Usage::

    python benchmarks/surfacecnn.py                       # precompute 512,1024; steps 256,512
    python benchmarks/surfacecnn.py --precompute 512 --steps 256
"""

from __future__ import annotations

import argparse
import os
import pathlib
import resource
import time

import jax
import jax.numpy as jnp
import numpy as np
from _harness import Report, time_jax

from jmeshtex.geometry import to_jax
from jmeshtex.metrics import load_vgg16
from jmeshtex.surfacecnn import (
    Config,
    default_layers,
    gram_targets,
    prepare_surface,
    required_levels,
    style_loss,
)

SHARED = pathlib.Path(__file__).resolve().parents[1].parent / "shared" / "data"


def _mesh():
    spot = pathlib.Path(os.environ.get("JMESHTEX_SHARED_DATA", SHARED)) / "spot" / "spot_triangulated.obj"
    if spot.is_file():
        from jmeshtex.io import load_mesh

        return "spot", load_mesh(spot)
    from jmeshtex.data import icosphere

    return "icosphere4+xatlas", icosphere(4)  # no UVs: unwrapped with xatlas


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _conv_flops(surface, weights) -> float:
    """Multiply-adds ×2 of every texel conv over the pyramid levels, forward only."""
    sizes = [len(r) for r in surface.pyramid.representative]
    level, total = 0, 0.0
    for name, (k, _) in zip(weights.names, weights.convs, strict=True):
        total += 2.0 * sizes[level] * 9 * k.shape[2] * k.shape[3]
        if name in weights.pools_after:
            level = min(level + 1, len(sizes) - 1)
    return total


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--precompute", default="512,1024", help="texture sizes for the precomputation")
    ap.add_argument("--steps", default="256,512", help="texture sizes for the optimisation step")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    load = os.getloadavg()
    report = Report("surfacecnn")
    print(f"load average {load}")
    name, mesh = _mesh()
    weights = load_vgg16()
    layers = default_layers(weights)
    levels = required_levels(weights, layers)
    for size in [int(s) for s in args.precompute.split(",") if s]:
        t0, c0 = time.perf_counter(), time.process_time()
        surface = prepare_surface(mesh, size=size, levels=levels)
        total, cpu = time.perf_counter() - t0, time.process_time() - c0
        s = surface.seconds
        arrays_mb = sum(np.asarray(a).nbytes for a in jax.tree.leaves(surface.pyramid.network_arrays())) / 2**20
        print(f"{name} {size}²: {surface.atlas.num_texels} texels, {total:.2f} s wall, {cpu:.2f} s CPU "
              f"(atlas {s['atlas']:.2f}, taps {s['taps']:.2f}, pyramid {s['pyramid']:.2f}), arrays {arrays_mb:.0f} MB")
        report.add(name=f"precompute {name} (target <= 15 s at 1024²)", size=f"{size}²",
                   texels=surface.atlas.num_texels, seconds=total, cpu_s=cpu, atlas_s=s["atlas"], taps_s=s["taps"],
                   pyramid_s=s["pyramid"], arrays_mb=arrays_mb, peak_rss_mb=_peak_mb(), load=load[0])
    config = Config()
    optimizer_lr = config.learning_rate
    exemplar = np.random.default_rng(0).uniform(size=(256, 256, 3))
    for size in [int(s) for s in args.steps.split(",") if s]:
        surface = prepare_surface(mesh, size=size, levels=levels)
        arrays = to_jax(surface.pyramid.network_arrays(), jnp.float32)
        targets = gram_targets(exemplar, weights, layers=layers)
        import optax

        opt = optax.adam(optimizer_lr)
        x = jax.random.uniform(jax.random.key(0), (surface.atlas.num_texels, 3), jnp.float32, 0.0, 0.2)
        state = opt.init(x)

        def step(x, state, arrays, targets, opt=opt):
            loss, g = jax.value_and_grad(style_loss)(x, arrays, weights, targets)
            updates, state = opt.update(g, state, x)
            return jnp.clip(optax.apply_updates(x, updates), 0.0, 1.0), state, loss

        # the arrays are arguments, not constants of the compiled program (as in the library)
        t = time_jax(jax.jit(step, static_argnames="opt"), x, state, arrays, targets, repeats=5, min_time=1.0)
        flops = 3.0 * _conv_flops(surface, weights)  # forward + ~2× for the backward
        print(f"{name} {size}²: step {t.run_s:.3f} s (compile {t.compile_s:.1f} s)")
        report.add(name=f"optimisation step {name} (fwd+bwd VGG-16, 18 Gram layers, Adam)", size=f"{size}²",
                   texels=surface.atlas.num_texels, seconds=t.run_s, compile_s=t.compile_s, flops=flops,
                   bound="flops", peak_rss_mb=_peak_mb(), load=os.getloadavg()[0])
    report.write(pathlib.Path(args.out) if args.out else None)


if __name__ == "__main__":
    main()

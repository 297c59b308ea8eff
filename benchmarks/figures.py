"""Regenerate the README's figures: one per method, made by the renderer and ``render.figure``.

Usage: ``python benchmarks/figures.py [--out docs/figures] [--full] [--from DEMO_FOLDER]``.

The figures are the ones ``jmeshtex demo`` writes (its public entry, :func:`jmeshtex.cli.main`;
one stage per method in ``jmeshtex/cli/_stages/<method>.py``, the quick setting unless ``--full``):
exemplar | result(s) | the evaluation protocol's baselines, laid out by
:func:`jmeshtex.render.figure`, textured results textured, geometry smooth-shaded. Writes
``<out>/<method>.png`` (DGTS, surface CNN, FL-VAE, FLDM, MeshMatch), each kept under ~300 KB (a
PNG over the budget is stored with a 256-colour palette), and prints versions, the machine, the
demo's report (per step: wall and process CPU seconds, the stage's summary line with the
baselines) and each figure's size. A few minutes in all on a 2-core CPU (quick settings; ``--full``
is the full demo, under 5 minutes on a quiet 2-core machine). ``--from`` copies the figures of an
existing ``jmeshtex demo --out DEMO_FOLDER`` run instead of running the demo (every stage is
seeded, so a run with the same settings writes the same figures).
"""

from __future__ import annotations

import argparse
import io
import os
import pathlib
import platform
import sys
import tempfile
import time

import jax
import numpy as np

import jmeshtex
from jmeshtex.cli import main as jmeshtex_main

#: method → its figure in the demo's output (``<method folder>/<file>``)
FIGURES = {
    "meshmatch": "meshmatch.png",
    "dgts": "dgts.png",
    "fl": "fl.png",
    "fldm": "fldm.png",
    "surfacecnn": "surfacecnn.png",
}
MAX_BYTES = 300_000


def _store(src: pathlib.Path, dst: pathlib.Path, *, max_bytes: int = MAX_BYTES) -> int:
    """Copy the PNG ``src`` to ``dst`` (optimised; palette-quantised if over ``max_bytes``); its size."""
    from PIL import Image

    image = Image.open(src).convert("RGB")
    buf = io.BytesIO()
    image.save(buf, format="PNG", optimize=True)
    if buf.tell() > max_bytes:
        buf = io.BytesIO()
        image.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(
            buf, format="PNG", optimize=True
        )
    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = dst.with_name(f".{dst.name}.tmp")
    tmp.write_bytes(buf.getvalue())
    os.replace(tmp, dst)
    return dst.stat().st_size


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out", default="docs/figures", help="folder of the PNGs (default docs/figures)"
    )
    parser.add_argument("--full", action="store_true", help="the full demo's settings (slower)")
    parser.add_argument(
        "--from",
        dest="source",
        type=pathlib.Path,
        default=None,
        help="copy the figures of this existing `jmeshtex demo` output folder",
    )
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out)
    print(
        f"jmeshtex {jmeshtex.__version__}, jax {jax.__version__}, numpy {np.__version__}, "
        f"python {platform.python_version()}"
    )
    print(f"machine: {platform.platform()}, {os.cpu_count()} CPUs, JAX devices {jax.devices()}")
    print(f"settings: {'full' if args.full else 'quick'} demo → {out}/", flush=True)
    t0, c0 = time.perf_counter(), time.process_time()
    with tempfile.TemporaryDirectory() as work:
        demo = args.source if args.source is not None else pathlib.Path(work) / "demo"
        if args.source is None:
            code = jmeshtex_main(
                ["demo", "--out", str(demo), "--no-progress", *([] if args.full else ["--quick"])]
            )
            if code != 0:
                return code
        else:
            print((demo / "report.txt").read_text(encoding="utf-8"), end="")
        for method, name in FIGURES.items():
            size = _store(demo / method / name, out / f"{method}.png")
            print(f"{out / (method + '.png')}: {size / 1e3:.0f} KB")
    print(
        f"total: {time.perf_counter() - t0:.1f} s wall, {time.process_time() - c0:.1f} s process CPU"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""``python -m benchmarks``: run benchmark sweeps, tabulate and plot them, compare two runs.

Usage (from the repository root)::

    python -m benchmarks list
    python -m benchmarks run ops_face_conv ops_field_conv --sizes 5 6 --threads 1 2 --repeats 3 --out sweep/
    python -m benchmarks run --quick --out /tmp/q           # every benchmark with tiny settings
    python -m benchmarks run ceilings --sizes 1024 --dtypes float32 float64 --out sweep/
    python -m benchmarks import --out committed/            # benchmarks/results/*.json in the sweep schema
    python -m benchmarks table sweep/sweep.json
    python -m benchmarks plot sweep/sweep.json --out sweep/
    python -m benchmarks compare old/sweep.json new/sweep.json --threshold 0.1   # exit 1 on a regression
    python -m benchmarks compare benchmarks/results/ops_face_conv.json new/sweep.json

``run`` writes ``sweep.json`` (the schema of :mod:`benchmarks._runner`), ``sweep.md`` (with the
Growth table: exponents ± 95 % confidence half-widths, and any warning) and the plots
``scaling.png`` / ``ceiling.png`` into ``--out``; it exits 1 when a cell failed. ``compare`` matches
a figure exactly, or by interpolating OLD's times over size within OLD's sizes (never
extrapolating), and says how many matched each way; it exits 1 on a regression, 2 when nothing
matched.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

from ._compare import compare, compare_markdown, summary_line
from ._runner import BENCHMARKS, import_results, load_sweep, markdown, plot, sweep


def _write(doc: dict, out: pathlib.Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / "sweep.json").write_text(json.dumps(doc, indent=1, default=float))
    (out / "sweep.md").write_text(markdown(doc))
    paths = plot(doc, out)
    print(f"wrote {out / 'sweep.json'}, sweep.md" + "".join(f", {p.name}" for p in paths))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="the benchmarks and their axes")
    r = sub.add_parser("run", help="run benchmarks over a grid")
    r.add_argument(
        "names",
        nargs="*",
        help="benchmarks (default: all; with --quick: all that have quick settings)",
    )
    r.add_argument("--sizes", nargs="+", default=None, help="the sizes, in each script's own unit")
    r.add_argument("--dtypes", nargs="+", default=None)
    r.add_argument("--presets", nargs="+", default=None)
    r.add_argument(
        "--threads", type=int, nargs="+", default=None, help="cores each cell is pinned to"
    )
    r.add_argument("--repeats", type=int, default=1, help="processes per cell (the noise estimate)")
    r.add_argument("--quick", action="store_true", help="tiny sizes (the test suite's sweep)")
    r.add_argument("--timeout", type=float, default=3600, help="seconds per cell")
    r.add_argument("--out", type=pathlib.Path, required=True)
    i = sub.add_parser("import", help="the committed results/*.json as one sweep")
    i.add_argument("names", nargs="*")
    i.add_argument("--out", type=pathlib.Path, required=True)
    t = sub.add_parser("table", help="markdown table of a sweep")
    t.add_argument("sweep", type=pathlib.Path)
    p = sub.add_parser("plot", help="scaling and ceiling plots of a sweep")
    p.add_argument("sweep", type=pathlib.Path)
    p.add_argument("--out", type=pathlib.Path, required=True)
    c = sub.add_parser(
        "compare", help="per-figure ratios (interpolated over size); exit 1 on a regression"
    )
    c.add_argument("old", type=pathlib.Path)
    c.add_argument("new", type=pathlib.Path)
    c.add_argument(
        "--threshold", type=float, default=0.10, help="slowdown that fails (0.10 = 10%%)"
    )
    c.add_argument(
        "--sigmas", type=float, default=3.0, help="noise multiples a slowdown must exceed"
    )
    args = ap.parse_args(argv)

    if args.command == "list":
        for name, b in BENCHMARKS.items():
            axes = [
                a
                for a, f in (
                    ("sizes", b.size_args),
                    ("presets", b.preset_args),
                    ("dtypes", b.dtype_args),
                )
                if f
            ]
            print(
                f"{name:16s} axes: {', '.join(axes + ['threads']):28s} quick: {' '.join(b.quick_args or ('-',))}"
            )
        return 0
    if args.command == "run":
        names = args.names or list(BENCHMARKS)
        doc = sweep(
            names,
            sizes=args.sizes,
            dtypes=args.dtypes,
            presets=args.presets,
            threads=args.threads,
            repeats=args.repeats,
            quick=args.quick,
            out=args.out,
            timeout=args.timeout,
        )
        _write(doc, args.out)
        failed = [c for c in doc["cells"] if c["returncode"] != 0]
        return 1 if failed or not doc["cells"] else 0
    if args.command == "import":
        _write(import_results(args.names or None), args.out)
        return 0
    if args.command == "table":
        print(markdown(load_sweep(args.sweep)), end="")
        return 0
    if args.command == "plot":
        for path in plot(load_sweep(args.sweep), args.out):
            print(f"wrote {path}")
        return 0
    rows, failed = compare(
        load_sweep(args.old), load_sweep(args.new), threshold=args.threshold, sigmas=args.sigmas
    )
    print(compare_markdown(rows, threshold=args.threshold), end="")
    matched = [r for r in rows if r["match"] is not None]
    if not matched:
        print(
            f"no figure in common ({summary_line(rows)}): NEW's sizes lie outside OLD's or its "
            "series are not in OLD",
            file=sys.stderr,
        )
        return 2
    print(
        f"{sum(r['status'] == 'REGRESSION' for r in matched)} regression(s) of {len(matched)} "
        "matched figures"
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

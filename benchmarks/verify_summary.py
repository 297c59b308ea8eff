"""Summarise ``jmeshtex verify --json`` results as the Markdown table in the README.

Usage: ``python benchmarks/verify_summary.py [benchmarks/results/verify.json]`` prints one row per
registered operator: number of checks, the largest relative error over the exact transforms in
float64 / float32, the smallest observed convergence order over the smooth isometries, the checks
that are reported only (with their float64 error) and, for negative controls, the transforms that
flag them.
"""

from __future__ import annotations

import json
import pathlib
import sys


def summary_table(results: list[dict]) -> str:
    """Markdown table of :func:`jmeshtex.testing.to_json` results, one row per operator."""
    rows = [
        "| operator | checks | max rel. error, exact transforms (f64 / f32) | smallest order, smooth isometries "
        "| reported only (f64 error) | negative control flagged by |",
        "|---|---|---|---|---|---|",
    ]
    entries = list(dict.fromkeys(r["entry"] for r in results))
    for name in entries:
        mine = [r for r in results if r["entry"] == name]
        exact = {
            dt: [
                r["error"]
                for r in mine
                if r["check"] == "exact"
                and not r["expect_fail"]
                and r["passed"] is not None
                and r["dtype"] == dt
            ]
            for dt in ("float64", "float32")
        }
        err = " / ".join(f"{max(v):.1e}" if v else "–" for v in exact.values())
        orders = [
            r["order"]
            for r in mine
            if r["check"] == "order" and r["order"] is not None and r["passed"] is not None
        ]
        reported = [
            f"{r['transform']} ({r['error']:.1e})"
            for r in mine
            if r["passed"] is None and r["dtype"] == "float64"
        ]
        flagged = [
            f"{r['transform']} ({r['error']:.1e})"
            for r in mine
            if r["expect_fail"] and r["dtype"] == "float64"
        ]
        rows.append(
            f"| `{name}` | {len(mine)} | {err} | {min(orders):.2f} | "
            if orders
            else f"| `{name}` | {len(mine)} | {err} |  | "
        )
        rows[-1] += f"{', '.join(reported)} | {', '.join(flagged)} |"
    failed = sum(r["passed"] is False for r in results)
    passed = sum(r["passed"] is True for r in results)
    reported = sum(r["passed"] is None for r in results)
    return (
        "\n".join(rows)
        + f"\n\n{len(results)} checks: {passed} passed, {failed} failed, {reported} reported."
    )


def main() -> None:
    path = pathlib.Path(
        sys.argv[1]
        if len(sys.argv) > 1
        else pathlib.Path(__file__).parent / "results" / "verify.json"
    )
    print(summary_table(json.loads(path.read_text())["results"]))


if __name__ == "__main__":
    main()

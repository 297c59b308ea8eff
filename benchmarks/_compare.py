"""``python -m benchmarks compare OLD.json NEW.json``: per-figure ratios, noise from repeats, regressions."""

from __future__ import annotations

import statistics

from ._runner import _fmt, figure_key


def compare(
    old: dict, new: dict, *, threshold: float = 0.10, sigmas: float = 3.0, min_noise: float = 0.02
) -> tuple[list[dict], bool]:
    """Per-figure time ratios ``new / old`` and which are regressions.

    The noise of a figure is the larger relative spread ``(max - min) / median`` of its repeats in
    either file (at least ``min_noise``: one run says nothing about noise). A figure is *flagged*
    when ``ratio - 1 > sigmas · noise`` (slower beyond the noise) and *fails* when it is flagged and
    also ``ratio - 1 > threshold``.

    Returns:
      ``(rows, failed)``: one row per figure in both files (``key, old, new, ratio, noise, status``
      with status ``ok``, ``faster``, ``slower (noise)``, ``REGRESSION``) and whether any failed.

    Example:
      >>> f = lambda s: {"figures": [{"benchmark": "b", "name": "x", "params": {}, "seconds": s[0], "runs": s}]}
      >>> rows, failed = compare(f([1.0, 1.01]), f([1.5, 1.52]))
      >>> rows[0]["status"], round(rows[0]["ratio"], 2), failed
      ('REGRESSION', 1.5, True)
    """
    before = {figure_key(f): f for f in old["figures"] if f.get("seconds")}
    rows, failed = [], False
    for f in new["figures"]:
        key = figure_key(f)
        if not f.get("seconds") or key not in before:
            continue
        o = before[key]

        def spread(runs):
            return (max(runs) - min(runs)) / statistics.median(runs) if len(runs) > 1 else 0.0

        noise = max(spread(o.get("runs") or []), spread(f.get("runs") or []), min_noise)
        ratio = f["seconds"] / o["seconds"]
        if ratio - 1 > sigmas * noise:
            status = "REGRESSION" if ratio - 1 > threshold else "slower (noise)"
        elif 1 - ratio > sigmas * noise:
            status = "faster"
        else:
            status = "ok"
        failed |= status == "REGRESSION"
        rows.append(
            {
                "key": key,
                "old": o["seconds"],
                "new": f["seconds"],
                "ratio": ratio,
                "noise": noise,
                "status": status,
            }
        )
    return rows, failed


def compare_markdown(rows: list[dict], *, threshold: float) -> str:
    lines = [
        f"| figure | old s | new s | new/old | noise | status (fail: > {threshold:.0%} and beyond noise) |",
        "|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {r['key']} | {_fmt(r['old'])} | {_fmt(r['new'])} | {r['ratio']:.3f} | {r['noise']:.3f} | "
        f"{r['status']} |"
        for r in rows
    ]
    return "\n".join(lines) + "\n"

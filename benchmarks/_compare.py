"""``python -m benchmarks compare OLD.json NEW.json``: per-figure ratios, noise from repeats,
regressions; figures at sizes OLD did not run are compared by interpolating over size."""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence

from ._runner import _fmt, _fmt_n, figure_key, recorded_count, series_key


def _spread(runs: Sequence[float]) -> float:
    return (max(runs) - min(runs)) / statistics.median(runs) if len(runs) > 1 else 0.0


def _interpolate(points: list[tuple[float, dict]], n: float) -> tuple[float, float, tuple] | str:
    """OLD's seconds of one series at size ``n``: linear in log time against log size between the
    two sizes around ``n`` (figures at one size pooled by their geometric mean). Returns
    ``(seconds, spread, (n_below, n_above))``, or why there is none (``n`` outside the sizes)."""
    by_size: dict[float, list[dict]] = {}
    for size, fig in points:
        by_size.setdefault(float(size), []).append(fig)
    sizes = sorted(by_size)
    if not sizes[0] <= n <= sizes[-1]:
        return (
            f"size {_fmt_n(n)} outside OLD's sizes {_fmt_n(sizes[0])}..{_fmt_n(sizes[-1])} "
            "(never extrapolated)"
        )

    def at(size: float) -> tuple[float, float]:
        figs = by_size[size]
        log_t = sum(math.log(f["seconds"]) for f in figs) / len(figs)
        return log_t, max(_spread(f.get("runs") or []) for f in figs)

    if n in by_size:
        log_t, spread = at(n)
        return math.exp(log_t), spread, (n, n)
    hi = next(s for s in sizes if s > n)
    lo = sizes[sizes.index(hi) - 1]
    (t_lo, s_lo), (t_hi, s_hi) = at(lo), at(hi)
    w = (math.log(n) - math.log(lo)) / (math.log(hi) - math.log(lo))
    return math.exp((1 - w) * t_lo + w * t_hi), max(s_lo, s_hi), (lo, hi)


def compare(
    old: dict, new: dict, *, threshold: float = 0.10, sigmas: float = 3.0, min_noise: float = 0.02
) -> tuple[list[dict], bool]:
    """Per-figure time ratios ``new / old`` and which are regressions.

    A timed figure of NEW is matched to OLD *exactly* when OLD has its :func:`figure_key` (series
    and size label; where both rows recorded a true count, the counts agree too). Otherwise it is
    matched *by interpolation* when OLD has its series (:func:`series_key`: everything but the
    size) at sizes around its own: OLD's log time is interpolated linearly in log size at NEW's
    size (at an OLD size itself, that figure's time). A size outside OLD's range of that series is
    never extrapolated: the figure is *unmatched*, and so is one whose series OLD lacks or whose size
    is unknown.

    The noise of a figure is the larger relative spread ``(max - min) / median`` of its repeats in
    either file (for an interpolated one, the larger of its two OLD neighbours'), at least
    ``min_noise``: one run says nothing about noise. A figure is *flagged* when ``ratio - 1 >
    sigmas · noise`` (slower beyond the noise) and *fails* when it is flagged and also ``ratio - 1 >
    threshold``.

    Returns:
      ``(rows, failed)``: one row per timed figure of NEW (``key, match, old, new, ratio, noise,
      status``; ``match`` is ``"exact"``, ``"interpolated"`` (with ``old_sizes``, the two OLD sizes
      used) or None (then ``old``/``ratio``/``noise`` are None and ``reason`` says why); ``status``
      is ``ok``, ``faster``, ``slower (noise)``, ``REGRESSION`` or ``unmatched``) and whether any
      failed.

    Example:
      >>> f = lambda s: {"figures": [{"benchmark": "b", "name": "x", "params": {}, "seconds": s[0], "runs": s}]}
      >>> rows, failed = compare(f([1.0, 1.01]), f([1.5, 1.52]))
      >>> rows[0]["status"], rows[0]["match"], round(rows[0]["ratio"], 2), failed
      ('REGRESSION', 'exact', 1.5, True)
      >>> g = lambda n, s: {"benchmark": "b", "name": "x", "params": {"n": n}, "seconds": s, "runs": [s]}
      >>> rows, _ = compare({"figures": [g(1e3, 1.0), g(1e5, 100.0)]}, {"figures": [g(1e4, 10.0), g(1e6, 1.0)]})
      >>> [(r["match"], r["old"] and round(r["old"], 6)) for r in rows]
      [('interpolated', 10.0), (None, None)]
    """
    timed_old = [f for f in old["figures"] if f.get("seconds")]
    before: dict[str, list[dict]] = {}
    by_series: dict[str, list[tuple[float, dict]]] = {}
    old_series = {series_key(f) for f in timed_old}
    for f in timed_old:
        before.setdefault(figure_key(f), []).append(f)
        if f["params"].get("n") and f["params"]["n"] > 0:
            by_series.setdefault(series_key(f), []).append((f["params"]["n"], f))
    rows, failed = [], False
    for f in new["figures"]:
        if not f.get("seconds"):
            continue
        key, count = figure_key(f), recorded_count(f)
        row = {"key": key, "match": None, "old": None, "new": f["seconds"], "ratio": None}
        row.update(noise=None, status="unmatched")
        exact = [
            o
            for o in before.get(key, [])
            if count is None or recorded_count(o) is None or recorded_count(o) == count
        ]
        n = f["params"].get("n")
        if exact:
            o = exact[0]
            row.update(match="exact", old=o["seconds"], old_spread=_spread(o.get("runs") or []))
        elif series_key(f) not in old_series:
            row["reason"] = "series not in OLD"
        elif not n or n <= 0:
            row["reason"] = "size unknown"
        elif series_key(f) not in by_series:
            row["reason"] = "OLD has this series only at sizes it could not determine"
        else:
            found = _interpolate(by_series[series_key(f)], float(n))
            if isinstance(found, str):
                row["reason"] = found
            else:
                seconds, spread, sizes = found
                row.update(match="interpolated", old=seconds, old_spread=spread, old_sizes=sizes)
        if row["match"] is not None:
            noise = max(row.pop("old_spread"), _spread(f.get("runs") or []), min_noise)
            ratio = f["seconds"] / row["old"]
            if ratio - 1 > sigmas * noise:
                status = "REGRESSION" if ratio - 1 > threshold else "slower (noise)"
            elif 1 - ratio > sigmas * noise:
                status = "faster"
            else:
                status = "ok"
            failed |= status == "REGRESSION"
            row.update(ratio=ratio, noise=noise, status=status)
        rows.append(row)
    return rows, failed


def match_counts(rows: list[dict]) -> dict[str, int]:
    """How many of NEW's timed figures matched exactly, by interpolation, and not at all.

    Example:
      >>> match_counts([{"match": "exact"}, {"match": "interpolated"}, {"match": None}, {"match": None}])
      {'exact': 1, 'interpolated': 1, 'unmatched': 2}
    """
    return {
        "exact": sum(r["match"] == "exact" for r in rows),
        "interpolated": sum(r["match"] == "interpolated" for r in rows),
        "unmatched": sum(r["match"] is None for r in rows),
    }


def summary_line(rows: list[dict]) -> str:
    """One line: of NEW's timed figures, how many matched exactly, by interpolation, not at all."""
    c = match_counts(rows)
    return (
        f"{len(rows)} timed figures in NEW: {c['exact']} matched exactly, {c['interpolated']} by "
        f"interpolation over size, {c['unmatched']} not at all"
    )


def compare_markdown(rows: list[dict], *, threshold: float) -> str:
    """The matched figures as a table, the match counts, and each unmatched figure with why."""
    lines = [
        f"| figure | match | old s | new s | new/old | noise | status (fail: > {threshold:.0%} and "
        "beyond noise) |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r["match"] is None:
            continue
        match = r["match"]
        if match == "interpolated":
            lo, hi = r["old_sizes"]
            match += f" ({_fmt_n(lo)})" if lo == hi else f" ({_fmt_n(lo)}..{_fmt_n(hi)})"
        lines.append(
            f"| {r['key']} | {match} | {_fmt(r['old'])} | {_fmt(r['new'])} | {r['ratio']:.3f} | "
            f"{r['noise']:.3f} | {r['status']} |"
        )
    lines += ["", summary_line(rows)]
    unmatched = [r for r in rows if r["match"] is None]
    if unmatched:
        lines += ["", "Not matched:", *(f"- {r['key']}: {r['reason']}" for r in unmatched)]
    return "\n".join(lines) + "\n"

"""Study: what one MeshMatch option costs, the benchmark's speed suite with other ``Config`` fields.

``python studies/meshmatch_options.py FIELD=VALUE [...] --name NAME [--sizes 16]``: the speed
suite of ``benchmarks/meshmatch.py`` (a bumpy torus source of 10K vertices, its self-transfer to
16K / 64K target vertices: preprocessing, the finest level's PatchMatch iteration, the total, the
PSNR beside the nearest-3D copy) with the fields given (Python literals, e.g. ``vote="'fan'"``,
``propagation="'sequential'"``). Writes ``studies/results/NAME.{json,md}``; the committed ones:

    python studies/meshmatch_options.py vote="'fan'" --name meshmatch_vote_fan
    python studies/meshmatch_options.py vote="'ring'" --name meshmatch_vote_ring
    python studies/meshmatch_options.py propagation="'sequential'" --name meshmatch_sequential
"""

from __future__ import annotations

import argparse
import ast

from _study import Report
from meshmatch import speed

from jmeshtex.meshmatch import Config


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "fields", nargs="+", metavar="FIELD=VALUE", help="Config fields over the default"
    )
    ap.add_argument("--name", required=True, help="the report's name (studies/results/NAME.*)")
    ap.add_argument("--sizes", default="16", help="target sizes in K vertices (16 and/or 64)")
    args = ap.parse_args(argv)
    changes = dict(item.split("=", 1) for item in args.fields)
    cfg = Config.from_dict({k: ast.literal_eval(v) for k, v in changes.items()})
    report = Report(args.name)
    report.notes.append(f"Config overrides: {', '.join(args.fields)}")
    speed(report, cfg, [int(s) for s in args.sizes.split(",")])
    report.write()


if __name__ == "__main__":
    main()

"""The second fault campaign's larger sweep (issue 57), outside CI.

Two parts, each counted as (inputs tried, bad outcomes, root causes with a bad outcome):

1. the seeded generators of ``tests/test_fault_campaign.py`` over ``--seeds`` seeds (every seed
   draws new names, sizes, damaged files and damage kinds);
2. the issue's own reproducers, run as separate ``jmeshtex`` processes (a FIFO or a training run
   cannot hang or pollute this process), each with a wall-clock limit; every file the "user" made
   is checksummed before and after.

A bad outcome: an exit status other than the expected one, a traceback on stderr, a changed or
missing user file, a timeout, or a wrong result. Run from the repository root::

    PYTHONPATH=. python studies/fault_campaign_2.py --seeds 20

It prints one line per reproducer and the totals; nothing is written outside a temporary folder.
"""

from __future__ import annotations

import argparse
import collections
import hashlib
import importlib.util
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
PYRAMID = QUAD + "v 0.5 0.5 1\n"


def _campaign_module():
    spec = importlib.util.spec_from_file_location(
        "fault_campaign", ROOT / "tests" / "test_fault_campaign.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def _digests(paths) -> dict[str, str]:
    out = {}
    for root in paths:
        root = pathlib.Path(root)
        for p in [root] if not root.is_dir() else sorted(root.rglob("*")):
            if p.is_symlink():
                out[str(p)] = "link"
            elif p.is_file():
                out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest()
            elif p.exists():
                out[str(p)] = "other"
    return out


def _jmeshtex(args, *, cwd, timeout=600, env=None):
    environment = {**os.environ, "PYTHONPATH": str(ROOT), "JMESHTEX_JAX_CACHE": "0", **(env or {})}
    start = time.perf_counter()
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "jmeshtex", *map(str, args)],
            cwd=cwd,
            env=environment,
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        return None, "", time.perf_counter() - start
    return proc.returncode, proc.stderr, time.perf_counter() - start


def _png(path, rng, size=4):
    from jmeshtex.io import save_png

    save_png(rng.random((size, size, 3)), path)


def reproducers(tmp: pathlib.Path, rng: np.random.Generator):
    """``(cause, name, argv, expected rc, user files, check(folder) or None, env)`` per reproducer."""
    out = []
    # 1: --overwrite into a folder with foreign checkpoints; dgts train DIR with a foreign sample
    d = tmp / "r1"
    for n in ("1", "100"):
        (d / "checkpoints" / n).mkdir(parents=True)
    (d / "checkpoints" / "100" / "holiday.jpg").write_text("x")
    out.append(
        (
            1,
            "fldm train --overwrite over foreign checkpoints/",
            [
                "fldm",
                "train",
                "--mesh",
                "striped-sphere:1",
                "--preset",
                "tiny",
                "--codec",
                "stripes",
                "--copies",
                "2",
                "--vertices",
                "100",
                "--steps",
                "300",
                "--overwrite",
                "--out",
                d,
                "--quiet",
            ],
            2,
            [d / "checkpoints"],
            None,
            None,
        )
    )
    d = tmp / "r1b"
    d.mkdir()
    (d / "sample.obj").write_text(QUAD + "f 1 2 3\n")
    out.append(
        (
            1,
            "dgts train DIR with a foreign sample.obj",
            ["dgts", "train", d, "--quiet"],
            2,
            [d / "sample.obj"],
            None,
            None,
        )
    )
    # 2: the texture an OBJ's MTL names is an input
    d = tmp / "r2"
    d.mkdir()
    _png(d / "tex.png", rng)
    (d / "m.mtl").write_text("newmtl a\nmap_Kd tex.png\n")
    (d / "m.obj").write_text(
        "mtllib m.mtl\n" + PYRAMID + "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "vt .5 .5\nusemtl a\nf 1/1 3/3 2/2\nf 1/1 4/4 3/3\nf 1/1 2/2 5/5\n"
        "f 2/2 3/3 5/5\nf 3/3 4/4 5/5\nf 4/4 1/1 5/5\n"
    )
    out.append(
        (
            2,
            "info m.obj --render tex.png",
            ["info", d / "m.obj", "--render", d / "tex.png"],
            2,
            [d],
            None,
            None,
        )
    )
    # 5: FIFOs and /dev/zero
    d = tmp / "r5"
    d.mkdir()
    os.mkfifo(d / "fifo.obj")
    (d / "zero.obj").symlink_to("/dev/zero")
    os.mkfifo(d / "fifo.png")
    sub = d / "m"
    sub.mkdir()
    (sub / "m.obj").write_text(
        "mtllib m.mtl\n" + PYRAMID + "f 1 3 2\nf 1 4 3\nf 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\n"
    )
    os.mkfifo(sub / "m.mtl")
    out += [
        (5, "info FIFO", ["info", d / "fifo.obj"], 2, [], None, None),
        (5, "info link to /dev/zero", ["info", d / "zero.obj"], 2, [], None, None),
        (
            5,
            "info --texture FIFO",
            ["info", "icosphere:1", "--texture", d / "fifo.png"],
            2,
            [],
            None,
            None,
        ),
        (
            5,
            "mtllib is a FIFO (loads without it)",
            ["info", sub / "m.obj"],
            0,
            [sub / "m.obj"],
            None,
            None,
        ),
        (
            5,
            "surfacecnn --exemplar FIFO",
            [
                "surfacecnn",
                "synthesize",
                "--mesh",
                "icosphere:2",
                "--exemplar",
                d / "fifo.png",
                "--out",
                d / "o",
                "--quiet",
            ],
            2,
            [],
            None,
            None,
        ),
    ]
    # 7: sizes
    o = tmp / "r7"
    np.save(tmp / "labels.npy", np.array([0, 1, 10**9]))
    out += [
        (
            7,
            "surfacecnn --size 1000000",
            [
                "surfacecnn",
                "synthesize",
                "--mesh",
                "torus",
                "--exemplar",
                "x.png",
                "--size",
                "1000000",
                "--out",
                o,
            ],
            2,
            [],
            None,
            None,
        ),
        (
            7,
            "fl reconstruct --size 100000",
            ["fl", "reconstruct", "--mesh", "torus", "--size", "100000", "--out", o],
            2,
            [],
            None,
            None,
        ),
        (
            7,
            "fl reconstruct --vertices 100000000",
            ["fl", "reconstruct", "--mesh", "torus", "--vertices", "100000000", "--out", o],
            2,
            [],
            None,
            None,
        ),
        (
            7,
            "fldm train --vertices 1000000000",
            ["fldm", "train", "--mesh", "icosphere:1", "--vertices", "1000000000", "--out", o],
            2,
            [],
            None,
            None,
        ),
        (
            7,
            "dgts prepare --samples 1000000000",
            [
                "dgts",
                "prepare",
                "--reference",
                "icosphere:1",
                "--samples",
                "1000000000",
                "--out",
                o,
            ],
            2,
            [],
            None,
            None,
        ),
        (
            7,
            "labels with maximum 1e9",
            [
                "fldm",
                "train",
                "--mesh",
                "icosphere:1",
                "--labels",
                tmp / "labels.npy",
                "--out",
                o,
                "--quiet",
            ],
            2,
            [tmp / "labels.npy"],
            None,
            None,
        ),
    ]
    # 8: what used to be tracebacks
    for i, text in enumerate(("{bad", "[1, 2]", '{"remeshes": "two"}')):
        d = tmp / f"r8_{i}"
        d.mkdir()
        (d / "prepare.json").write_text(text)
        out.append(
            (
                8,
                f"dgts train, prepare.json {text!r}",
                ["dgts", "train", d, "--overwrite"],
                2,
                [d / "prepare.json"],
                None,
                None,
            )
        )
    for kind, arr in (("empty", np.zeros(0, np.int64)), ("NaN", np.array([0.0, np.nan]))):
        np.save(tmp / f"l_{kind}.npy", arr)
        out.append(
            (
                8,
                f"fldm train --labels {kind}",
                [
                    "fldm",
                    "train",
                    "--mesh",
                    "icosphere:1",
                    "--labels",
                    tmp / f"l_{kind}.npy",
                    "--out",
                    tmp / "r8o",
                    "--quiet",
                ],
                2,
                [tmp / f"l_{kind}.npy"],
                None,
                None,
            )
        )
    (tmp / "cachefile").write_text("x")
    out.append(
        (
            8,
            "JMESHTEX_JAX_CACHE is a file",
            ["fl", "encode", "--mesh", "icosahedron", "--out", tmp / "enc.npz"],
            2,
            [tmp / "cachefile"],
            None,
            {"JMESHTEX_JAX_CACHE": str(tmp / "cachefile")},
        )
    )
    d = tmp / "r8s"
    d.mkdir()
    (tmp / "elsewhere").mkdir()
    (tmp / "elsewhere" / "keep.txt").write_text("mine")
    (d / "checkpoints").symlink_to(tmp / "elsewhere")
    out.append(
        (
            8,
            "surfacecnn with a symlinked checkpoints/",
            [
                "surfacecnn",
                "synthesize",
                "--mesh",
                "icosphere:2",
                "--exemplar",
                tmp / "x16.png",
                "--steps",
                "1",
                "--size",
                "16",
                "--out",
                d,
                "--overwrite",
                "--quiet",
            ],
            2,
            [tmp / "elsewhere"],
            None,
            None,
        )
    )
    _png(tmp / "x16.png", rng, 16)
    # 9: damaged files
    d = tmp / "r9"
    d.mkdir()
    from jmeshtex.data import icosphere

    v, f = icosphere(1)
    body = [" ".join(map(str, x)) for x in v] + ["3 " + " ".join(map(str, x)) for x in f]
    (d / "lying.off").write_text(f"OFF\n{len(v)} {len(f)} 0\n" + "\n".join(body[:-4]) + "\n")
    (d / "vt.obj").write_text(PYRAMID + "vt 0 0\nf 1/1 3/9 2/1\n")
    (d / "nan.obj").write_text("v 0 0 0 nan 0 0\nv 1 0 0 1 0 0\nv 0 1 0 0 1 0\nf 1 2 3\n")
    out += [
        (9, "OFF 76 of 80 faces", ["info", d / "lying.off"], 2, [d], None, None),
        (9, "vt index out of range", ["info", d / "vt.obj"], 2, [d], None, None),
        (9, "NaN vertex colours", ["info", d / "nan.obj"], 2, [d], None, None),
    ]
    # 10: valid inputs accepted, the right cause named
    d = tmp / "r10"
    d.mkdir()
    (d / "uv.obj").write_text(
        PYRAMID + "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt .5 .5\n"
        "f 1/1 3/3 2/2\nf 1/1 4/4 3/3\nf 1/1 2/2 5/5\nf 2/2 3/3 5/5\n"
        "f 3/3 4/4 5/5\nf 4/4 1/1 5/5\n"
    )
    (d / "tabs.obj").write_text(
        PYRAMID.replace(" ", "\t") + "f\t1\t3\t2\nf\t1\t4\t3\nf\t1\t2\t5\n"
        "f\t2\t3\t5\nf\t3\t4\t5\nf\t4\t1\t5\n"
    )
    (d / "zero.obj").write_text(PYRAMID + "f 0 2 1\nf 0 3 2\nf 0 1 4\nf 1 2 4\nf 2 3 4\nf 3 0 4\n")
    out += [
        (
            10,
            "info --render of an OBJ with vt and no material",
            ["info", d / "uv.obj", "--render", d / "uv.png"],
            0,
            [d / "uv.obj"],
            lambda d=d: (d / "uv.png").is_file(),
            None,
        ),
        (10, "tab-separated OBJ", ["info", d / "tabs.obj"], 0, [d / "tabs.obj"], None, None),
        (10, "0-based OBJ", ["info", d / "zero.obj"], 2, [d / "zero.obj"], None, None),
        (10, "icosahedron:7", ["info", "icosahedron:7"], 2, [], None, None),
        (
            10,
            "fldm train --steps -1",
            ["fldm", "train", "--mesh", "icosphere:1", "--steps", "-1", "--out", d / "o"],
            2,
            [],
            None,
            None,
        ),
    ]
    # 11: meshmatch onto a target with UVs: the render and the texture keep apart
    d = tmp / "r11"
    d.mkdir()
    from jmeshtex import Mesh
    from jmeshtex.io import save_mesh

    v3, f3 = icosphere(3)
    save_mesh(Mesh(v3, f3, uv=v3[f3][..., :2] * 0.5 + 0.5), d / "uv.obj")  # UVs, no texture

    def distinct(d=d):
        import json

        summary = json.loads((d / "o" / "summary.json").read_text())
        render, texture = d / "o" / "target.png", pathlib.Path(summary.get("texture", ""))
        return (
            render.is_file()
            and texture.is_file()
            and texture != render
            and str(render) in summary["renders"]
        )

    out.append(
        (
            11,
            "meshmatch transfer onto a UV target",
            [
                "meshmatch",
                "transfer",
                "--source",
                "striped-sphere:3",
                "--target",
                d / "uv.obj",
                "--out",
                d / "o",
                "--quiet",
            ],
            0,
            [d / "uv.obj"],
            distinct,
            None,
        )
    )
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--skip-reproducers", action="store_true")
    args = parser.parse_args()
    module = _campaign_module()
    tried = bad = 0
    bad_causes: set[int] = set()
    per_cause: collections.Counter = collections.Counter()
    start = time.perf_counter()
    for seed in range(args.seeds):
        with tempfile.TemporaryDirectory() as tmp:
            counts, failures = module.run_campaign(pathlib.Path(tmp), np.random.default_rng(seed))
        for (cause, outcome), n in counts.items():
            tried += n
            per_cause[cause] += n
            if outcome == "bad":
                bad += n
                bad_causes.add(cause)
        for name, why in failures:
            print(f"seed {seed}: BAD {name}: {why}")
    print(
        f"generators: {tried} inputs over {args.seeds} seeds in "
        f"{time.perf_counter() - start:.0f} s, {bad} bad, causes with a bad outcome: "
        f"{sorted(bad_causes) or 'none'}; per cause {dict(sorted(per_cause.items()))}"
    )
    if args.skip_reproducers:
        return int(bad > 0)
    r_tried = r_bad = 0
    r_causes: set[int] = set()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        for cause, name, argv, want, user, check, env in reproducers(tmp, np.random.default_rng(0)):
            before = _digests(user)
            rc, err, seconds = _jmeshtex(argv, cwd=tmp, env=env)
            after = _digests(user)
            problems = []
            if rc is None:
                problems.append("timed out")
            elif rc != want:
                problems.append(f"exit {rc}, expected {want}")
            if "Traceback" in err:
                problems.append("traceback")
            if before != after:
                problems.append("user files changed")
            if check is not None and rc == want and not check():
                problems.append("wrong result")
            r_tried += 1
            line = err.strip().splitlines()[-1][:160] if err.strip() else ""
            status = "ok " if not problems else "BAD"
            print(
                f"{status} [{cause:2d}] {name} (rc {rc}, {seconds:.1f} s) {'; '.join(problems)}"
                f"\n      {line}"
            )
            if problems:
                r_bad += 1
                r_causes.add(cause)
    print(
        f"reproducers: {r_tried} tried, {r_bad} bad, causes with a bad outcome: "
        f"{sorted(r_causes) or 'none'}"
    )
    print(
        f"total: {tried + r_tried} inputs, {bad + r_bad} bad outcomes, "
        f"{len(bad_causes | r_causes)} root causes"
    )
    return int(bad + r_bad > 0)


if __name__ == "__main__":
    sys.exit(main())

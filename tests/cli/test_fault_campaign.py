"""The fault campaign in the suite: bad files and bad arguments through the main subcommands.

Every case runs in-process through ``jmeshtex.cli.main`` and must end, within a modest time, in
either a non-zero exit with one error line and no traceback, or exit 0 with only finite numbers in
what it wrote. No input file may change. The cases come from :mod:`jmeshtex.testing`
(``write_bad_mesh_files``, ``BAD_ARGUMENTS``); the per-class counts are printed (``-s``).
"""

from __future__ import annotations

import collections
import contextlib
import hashlib
import io
import pathlib
import time
import warnings

import numpy as np
import pytest

from jmeshtex.cli import main
from jmeshtex.io import load_mesh, save_png
from jmeshtex.testing import BAD_ARGUMENTS, BAD_MESH_FILES, write_bad_mesh_files

#: seconds one case may take (each is refused before any training; the slowest fits a 1-level
#: DGTS template in a few seconds on a loaded 2-core machine)
CASE_SECONDS = 30.0

#: the main mesh-taking subcommands, each given one mesh file and a fresh --out
COMMANDS = {
    "info": lambda mesh, out, ex: ["info", mesh],
    "meshmatch transfer": lambda mesh, out, ex: [
        *("meshmatch", "transfer", "--source", mesh, "--target", "torus:6:3"),
        *("--out", out, "--quiet"),
    ],
    "fl encode": lambda mesh, out, ex: ["fl", "encode", "--mesh", mesh, "--out", out + ".npz"],
    "surfacecnn synthesize": lambda mesh, out, ex: [
        *("surfacecnn", "synthesize", "--mesh", mesh, "--exemplar", ex, "--steps", "1"),
        *("--size", "16", "--out", out, "--quiet"),
    ],
    "dgts prepare": lambda mesh, out, ex: [
        *("dgts", "prepare", "--reference", mesh, "--levels", "1", "--steps", "1"),
        *("--samples", "200", "--out", out, "--quiet"),
    ],
    "fldm train": lambda mesh, out, ex: [
        *("fldm", "train", "--mesh", mesh, "--preset", "tiny", "--steps", "1"),
        *("--out", out, "--quiet"),
    ],
}

#: files no command may accept (the scale files are valid meshes: info and dgts take them)
ALWAYS_BAD = BAD_MESH_FILES[:6]


def _digest(folder: pathlib.Path) -> dict[str, str]:
    return {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.iterdir())
        if p.is_file()
    }


def _run(argv: list[str]) -> tuple[int, str, float]:
    err = io.StringIO()
    start = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # MeshRepairWarning notes etc. are not failures here
            try:
                rc = main(argv)
            except SystemExit as exit_:  # argparse: usage line + one error line, status 2
                rc = exit_.code
    return rc, err.getvalue(), time.perf_counter() - start


def _finite_outputs(out: pathlib.Path) -> list[str]:
    """Files under ``out`` holding a non-finite number (npz arrays, mesh vertices)."""
    bad = []
    files = [out] if out.is_file() else sorted(out.rglob("*")) if out.exists() else []
    for p in files:
        if p.suffix == ".npz":
            with np.load(p) as data:
                for key in data.files:
                    a = data[key]
                    if np.issubdtype(a.dtype, np.inexact) and not np.isfinite(a).all():
                        bad.append(f"{p.name}:{key}")
        elif p.suffix in (".obj", ".ply"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                if not np.isfinite(load_mesh(p).vertices).all():
                    bad.append(p.name)
    return bad


def _clean_failure(rc, err: str) -> bool:
    errors = [line for line in err.splitlines() if "error" in line.lower()]
    return rc not in (0, None) and "Traceback" not in err and len(errors) == 1


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("inputs")
    paths = write_bad_mesh_files(folder)
    save_png(np.random.default_rng(0).random((8, 8, 3)), folder / "exemplar.png")
    return folder, paths


def test_bad_mesh_files_through_every_command(inputs, tmp_path):
    folder, paths = inputs
    before = _digest(folder)
    counts: collections.Counter = collections.Counter()
    problems = []
    for name, path in paths.items():
        for command, build in COMMANDS.items():
            if name not in ALWAYS_BAD and command not in (
                "info",
                "dgts prepare",
                "surfacecnn synthesize",
            ):
                continue  # valid meshes at extreme scales: the commands that take untextured meshes
            out = tmp_path / f"{command.replace(' ', '_')}-{name}"
            rc, err, seconds = _run(build(str(path), str(out), str(folder / "exemplar.png")))
            outcome = "refused" if rc else "ran"
            if seconds > CASE_SECONDS:
                problems.append(f"{command} {name}: {seconds:.0f} s")
            if rc and not _clean_failure(rc, err):
                problems.append(f"{command} {name}: not one clean error line:\n{err}")
            if not rc:
                if name in ALWAYS_BAD:
                    problems.append(f"{command} {name}: accepted a broken mesh")
                nonfinite = _finite_outputs(
                    pathlib.Path(str(out) + ".npz") if command == "fl encode" else out
                )
                if nonfinite:
                    problems.append(f"{command} {name}: exit 0 with non-finite {nonfinite}")
            counts[(command, outcome)] += 1
    print(dict(counts))
    assert not problems, "\n".join(problems)
    assert _digest(folder) == before
    assert sum(counts.values()) == len(ALWAYS_BAD) * len(COMMANDS) + 3 * 3


#: what the error line of each BAD_ARGUMENTS case must mention (refused for the right reason)
EXPECT = {
    "info torus:0:0": "torus needs numbers >= 3",
    "info icosphere:-1": "icosphere needs numbers >= 0",
    "info icosphere:12 (size budget)": "vertices, more than",
    "info grid:x": "whole numbers expected",
    "seed 2**70": "argument --seed",
    "negative seed": "argument --seed",
    "fl train --stop-after -3": "argument --stop-after",
    "surfacecnn --max-image-size 0": "argument --max-image-size",
    "fldm sample --eta nan": "argument --eta",
    "fldm sample --eta inf": "argument --eta",
    "meshmatch --fan-radius 1e9": "argument --fan-radius",
    "meshmatch --fan-radius nan": "argument --fan-radius",
    "dgts prepare --levels 12": "argument --levels",
    "dgts prepare --levels 9 (face budget)": "faces at the finest level",
    "verify --only bogus": "not registered: bogus; registered operators: ",
    "procedural spec with too many numbers": "too many numbers",
    "fldm sample --n 0": "argument --num-samples/--n",
    "fldm train --labels missing": "cannot read --labels",
    "meshmatch paint --mask missing": "cannot read mask",
}


def test_bad_arguments_are_refused_before_any_work(tmp_path):
    assert set(EXPECT) == set(BAD_ARGUMENTS)
    problems = []
    for i, (name, argv) in enumerate(BAD_ARGUMENTS.items()):
        needs_out = argv[0] not in ("info", "verify")
        full = [*argv, *(["--out", str(tmp_path / f"out{i}")] if needs_out else [])]
        rc, err, seconds = _run(full)
        if not _clean_failure(rc, err) or EXPECT[name] not in err:
            problems.append(f"{name}: rc={rc}, stderr:\n{err}")
        if seconds > CASE_SECONDS / 3:
            problems.append(f"{name}: {seconds:.1f} s before the refusal")
    assert not problems, "\n".join(problems)
    # a failed command leaves no output folder behind
    assert not any(p.is_dir() for p in tmp_path.iterdir())


def test_the_harness_passes_good_input_and_sees_a_traceback():
    rc, err, _ = _run(["info", "icosphere:1"])
    assert rc == 0 and err == ""
    assert not _clean_failure(1, "Traceback (most recent call last):\nValueError: error\n")
    assert not _clean_failure(0, "")


def test_a_closed_pipe_ends_quietly():
    """``jmeshtex info … | head``: the reader goes away; no BrokenPipeError traceback."""
    import subprocess
    import sys

    code = (
        "import sys, time\n"
        "from jmeshtex.cli import main\n"
        "time.sleep(0.3)\n"  # let the reader close the pipe first
        "sys.exit(main(['info', 'icosphere:1']))\n"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    proc.stdout.close()  # the reader is gone before anything is written
    err = proc.stderr.read().decode()
    proc.stderr.close()
    assert proc.wait(timeout=120) == 141
    assert "Traceback" not in err and "BrokenPipeError" not in err, err


def test_a_mesh_out_of_float32_range_is_refused_before_any_work(tmp_path):
    """MeshMatch self-transfer of a 1e30-scaled mesh: the scale check refuses it, nothing written."""
    from jmeshtex.cli._common import procedural_mesh
    from jmeshtex.io import save_mesh

    mesh = procedural_mesh("striped-sphere:3")
    path = tmp_path / "huge.ply"
    save_mesh(mesh.replace(vertices=mesh.vertices * 1e30), path)
    out = tmp_path / "out"
    argv = ["meshmatch", "transfer", "--source", str(path), "--target", str(path)]
    rc, err, seconds = _run([*argv, "--out", str(out), "--quiet"])
    assert _clean_failure(rc, err) and "mean edge length 1.51e+29 is outside" in err, err
    assert seconds < CASE_SECONDS / 3
    assert not out.exists()


def test_a_result_that_is_not_finite_is_not_written(tmp_path, monkeypatch):
    """A transfer whose colours come back NaN (poisoned here, as an out-of-range mesh once did):
    refused after the match, nothing written."""
    import jmeshtex.meshmatch

    real = jmeshtex.meshmatch.transfer

    def poisoned(*args, **kwargs):
        result = real(*args, **kwargs)
        colors = np.full_like(result.mesh.vertex_colors, np.nan)
        return result._replace(mesh=result.mesh.replace(vertex_colors=colors))

    monkeypatch.setattr(jmeshtex.meshmatch, "transfer", poisoned)
    out = tmp_path / "out"
    argv = ["meshmatch", "transfer", "--source", "striped-sphere:1", "--target", "torus:6:3"]
    rc, err, seconds = _run([*argv, "--levels", "1", "--steps", "1", "--out", str(out), "--quiet"])
    assert _clean_failure(rc, err) and "colours are not finite" in err, err
    assert seconds < CASE_SECONDS
    assert not any(p.name.endswith((".ply", ".obj", ".json")) for p in out.rglob("*"))

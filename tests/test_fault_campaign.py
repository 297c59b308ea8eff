"""The second fault campaign in the suite: one seeded generator per root cause of issue 57.

Every case builds its inputs in a fresh folder from the seeded ``rng`` (names, sizes, which file is
damaged and how), runs one CLI command in-process (``jmeshtex.cli.main``) or one library call, and
must end within ``CASE_SECONDS`` in the outcome the case names: a typed error (a
:class:`~jmeshtex.JmeshtexError`, or argparse's one-line usage error, exit 2) or a correct result.
Every file the "user" put there is checksummed before and after: none may change or vanish. A
hanging read (a FIFO) is cut by ``SIGALRM`` and counts as a failure. The counts per root cause are
printed (``-s``); ``studies/fault_campaign_2.py`` runs the same generators over many seeds plus the
slow reproducers (training runs) and prints the totals.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import hashlib
import io
import os
import pathlib
import signal
import struct
import time
import warnings
import zlib
from collections.abc import Callable

import numpy as np
import pytest

from jmeshtex import JmeshtexError
from jmeshtex.cli import main

#: seconds one case may take (each is a refusal before any training, or a small load)
CASE_SECONDS = 20.0
#: seconds for a case whose command first imports a method package (flax, optax: ~10 s on a
#: 2-core machine at load 13, measured) before it refuses
IMPORT_SECONDS = 60.0


@dataclasses.dataclass
class Case:
    cause: int  # the root cause of issue 57 it exercises
    name: str
    run: Callable[[], object]  # raises, returns an exit status, or returns a result to check
    expect: str  # "typed": a typed error or exit 2; "ok": a result that `check` accepts
    user_files: list[pathlib.Path] = dataclasses.field(default_factory=list)
    check: Callable[[object], bool] | None = None
    limit: float = CASE_SECONDS  # seconds
    can_hang: bool = False  # a read that could block forever: cut by SIGALRM at ``limit``


class _Hang(Exception):
    pass


def _digests(paths: list[pathlib.Path]) -> dict[str, str]:
    out = {}
    for root in paths:
        files = [root] if not root.is_dir() else sorted(p for p in root.rglob("*"))
        for p in files:
            if p.is_symlink():
                out[str(p)] = "link:" + os.readlink(p)
            elif p.is_file():
                out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest()
            elif p.is_dir():
                out[str(p)] = "dir"
            elif p.exists():
                out[str(p)] = "special"
    return out


def _cli(*argv: str) -> int:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            rc = main([str(a) for a in argv])
        except SystemExit as exit_:  # argparse: usage + one error line, status 2
            rc = exit_.code
    text = err.getvalue()
    if "Traceback" in text:
        raise AssertionError(f"traceback from {argv}: {text[-400:]}")
    return rc


def _fldm_train_labels(labels, out) -> int:
    """``jmeshtex fldm train`` on icosphere:1 with the labels file ``labels``."""
    return _cli(
        "fldm", "train", "--mesh", "icosphere:1", "--labels", labels, "--out", out, "--quiet"
    )


def _outcome(case: Case) -> tuple[str, float]:
    """``("good" | "bad: why", seconds)`` for one case."""
    before = _digests(case.user_files)

    def alarm(*_):
        raise _Hang

    if case.can_hang:  # only here: an alarm elsewhere could land in a library's callback
        old = signal.signal(signal.SIGALRM, alarm)
        signal.setitimer(signal.ITIMER_REAL, case.limit)
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                result = case.run()
                exit_2 = isinstance(result, int) and not isinstance(result, bool) and result == 2
                kind = "exit 2" if exit_2 else "result"
            except JmeshtexError as err:
                kind, result = "typed", err
            except _Hang:
                kind, result = "hang", None
            except Exception as err:  # the failures this campaign looks for
                kind, result = f"untyped {type(err).__name__}: {str(err)[:200]}", err
    finally:
        if case.can_hang:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, old)
    seconds = time.perf_counter() - start
    after = _digests(case.user_files)
    if before != after:
        changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
        return f"bad: user files changed {changed[:3]}", seconds
    if case.expect == "typed" and kind not in ("typed", "exit 2"):
        return f"bad: expected a typed error, got {kind} {result!r}"[:300], seconds
    if case.expect == "ok":
        if kind != "result" or (case.check is not None and not case.check(result)):
            return f"bad: expected a correct result, got {kind} {result!r}"[:300], seconds
    if case.expect == "typed" and case.check is not None and not case.check(result):
        return f"bad: the error does not name the cause: {result}"[:300], seconds
    return "good", seconds


# ----------------------------------------------------------------------------------------------
# input builders
# ----------------------------------------------------------------------------------------------

_QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"


def _png(path: pathlib.Path, rng: np.random.Generator, size: int = 4) -> pathlib.Path:
    from jmeshtex.io import save_png

    save_png(rng.random((size, size, 3)), path)
    return path


def _textured_obj(folder: pathlib.Path, rng: np.random.Generator, tex_name: str) -> pathlib.Path:
    """An OBJ with UVs, its MTL and the texture it names (all the user's)."""
    folder.mkdir(parents=True, exist_ok=True)
    _png(folder / tex_name, rng)
    (folder / "m.mtl").write_text(f"newmtl mat\nmap_Kd {tex_name}\n")
    obj = folder / "m.obj"
    obj.write_text(
        "mtllib m.mtl\n" + _QUAD + "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl mat\n"
        "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
    )
    return obj


def _huge_png(path: pathlib.Path, side: int) -> pathlib.Path:
    """A valid PNG header claiming ``side`` x ``side`` RGB pixels, followed by almost no data."""

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))

    ihdr = struct.pack(">IIBBBBB", side, side, 8, 2, 0, 0, 0)
    body = zlib.compress(b"\0" * 64)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", body) + chunk(b"IEND", b"")
    )
    return path


def _names(rng: np.random.Generator, n: int) -> list[str]:
    pool = ["1", "2", "3", "7", "100", "999", "\u00b2", "01", "x", "notes", "5.tmp"]
    return list(rng.choice(pool, size=n, replace=False))


# ----------------------------------------------------------------------------------------------
# the generators, one per root cause
# ----------------------------------------------------------------------------------------------


def _cause1(tmp: pathlib.Path, rng: np.random.Generator) -> list[Case]:
    """User data in an output folder: checkpoint retention, --overwrite, `dgts train DIR`."""
    from jmeshtex.cli._output import claim_output, release_all
    from jmeshtex.io import Checkpoints, atomic_write, unprotect_all

    cases = []
    ck = tmp / "c1" / "checkpoints"
    for name in {*_names(rng, 3), "100"}:  # "100": the reproducer
        (ck / name).mkdir(parents=True)
        (ck / name / "holiday.jpg").write_bytes(rng.bytes(16))
    keep = int(rng.integers(1, 4))
    steps = sorted(rng.choice(np.arange(10, 60), size=4, replace=False).tolist())  # not foreign

    def saves():
        c = Checkpoints(ck, keep=keep, fingerprint={"run": 1})
        for s in steps:
            c.save(s, {"w": np.full(3, float(s))}, meta={"s": s})
        return c.latest_step()

    def kept(latest):
        ours = [p for p in ck.iterdir() if p.name in {str(s) for s in steps}]
        return latest == steps[-1] and len(ours) == keep

    cases.append(Case(1, "retention keeps foreign folders", saves, "ok", [*ck.iterdir()], kept))
    digits = [p for p in sorted(ck.iterdir()) if p.name.isascii() and p.name.isdigit()]
    foreign = digits[int(rng.integers(len(digits)))]  # "01" is step 1's name spelt otherwise
    cases.append(
        Case(
            1,
            "saving over a foreign step folder",
            lambda: Checkpoints(ck, fingerprint={"run": 1}).save(int(foreign.name), {"w": 0.0}),
            "typed" if foreign.name == str(int(foreign.name)) else "ok",
            [foreign],
        )
    )

    out = tmp / "c1" / "out"
    out.mkdir()
    name = str(rng.choice(["sample.obj", "summary.json", "model.npz", "target.png"]))
    (out / name).write_bytes(rng.bytes(32))

    def overwrite():
        try:
            claim_output(out, command="campaign", overwrite=True)
            atomic_write(out / name, b"replaced")
        finally:
            release_all()
            unprotect_all()

    cases.append(Case(1, "--overwrite replacing a foreign file", overwrite, "typed", [out / name]))
    repro = tmp / "c1" / "repro"  # the reproducer: refused before any work
    for n in ("1", "100"):
        (repro / "checkpoints" / n).mkdir(parents=True)
    (repro / "checkpoints" / "100" / "holiday.jpg").write_bytes(rng.bytes(8))
    cases.append(
        Case(
            1,
            "fldm train --overwrite over foreign checkpoints/",
            lambda: _cli(
                *("fldm", "train", "--mesh", "striped-sphere:1", "--preset", "tiny"),
                *("--codec", "stripes", "--copies", "2", "--vertices", "100", "--steps", "300"),
                *("--overwrite", "--out", repro, "--quiet"),
            ),
            "typed",
            [repro / "checkpoints"],
            limit=IMPORT_SECONDS,
        )
    )
    dgts = tmp / "c1" / "dgts"
    dgts.mkdir()
    (dgts / "sample.obj").write_text(_QUAD + "f 1 2 3\n")
    cases.append(
        Case(
            1,
            "dgts train DIR with foreign files",
            lambda: _cli("dgts", "train", dgts),
            "typed",
            [dgts / "sample.obj"],
        )
    )
    return cases


def _cause2(tmp: pathlib.Path, rng: np.random.Generator) -> list[Case]:
    """Files an OBJ references are inputs: no output may replace its MTL or texture."""
    tex = str(rng.choice(["tex.png", "albedo.png", "t.png"]))
    obj = _textured_obj(tmp / "c2", rng, tex)
    user = [obj, obj.parent / "m.mtl", obj.parent / tex]
    return [
        Case(
            2,
            "info --render onto the texture",
            lambda: _cli("info", obj, "--render", obj.parent / tex),
            "typed",
            user,
        ),
        Case(
            2,
            "info --render onto the MTL",
            lambda: _cli("info", obj, "--render", obj.parent / "m.mtl"),
            "typed",
            user,
        ),
    ]


def _cause4(tmp: pathlib.Path, rng: np.random.Generator) -> list[Case]:
    """Writes through links: a link at an output path is replaced, never written through."""
    from jmeshtex.io import atomic_write

    folder = tmp / "c4"
    folder.mkdir()
    victim = folder / "victim.txt"
    victim.write_bytes(rng.bytes(8))
    link = folder / str(rng.choice(["report.txt", ".report.txt.tmp", "out.png"]))
    link.symlink_to(victim)

    def write():
        atomic_write(link, b"new")
        return link.read_bytes()

    return [
        Case(4, "atomic write at a planted link", write, "ok", [victim], lambda r: r == b"new"),
        Case(
            4,
            "demo --out is a file",
            lambda: _cli("demo", "--out", victim, "--quick"),
            "typed",
            [victim],
        ),
    ]


def _cause5(tmp: pathlib.Path, rng: np.random.Generator) -> list[Case]:
    """Reads that never end: FIFOs and devices anywhere a file is read; size and memory caps."""
    from jmeshtex import io as jio

    folder = tmp / "c5"
    folder.mkdir()
    fifo = folder / str(rng.choice(["m.obj", "mesh.obj"]))
    os.mkfifo(fifo)
    zero = folder / "z.obj"
    zero.symlink_to("/dev/zero")
    tex_fifo = folder / "t.png"
    os.mkfifo(tex_fifo)
    labels_fifo = folder / "l.npy"
    os.mkfifo(labels_fifo)
    sub = folder / "obj"
    sub.mkdir()
    which = str(rng.choice(["mtl", "map"]))
    (sub / "m.obj").write_text(
        "mtllib m.mtl\n" + _QUAD + "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl a\nf 1/1 2/2 3/3\n"
    )
    if which == "mtl":
        os.mkfifo(sub / "m.mtl")
    else:
        (sub / "m.mtl").write_text("newmtl a\nmap_Kd t.png\n")
        os.mkfifo(sub / "t.png")
    big = _huge_png(folder / "big.png", int(rng.integers(60_000, 200_000)))
    small = folder / "s.obj"
    small.write_text(_QUAD + "f 1 2 3\n" * 3)
    out = folder / "out"

    def capped():
        old = jio._read.MAX_INPUT_BYTES
        jio._read.MAX_INPUT_BYTES = 10
        try:
            return jio.load_mesh(small)
        finally:
            jio._read.MAX_INPUT_BYTES = old

    return [
        Case(5, "FIFO mesh", lambda: _cli("info", fifo), "typed"),
        Case(5, "mesh link to /dev/zero", lambda: jio.load_mesh(zero), "typed"),
        Case(
            5,
            f"FIFO {which} named by an OBJ",
            lambda: jio.load_mesh(sub / "m.obj"),
            "ok",
            [sub / "m.obj"],
            lambda m: m.num_faces == 1 and m.texture is None,
        ),
        Case(5, "FIFO --texture", lambda: jio.load_texture(tex_fifo), "typed"),
        Case(
            5,
            "FIFO --texture on a procedural mesh",
            lambda: _cli("info", "icosphere:1", "--texture", tex_fifo),
            "typed",
        ),
        Case(
            5,
            "FIFO --labels",
            lambda: _fldm_train_labels(labels_fifo, out),
            "typed",
        ),
        Case(
            5,
            "texture beyond the memory budget",
            lambda: jio.load_texture(big),
            "typed",
            [big],
            lambda e: "budget" in str(e),
        ),
        Case(5, "file over the size cap", capped, "typed", [small]),
    ]


def _cause6(tmp: pathlib.Path, rng: np.random.Generator) -> list[Case]:
    """A damaged newest checkpoint falls back to the newest intact step."""
    from jmeshtex.io import Checkpoints

    folder = tmp / "c6"
    c = Checkpoints(folder, keep=3, fingerprint={"run": 1})
    for s in (1, 2, 3):
        c.save(s, {"w": np.full(4, float(s))}, meta={"s": s})
    files = sorted(p for p in (folder / "3").rglob("*") if p.is_file())
    victim = files[int(rng.integers(len(files)))]
    how = str(rng.choice(["truncate", "flip", "delete", "garbage"]))
    raw = victim.read_bytes()
    if how == "truncate":
        victim.write_bytes(raw[: len(raw) // 2])
    elif how == "delete":
        victim.unlink()
    elif how == "garbage":
        victim.write_bytes(rng.bytes(max(1, len(raw))))
    else:
        flipped = bytearray(raw or b"\0")
        flipped[int(rng.integers(len(flipped)))] ^= 0xFF
        victim.write_bytes(bytes(flipped))
    (folder / "\u00b2").mkdir()

    def resume():
        state, meta = Checkpoints(folder, fingerprint={"run": 1}).restore({"w": np.zeros(4)})
        return state["w"].tolist(), meta

    return [
        Case(
            6,
            f"{how} {victim.relative_to(folder)}",
            resume,
            "ok",
            [folder / "\u00b2"],
            lambda r: r == ([2.0] * 4, {"s": 2}),
        )
    ]


def _cause7(tmp: pathlib.Path, rng: np.random.Generator) -> list[Case]:
    """Sizes that would exhaust memory are refused before anything is built."""
    out = tmp / "c7" / "out"
    labels = tmp / "c7" / "labels.npy"
    labels.parent.mkdir()
    big = np.zeros(42, np.int64)
    big[int(rng.integers(42))] = int(rng.choice([10**9, 10**6, 5000]))
    np.save(labels, big)
    n = str(rng.choice(["1000000", "100000", "99999"]))
    return [
        Case(
            7,
            "surfacecnn --size",
            lambda: _cli(
                "surfacecnn",
                "synthesize",
                "--mesh",
                "torus",
                "--exemplar",
                "x.png",
                "--size",
                n,
                "--out",
                out,
            ),
            "typed",
        ),
        Case(
            7,
            "fl reconstruct --size",
            lambda: _cli("fl", "reconstruct", "--mesh", "torus", "--size", n, "--out", out),
            "typed",
        ),
        Case(
            7,
            "fl reconstruct --vertices",
            lambda: _cli(
                "fl", "reconstruct", "--mesh", "torus", "--vertices", "100000000", "--out", out
            ),
            "typed",
        ),
        Case(
            7,
            "fldm train --vertices",
            lambda: _cli(
                "fldm", "train", "--mesh", "icosphere:1", "--vertices", "1000000000", "--out", out
            ),
            "typed",
        ),
        Case(
            7,
            "dgts prepare --samples",
            lambda: _cli(
                "dgts",
                "prepare",
                "--reference",
                "icosphere:1",
                "--samples",
                "1000000000",
                "--out",
                out,
            ),
            "typed",
        ),
        Case(
            7,
            "labels with a huge maximum",
            lambda: _fldm_train_labels(labels, out),
            "typed",
            [labels],
        ),
    ]


def _cause8(tmp: pathlib.Path, rng: np.random.Generator) -> list[Case]:
    """What used to end in a traceback: bad records, bad labels, a bad cache folder, links."""
    folder = tmp / "c8"
    folder.mkdir()
    cases = []
    bad = str(rng.choice(["{not json", "[1, 2]", '{"remeshes": "two"}', '"text"', "\xff"]))
    d = folder / "dgts"
    d.mkdir()
    (d / "prepare.json").write_text(bad, encoding="latin-1")
    cases.append(
        Case(
            8,
            "dgts train: bad prepare.json",
            lambda: _cli("dgts", "train", d, "--overwrite"),
            "typed",
            [d / "prepare.json"],
        )
    )
    for kind in ("empty", "nan", "negative", "2d"):
        arr = {
            "empty": np.zeros(0, np.int64),
            "nan": np.array([0.0, np.nan, 1.0]),
            "negative": np.array([0, -int(rng.integers(1, 9)), 1]),
            "2d": np.zeros((3, 2), np.int64),
        }[kind]
        path = folder / f"labels_{kind}.npy"
        np.save(path, arr)
        cases.append(
            Case(
                8,
                f"fldm train --labels {kind}",
                lambda p=path: _cli(
                    "fldm",
                    "train",
                    "--mesh",
                    "icosphere:1",
                    "--labels",
                    p,
                    "--out",
                    folder / "o",
                    "--quiet",
                ),
                "typed",
                [path],
                lambda e: e == 2,
            )
        )
    cache_file = folder / "cache"
    cache_file.write_text("x")

    def bad_cache():
        old = os.environ.get("JMESHTEX_JAX_CACHE")
        os.environ["JMESHTEX_JAX_CACHE"] = str(cache_file)
        try:
            return _cli("fl", "encode", "--mesh", "icosahedron", "--out", folder / "z.npz")
        finally:
            if old is None:
                os.environ.pop("JMESHTEX_JAX_CACHE")
            else:
                os.environ["JMESHTEX_JAX_CACHE"] = old

    cases.append(Case(8, "JMESHTEX_JAX_CACHE is a file", bad_cache, "typed", [cache_file]))
    s = folder / "scnn"
    (folder / "elsewhere").mkdir()
    (folder / "elsewhere" / "keep.txt").write_text("mine")
    s.mkdir()
    (s / "checkpoints").symlink_to(folder / "elsewhere")
    from jmeshtex.io import Checkpoints

    cases.append(
        Case(
            8,
            "a symlinked checkpoints folder",
            lambda: Checkpoints(s / "checkpoints"),
            "typed",
            [folder / "elsewhere"],
        )
    )
    return cases


def _cause9(tmp: pathlib.Path, rng: np.random.Generator) -> list[Case]:
    """Damaged files are refused or their repairs counted, never accepted silently."""
    from PIL import Image

    from jmeshtex import MeshRepairWarning
    from jmeshtex.data import icosphere
    from jmeshtex.io import load_mesh, load_texture

    folder = tmp / "c9"
    folder.mkdir()
    v, f = icosphere(1)
    lie = int(rng.integers(1, 6))
    off = folder / "lying.off"
    body = [" ".join(map(str, x)) for x in v] + ["3 " + " ".join(map(str, x)) for x in f]
    if rng.random() < 0.5:
        off.write_text(f"OFF\n{len(v)} {len(f) + lie} 0\n" + "\n".join(body) + "\n")
    else:
        off.write_text(f"OFF\n{len(v)} {len(f)} 0\n" + "\n".join(body[:-lie]) + "\n")
    vt = folder / "vt.obj"
    vt.write_text(_QUAD + "vt 0 0\nvt 1 0\nvt 1 1\nf 1/1 2/2 3/9\n")
    nan = folder / "nan.obj"
    nan.write_text("v 0 0 0 nan 0 0\nv 1 0 0 1 0 0\nv 0 1 0 0 1 0\nf 1 2 3\n")
    tiff = folder / "f.tiff"
    data = rng.random((4, 4)).astype(np.float32)
    data[int(rng.integers(4)), int(rng.integers(4))] = rng.choice([np.nan, np.inf, 1e6])
    Image.fromarray(data, mode="F").save(tiff)
    short = folder / "short.obj"
    short.write_text(_QUAD + "f 1 2 3\nf 1 2\nf 3\n")

    def counted():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            mesh = load_mesh(short)
        said = any(
            issubclass(w.category, MeshRepairWarning) and "fewer than 3" in str(w.message)
            for w in caught
        )
        return mesh.num_faces == 1 and said

    return [
        Case(9, "OFF with lying counts", lambda: load_mesh(off), "typed", [off]),
        Case(9, "vt index out of range", lambda: load_mesh(vt), "typed", [vt]),
        Case(9, "NaN vertex colours", lambda: load_mesh(nan), "typed", [nan]),
        Case(9, "float TIFF with bad texels", lambda: load_texture(tiff), "typed", [tiff]),
        Case(9, "faces with < 3 corners counted", counted, "ok", [short], lambda r: r is True),
    ]


def _cause10(tmp: pathlib.Path, rng: np.random.Generator) -> list[Case]:
    """Valid inputs accepted, and the right cause named."""
    from jmeshtex import MeshScaleError
    from jmeshtex.data import icosphere
    from jmeshtex.geometry import validate_mesh
    from jmeshtex.io import load_mesh

    folder = tmp / "c10"
    folder.mkdir()
    tabs = folder / "tabs.obj"
    tabs.write_text("v\t0\t0\t0\nv\t1\t0\t0\nv\t0\t1\t0\nf\t1\t2\t3\n")
    zero = folder / "zero.obj"
    zero.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 0 1 2\nf 1 3 2\n")
    v, f = icosphere(1)
    scale = float(rng.choice([1e200, 1e-200, 1e150, 1e-150]))
    from jmeshtex.io import load_model, save_model

    weights = rng.standard_normal(6)
    weights[int(rng.integers(6))] = rng.choice([np.nan, np.inf, -np.inf])
    model = save_model(folder / "m.npz", kind="k", config={}, params={"w": weights})
    return [
        Case(
            10,
            "tab-separated OBJ",
            lambda: load_mesh(tabs),
            "ok",
            [tabs],
            lambda m: m.num_faces == 1,
        ),
        Case(
            10, "NaN weights in a model file", lambda: load_model(model, kind="k"), "typed", [model]
        ),
        Case(
            10,
            "0-based OBJ",
            lambda: load_mesh(zero),
            "typed",
            [zero],
            lambda e: "start at 1" in str(e),
        ),
        Case(
            10,
            f"scale {scale:g}",
            lambda: validate_mesh(v * scale, f),
            "typed",
            [],
            lambda e: isinstance(e, MeshScaleError),
        ),
        Case(
            10, "icosahedron:N", lambda: _cli("info", f"icosahedron:{rng.integers(1, 9)}"), "typed"
        ),
        Case(
            10,
            "--steps -1",
            lambda: _cli(
                "fldm", "train", "--mesh", "icosphere:1", "--steps", "-1", "--out", folder / "o"
            ),
            "typed",
        ),
    ]


def _cause12(tmp: pathlib.Path, rng: np.random.Generator) -> list[Case]:
    """Public entries validate what they are given."""
    import jax
    import jax.numpy as jnp

    from jmeshtex import Mesh, fl, geometry, meshmatch, ops
    from jmeshtex.data import icosphere
    from jmeshtex.io import Checkpoints

    v, f = icosphere(1)
    bad_faces = {
        "empty-2col": np.zeros((0, 2), np.int64),
        "2 columns": f[:, :2],
        "ragged": [[0, 1, 2], [0, 1]],
        "out of range": f + len(v),
        "-1": np.where(f == f.max(), -1, f),
        "4 columns": np.concatenate([f, f[:, :1]], axis=1),
    }
    name = str(rng.choice(list(bad_faces)))
    faces = bad_faces[name]
    expect = "ok" if name == "empty-2col" else "typed"  # no faces: an empty, correct answer
    scale = float(rng.choice([1e200, 1e-200]))
    return [
        Case(12, f"edge_lengths faces {name}", lambda: geometry.edge_lengths(v, faces), expect),
        Case(
            12,
            f"vertex_normals faces {name}",
            lambda: geometry.vertex_normals(v, faces),
            expect,
            [],
            None if name != "empty-2col" else lambda n: n.shape == v.shape and not n.any(),
        ),
        Case(
            12,
            f"mean_edge_length at {scale:g}",
            lambda: geometry.mean_edge_length(v * scale, f),
            "ok",
            [],
            lambda x: np.isfinite(x) and 0.3 < x / scale < 1.0,
        ),
        Case(
            12,
            f"HKS at {scale:g}",
            lambda: geometry.laplacian_eigenpairs(v * scale, f, k=3),
            "typed",
        ),
        Case(12, "safe_norm('abc')", lambda: ops.safe_norm("abc"), "typed"),
        Case(
            12,
            "masked_mean bad mask",
            lambda: ops.masked_mean(jnp.ones((4, 2)), jnp.ones(3)),
            "typed",
        ),
        Case(
            12,
            "elementwise_max shapes",
            lambda: ops.elementwise_max((jnp.ones(2), jnp.ones(3))),
            "typed",
        ),
        Case(12, "Checkpoints(keep=0)", lambda: Checkpoints(tmp / "k", keep=0), "typed"),
        Case(
            12,
            "fl.encode(key=None)",
            lambda: fl.encode(fl.load_pretrained(), (v, f), key=None),
            "typed",
        ),
        Case(
            12,
            "meshmatch.transfer(config=dict)",
            lambda: meshmatch.transfer(
                Mesh(v, f, vertex_colors=np.ones_like(v)), (v, f), key=jax.random.key(0), config={}
            ),
            "typed",
        ),
    ]


GENERATORS = (
    _cause1,
    _cause2,
    _cause4,
    _cause5,
    _cause6,
    _cause7,
    _cause8,
    _cause9,
    _cause10,
    _cause12,
)


def run_campaign(tmp: pathlib.Path, rng: np.random.Generator) -> tuple[collections.Counter, list]:
    """Every generator's cases under ``tmp``: (Counter of (cause, outcome)), [(case, why)] bad)."""
    counts: collections.Counter = collections.Counter()
    bad = []
    cwd = os.getcwd()
    os.chdir(tmp)  # outputs of refused commands (none expected) land here, not in the repository
    try:
        for gen in GENERATORS:
            for case in gen(tmp, rng):
                if "_cli" in case.run.__code__.co_names:  # a command: may import a method first
                    case.limit = max(case.limit, IMPORT_SECONDS)
                if gen is _cause5:  # reads of FIFOs and devices: a regression would block
                    case.can_hang = True
                outcome, seconds = _outcome(case)
                if outcome == "good" and seconds > case.limit:
                    outcome = f"bad: slow ({seconds:.1f} s)"
                counts[(case.cause, "good" if outcome == "good" else "bad")] += 1
                if outcome != "good":
                    bad.append((f"cause {case.cause}: {case.name}", outcome))
    finally:
        os.chdir(cwd)
    return counts, bad


@pytest.mark.unchecked  # what a user meets: jaxtyping's run-time checks are a test-only layer
def test_the_second_campaign_finds_no_bad_outcome(tmp_path, rng):
    start = time.perf_counter()
    counts, bad = run_campaign(tmp_path, rng)
    total = sum(counts.values())
    print(f"\nfault campaign 2: {total} cases in {time.perf_counter() - start:.1f} s")
    for cause in sorted({c for c, _ in counts}):
        print(f"  cause {cause:2d}: {counts[(cause, 'good')]} good, {counts[(cause, 'bad')]} bad")
    assert total >= 40
    assert not bad, "\n".join(f"{name}: {why}" for name, why in bad)


@pytest.mark.parametrize("expect", ["typed", "ok"])
def test_the_campaign_can_fail(tmp_path, expect):
    """The harness itself: a changed user file, an untyped error and a wrong result are caught."""
    victim = tmp_path / "v.txt"
    victim.write_text("a")

    def clobber():
        victim.write_text("b")

    assert _outcome(Case(0, "clobber", clobber, expect, [victim]))[0].startswith("bad")
    assert _outcome(Case(0, "raw", lambda: [][1], expect))[0].startswith("bad")
    wrong = Case(0, "wrong", lambda: 1, "ok", [], lambda r: r == 2)
    assert _outcome(wrong)[0].startswith("bad")

"""The surface-CNN quality protocol's report keeps every finished cell: one in the work folder, or,
where that folder is gone, the committed row."""

from __future__ import annotations

import json
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))  # the benchmark imports its harness as a sibling

import surfacecnn  # noqa: E402


def _row(mesh, exemplar, origin, size=512, steps=500):
    return {"mesh": mesh, "exemplar": exemplar, "size": size, "steps": steps, "origin": origin}


def test_finished_rows_take_the_work_folder_over_the_record_in_protocol_order(tmp_path):
    record = tmp_path / "surfacecnn.quality.json"
    committed = [
        _row("fandisk", "brick", "record"),
        _row("spot", "brick", "record"),
        _row("spot", "grass", "record"),
        _row("cow", "brick", "record", steps=150),  # another protocol setting: not this report's
    ]
    record.write_text(json.dumps(committed))
    work = tmp_path / "work"
    for mesh, exemplar in (("spot", "grass"), ("cow", "grass")):
        cell = work / f"{mesh}_{exemplar}_512_500"
        cell.mkdir(parents=True)
        (cell / "row.json").write_text(json.dumps(_row(mesh, exemplar, "work")))
    (work / "cow_brick_512_500").mkdir()  # started, not finished

    rows = surfacecnn.finished_rows(work, record, 512, 500)
    assert [(r["mesh"], r["exemplar"], r["origin"]) for r in rows] == [
        ("spot", "brick", "record"),
        ("spot", "grass", "work"),
        ("cow", "grass", "work"),
        ("fandisk", "brick", "record"),
    ]
    assert surfacecnn.finished_rows(work, tmp_path / "absent.json", 512, 150) == []

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


def test_finished_rows_come_from_the_work_folder_alone_in_protocol_order(tmp_path):
    """No row is carried over from an earlier results file: only the cells this work folder
    finished, at this protocol setting, in protocol order."""
    work = tmp_path / "work"
    for mesh, exemplar in (("cow", "grass"), ("spot", "grass")):
        cell = work / f"{mesh}_{exemplar}_512_500"
        cell.mkdir(parents=True)
        (cell / "row.json").write_text(json.dumps(_row(mesh, exemplar, "work")))
    (work / "cow_brick_512_500").mkdir()  # started, not finished
    (work / "fandisk_brick_512_150").mkdir()
    (work / "fandisk_brick_512_150" / "row.json").write_text(
        json.dumps(_row("fandisk", "brick", "work", steps=150))  # another protocol setting
    )

    rows = surfacecnn.finished_rows(work, 512, 500)
    assert [(r["mesh"], r["exemplar"], r["origin"]) for r in rows] == [
        ("spot", "grass", "work"),
        ("cow", "grass", "work"),
    ]
    assert surfacecnn.finished_rows(tmp_path / "empty", 512, 500) == []


def test_speck_texels_tell_seam_specks_from_colour_noise_inside_charts(tmp_path):
    """A coloured dot on a chart's border counts as a border speck, one in the middle as an inside
    speck; a committed row that already has the split, or a cell without textures, is left alone."""
    import numpy as np

    from jmeshtex.data import grid

    n = 32
    v, f = grid(4)
    np.savez(tmp_path / "cow_xatlas.npz", vertices=v, faces=f, uv=0.5 * v[f][..., :2] + 0.25)
    cell = tmp_path / f"cow_grass_{n}_5"
    cell.mkdir()
    grey = np.full((n, n, 3), 0.5, np.float32)
    inside, border = grey.copy(), grey.copy()
    inside[16, 16] = (1.0, 0.2, 0.2)  # the chart covers texels 8..23: the centre is 8 from its edge
    border[8, 16] = (1.0, 0.2, 0.2)  # on its edge
    np.save(cell / "surface_texture.npy", inside)
    np.save(cell / "uv2d_texture.npy", border)
    rows = [
        {"mesh": "cow", "exemplar": "grass", "size": n, "steps": 5, "surface": {}, "uv2d": {}},
        {"mesh": "cow", "exemplar": "brick", "size": n, "steps": 5, "surface": {}, "uv2d": {}},
    ]
    surfacecnn.speck_texels(rows, tmp_path)
    s, u = rows[0]["surface"]["speck_texels"], rows[0]["uv2d"]["speck_texels"]
    assert s["border"] == 0 and s["inside"] > 0
    assert u["border"] > 0 and u["inside"] == 0
    assert "speck_texels" not in rows[1]["surface"]  # no textures kept
    rows[0]["surface"]["speck_texels"] = {"border": -1.0, "inside": -1.0}
    surfacecnn.speck_texels(rows, tmp_path)
    assert rows[0]["surface"]["speck_texels"]["border"] == -1.0


def test_the_quality_table_shows_orientation_beside_control_and_tiled_or_a_dash():
    row = {
        "orientation_control": {"seam": 0.9, "interior": 0.99},
        "uv_tiled": {"orientation_seam": 0.6, "orientation_interior": 0.98},
    }
    cell = surfacecnn._orientation_cell(
        row, {"orientation_seam": 0.88, "orientation_interior": 0.97}
    )
    assert cell == "0.880 / 0.970 (0.900 / 0.990; 0.600 / 0.980)"
    assert surfacecnn._orientation_cell({}, {"seam_ratio": 1.0}) == "—"  # scored before the measure


def test_the_quality_table_names_each_cells_frames():
    smoothed = {"frames": {"frames": "global", "frame_smoothing": 4.0}}
    paper = {"frames": {"frames": "global", "frame_smoothing": 0.0}}
    assert surfacecnn._frames_words(smoothed) == "global, smoothed over 4 texels"
    assert surfacecnn._frames_words(paper) == "global, smoothed over 0 texels"
    assert "not recorded" in surfacecnn._frames_words({})  # a cell finished before the record


def test_the_orientation_control_runs_straight_across_seams():
    """The control the benchmark bakes (stripes along the frames' vector) is seamless on a layout
    with a seam: its seam alignment is the interior's."""
    import numpy as np

    from jmeshtex import Mesh
    from jmeshtex.data import grid
    from jmeshtex.metrics import seam_orientation
    from jmeshtex.surfacecnn import Config, prepare_surface

    v, f = grid(12)
    xy = v[f][..., :2]
    left = (xy[..., 0].mean(axis=1) < 0.5)[:, None, None]
    uv = np.where(
        left,
        0.02 + 0.45 * xy,
        np.stack([0.5 + 0.45 * xy[..., 1], 0.5 + 0.45 * (1 - xy[..., 0])], -1),
    )
    mesh = Mesh(v, f, uv=uv)
    surface = prepare_surface(mesh, size=96, levels=0)
    control = surfacecnn.orientation_control(mesh, surface, Config(size=96))
    r = seam_orientation(mesh.replace(uv=surface.atlas.uv), control)
    assert r.seam_edges == 12 and r.seam > 0.98 and r.interior > 0.98

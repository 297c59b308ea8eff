"""load_mesh / load_texture: seam merging, stored indexing, image conventions, clean errors."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from PIL import Image

from jmeshtex import (
    Mesh,
    MeshIOError,
    MeshRepairWarning,
    NonManifoldVertexError,
    NonTriangleFaceError,
)
from jmeshtex.data import icosphere
from jmeshtex.geometry import mesh_statistics, validate_mesh
from jmeshtex.io import load_mesh, load_texture, save_mesh

SEAM_OBJ = """\
# a unit square whose diagonal is a UV seam: 4 positions, 6 texture coordinates
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0.0 0.0
vt 0.5 0.0
vt 0.5 0.5
vt 0.6 0.6
vt 1.0 1.0
vt 0.6 1.0
f 1/1 2/2 3/3
f 1/4 3/5 4/6
"""


def test_seam_split_obj_is_merged_and_keeps_its_stored_indexing(tmp_path):
    path = tmp_path / "seam.obj"
    path.write_text(SEAM_OBJ)
    m = load_mesh(path)
    assert m.name == "seam" and m.num_vertices == 4 and m.num_faces == 2
    assert m.vertices.tolist() == [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    assert m.faces.tolist() == [[0, 1, 2], [0, 2, 3]]
    np.testing.assert_array_equal(
        m.uv, [[[0, 0], [0.5, 0], [0.5, 0.5]], [[0.6, 0.6], [1, 1], [0.6, 1]]]
    )
    assert len(m.split_to_merged) == 6  # vertices 0 and 2 were stored twice
    np.testing.assert_array_equal(m.split_to_merged[m.split_faces], m.faces)
    validate_mesh(m.vertices, m.faces)
    raw = load_mesh(path, merge_seams=False)
    assert raw.num_vertices == 6 and raw.split_faces is None
    np.testing.assert_array_equal(raw.uv, m.uv)
    np.testing.assert_array_equal(raw.vertices[raw.faces], m.vertices[m.faces])


def test_polygons_are_triangulated_and_dtypes_fixed(tmp_path):
    path = tmp_path / "quad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    with pytest.warns(
        MeshRepairWarning, match=r"split 1 polygon face \(4 corners\) into 2 triangles"
    ):
        m = load_mesh(path)
    assert m.faces.dtype == np.int64 and m.vertices.dtype == np.float64
    assert m.num_faces == 2 and m.uv is None and m.texture is None and m.vertex_colors is None
    validate_mesh(m.vertices, m.faces)


# a quad, a triangle and a pentagon: 2 + 1 + 3 = 6 triangles
_POLY_V = [
    [0, 0, 0],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 0],
    [2, 0, 0],
    [3, 1, 0],
    [2.5, 2, 0],
    [1.5, 2, 0],
]
_POLY_F = [[0, 1, 2, 3], [1, 4, 2], [4, 5, 6, 7, 2]]
# trimesh's OFF reader fails on faces of more than 4 corners (numpy 2): there, the pentagon is split
_OFF_F = [[0, 1, 2, 3], [1, 4, 2], [4, 5, 6, 2], [6, 7, 2]]


def _polygon_file(tmp_path, suffix: str):
    path = tmp_path / f"poly{suffix}"
    rows = "".join(f"{x} {y} {z}\n" for x, y, z in _POLY_V)
    if suffix == ".obj":
        path.write_text(
            "".join(f"v {r}" for r in rows.splitlines(True))
            + "".join("f " + " ".join(str(i + 1) for i in f) + "\n" for f in _POLY_F)
        )
    elif suffix == ".off":
        path.write_text(
            f"OFF\n{len(_POLY_V)} {len(_OFF_F)} 0\n{rows}"
            + "".join(f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in _OFF_F)
        )
    else:
        path.write_text(
            f"ply\nformat ascii 1.0\nelement vertex {len(_POLY_V)}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {len(_POLY_F)}\nproperty list uchar int vertex_indices\n"
            f"end_header\n{rows}"
            + "".join(f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in _POLY_F)
        )
    return path


@pytest.mark.parametrize(
    ("suffix", "message", "records", "polygons"),
    [
        (".obj", r"split 2 polygon faces \(4 or 5 corners\) into 5 triangles", 3, [0, 2]),
        (".ply", r"split 2 polygon faces \(4 or 5 corners\) into 5 triangles", 3, [0, 2]),
        (".off", r"split 2 polygon faces \(4 corners\) into 4 triangles", 4, [0, 2]),
    ],
)
def test_polygon_faces_warn_with_counts_or_raise_when_strict(
    tmp_path, suffix, message, records, polygons
):
    path = _polygon_file(tmp_path, suffix)
    with pytest.warns(MeshRepairWarning, match=message):
        m = load_mesh(path)
    assert m.num_faces == 6
    validate_mesh(m.vertices, m.faces)
    with pytest.raises(
        NonTriangleFaceError, match=rf"2 polygon faces .* among its {records} faces"
    ) as info:
        load_mesh(path, strict=True)
    assert info.value.indices.tolist() == polygons  # positions among the file's faces


def test_binary_ply_quads_warn(tmp_path):
    path = tmp_path / "quad.ply"
    header = (
        "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = np.array(_POLY_V[:4], "<f4").tobytes() + bytes([4]) + np.arange(4, dtype="<i4").tobytes()
    path.write_bytes(header.encode() + body)
    with pytest.warns(
        MeshRepairWarning, match=r"split 1 polygon face \(4 corners\) into 2 triangles"
    ):
        assert load_mesh(path).num_faces == 2


def test_triangle_files_load_without_a_warning(tmp_path):
    path = tmp_path / "ico.obj"
    save_mesh(Mesh(*icosphere(1)), path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_mesh(path, strict=True).num_faces == 80


def test_vertex_colors_rgb_or_rgba(tmp_path):
    v, f = icosphere(1)
    opaque = np.tile([10, 20, 30, 255], (len(v), 1)).astype(np.uint8)
    translucent = opaque.copy()
    translucent[5, 3] = 128
    for name, rgba in [("opaque", opaque), ("translucent", translucent)]:
        import trimesh

        path = tmp_path / f"{name}.ply"
        path.write_bytes(
            trimesh.Trimesh(v, f, vertex_colors=rgba, process=False).export(file_type="ply")
        )
        m = load_mesh(path)
        assert m.vertex_colors.dtype == np.float32
        assert m.vertex_colors.shape == (len(v), 3 if name == "opaque" else 4)
        np.testing.assert_array_equal(
            m.vertex_colors, rgba[:, : m.vertex_colors.shape[1]] / np.float32(255)
        )


def test_foreign_glb_scene_with_two_meshes_is_concatenated(tmp_path):
    import trimesh

    a = trimesh.creation.box()
    b = trimesh.creation.icosphere(1)
    b.apply_translation([3.0, 0, 0])
    path = tmp_path / "scene.glb"
    path.write_bytes(trimesh.Scene([a, b]).export(file_type="glb"))
    m = load_mesh(path)
    assert m.num_faces == len(a.faces) + len(b.faces)
    assert mesh_statistics(m).components == 2


@pytest.mark.parametrize(
    "name, content, match",
    [
        ("points.obj", b"v 0 0 0\nv 1 0 0\n", "no triangles"),
        ("empty.obj", b"", "no triangles"),
        ("bad_index.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "cannot read mesh"),
        ("junk.off", b"hello world\n", "cannot read mesh"),
        ("bad_index.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n", "outside the range"),
        ("junk.ply", bytes(range(256)) * 2, "Not a ply"),
        ("junk.glb", b"glTF" + bytes(100), "cannot read mesh"),
        ("mesh.stl", b"solid x\nendsolid x\n", "unsupported mesh format '.stl'"),
        ("noext", b"v 0 0 0\n", "unsupported mesh format"),
    ],
)
def test_unreadable_files_raise_mesh_io_error(tmp_path, name, content, match):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(MeshIOError, match=match):
        load_mesh(path)


def test_missing_paths(tmp_path):
    with pytest.raises(MeshIOError, match="no such file"):
        load_mesh(tmp_path / "missing.obj")
    with pytest.raises(MeshIOError, match="directory"):
        load_mesh(tmp_path)
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(MeshIOError, match="cannot read texture .*no such file"):
        load_mesh(tmp_path / "m.obj", texture=tmp_path / "missing.png")
    (tmp_path / "not_an_image.png").write_text("nope")
    with pytest.raises(MeshIOError, match="cannot read texture"):
        load_texture(tmp_path / "not_an_image.png")


def test_load_texture_modes_and_orientation(tmp_path):
    rows = np.zeros((4, 3), np.uint8)
    rows[0] = 255  # the top row is white
    cases = {
        "L": (Image.fromarray(rows), 1),
        "LA": (Image.fromarray(np.stack([rows, rows], -1)), 2),
        "RGB": (Image.fromarray(np.stack([rows] * 3, -1)), 3),
        "RGBA": (Image.fromarray(np.stack([rows] * 4, -1)), 4),
        "P": (Image.fromarray(np.stack([rows] * 3, -1)).convert("P"), 3),
        "I;16": (Image.fromarray(rows.astype(np.uint16) * 257), 1),
    }
    for mode, (image, channels) in cases.items():
        path = tmp_path / f"{mode.replace(';', '_')}.png"
        image.save(path)
        t = load_texture(path)
        assert t.dtype == np.float32 and t.shape == (4, 3, channels), mode
        np.testing.assert_array_equal(t[0], 1.0)
        np.testing.assert_array_equal(t[1:], 0.0)


@pytest.mark.shared_data
def test_spot_merges_its_uv_seams(shared_data):
    import trimesh

    obj = shared_data / "spot" / "spot_triangulated.obj"
    m = load_mesh(obj, texture=shared_data / "spot" / "spot_texture.png")
    assert (len(m.split_to_merged), m.num_vertices, m.num_faces) == (3225, 2930, 5856)
    raw = trimesh.load_mesh(str(obj), process=False)
    # the stored vertices are exact copies of the merged ones, the corners keep the file's UVs
    np.testing.assert_array_equal(m.vertices[m.split_to_merged], raw.vertices)
    np.testing.assert_array_equal(m.split_faces, raw.faces)
    np.testing.assert_array_equal(m.split_to_merged[m.split_faces], m.faces)
    np.testing.assert_array_equal(m.uv, raw.visual.uv[raw.faces])
    assert m.texture.shape == (1024, 1024, 3) and m.texture.dtype == np.float32
    assert 0.0 <= m.texture.min() and m.texture.max() <= 1.0
    s = mesh_statistics(m)
    assert s.valid and s.closed and s.genus == 0 and s.components == 1
    unmerged = load_mesh(obj, merge_seams=False)
    assert unmerged.num_vertices == 3225 and unmerged.texture is None  # the OBJ names no texture
    with pytest.raises(NonManifoldVertexError):  # the seams pinch where they meet
        validate_mesh(unmerged.vertices, unmerged.faces)


@pytest.mark.shared_data
def test_spot_textured_round_trip(shared_data, tmp_path):
    spot = shared_data / "spot"
    m = load_mesh(spot / "spot_triangulated.obj", texture=spot / "spot_texture.png")
    save_mesh(m, tmp_path / "spot.obj")
    back = load_mesh(tmp_path / "spot.obj")
    np.testing.assert_array_equal(back.vertices, m.vertices)
    np.testing.assert_array_equal(back.faces, m.faces)
    np.testing.assert_array_equal(back.uv, m.uv)
    np.testing.assert_array_equal(back.texture, m.texture)  # 8-bit PNG in, 8-bit PNG out
    assert len(back.split_to_merged) == 3225


def test_loaded_mesh_is_a_mesh_record(tmp_path):
    path = tmp_path / "ico.off"
    save_mesh(Mesh(*icosphere(1)), path)
    assert isinstance(load_mesh(str(path)), Mesh)

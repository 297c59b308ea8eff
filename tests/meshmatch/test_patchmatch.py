"""PatchMatch end to end: self-transfer quality, rotation recovery, painting, displacement, CLI."""

from __future__ import annotations

import json

import jax
import numpy as np
import pytest

from jmeshtex import InputError, Mesh
from jmeshtex.data import coloured_sphere_pair, icosphere
from jmeshtex.meshmatch import Config, load, meshmatch, paint_by_example, transfer_displacement
from jmeshtex.metrics import psnr
from jmeshtex.testing import CATALOGUE, MeshState

KEY = jax.random.key(0)


def _bumpy_sphere(level=2):
    v, f = icosphere(level)
    r = 1 + 0.25 * np.sin(3 * v[:, 0] + 1) * np.cos(2 * v[:, 1]) + 0.15 * np.sin(4 * v[:, 2] + 0.5)
    return v * r[:, None], f


def test_self_transfer_psnr():
    """Source 642 V, target = the same bumpy surface subdivided (2562 V): ≥ 20 dB, random ≪."""
    source, target, truth = coloured_sphere_pair(3)
    result = meshmatch(
        source, source.vertex_colors, target, key=KEY, config=Config(), progress=False
    )
    value = psnr(result.colors, truth)
    rng = np.random.default_rng(0)
    random_colors = source.vertex_colors[rng.integers(0, source.num_vertices, target.num_vertices)]
    print(f"self-transfer {value:.2f} dB, random {psnr(random_colors, truth):.2f} dB")
    assert value >= 20.0
    assert psnr(random_colors, truth) <= value - 8.0


def test_relabelled_target_is_matched_with_the_frame_rotation():
    """A relabelled copy has every tangent frame turned (new slot-0 edges): the match must be the
    same vertex and the rotation the frame turn, to the nearest step 2π/A."""
    v, f = _bumpy_sphere(2)
    rng = np.random.default_rng(3)
    real = CATALOGUE["permute_vertices"].draw(rng, MeshState(v, f))
    colors = 0.5 + 0.4 * np.sin(5 * v[:, :3] + np.array([0.0, 1.0, 2.0]))
    cfg = Config(levels=1, coarse_steps=25)
    r = meshmatch((v, f), colors, (real.target.vertices, real.target.faces), key=KEY, config=cfg)
    hit = r.nnf == real.vperm
    assert hit.mean() > 0.95
    A = cfg.num_angles
    beta = real.frame_rotation()  # target direction φ is source direction φ + β
    step = np.angle(np.exp(1j * (2 * np.pi * r.rotation / A - beta)))
    assert np.all(np.abs(step[hit]) <= 2 * np.pi / A * 0.5 + 1e-6)


def test_paint_by_example_keeps_paint_and_copies_only_painted():
    v, f = _bumpy_sphere(2)
    colors = np.stack(
        [0.5 + 0.4 * np.sin(8 * v[:, 0]), 0.5 + 0.0 * v[:, 1], 0.5 + 0.4 * np.cos(8 * v[:, 2])], 1
    )
    painted = v[:, 2] > -0.1
    out = paint_by_example(
        Mesh(v, f, vertex_colors=colors),
        painted,
        key=KEY,
        config=Config(levels=1, steps=4, coarse_steps=4),
    )
    np.testing.assert_allclose(out.mesh.vertex_colors[painted], colors[painted], atol=1e-6)
    assert painted[out.match.nnf].all()  # every match is a painted vertex
    with pytest.raises(InputError, match="paints no vertex"):
        paint_by_example(Mesh(v, f, vertex_colors=colors), np.zeros(len(v), bool), key=KEY)


def test_displacement_transfer_moves_along_normals():
    v, f = _bumpy_sphere(2)
    smooth_v = v / np.linalg.norm(v, axis=1, keepdims=True)
    out = transfer_displacement(
        (v, f), Mesh(smooth_v, f), key=KEY, config=Config(levels=1, steps=2, coarse_steps=4)
    )
    moved = out.mesh.vertices - smooth_v
    assert np.abs(moved).max() > 1e-3
    normal = smooth_v  # the unit sphere's normals
    cos = np.abs(np.einsum("vd,vd->v", moved, normal)) / np.maximum(
        np.linalg.norm(moved, axis=1), 1e-300
    )
    assert np.all(cos[np.linalg.norm(moved, axis=1) > 1e-9] > 0.99)


def test_bad_inputs():
    v, f = icosphere(1)
    with pytest.raises(InputError, match="source_colors"):
        meshmatch((v, f), np.ones((3, 3)), (v, f), key=KEY)
    with pytest.raises(InputError, match="source_mask"):
        meshmatch((v, f), np.ones((len(v), 3)), (v, f), key=KEY, source_mask=np.zeros(len(v), bool))
    with pytest.raises(InputError, match="target must be a jmeshtex.Mesh"):
        meshmatch((v, f), np.ones((len(v), 3)), v, key=KEY)


def test_cli_transfer_writes_mesh_renders_and_summary(tmp_path):
    from jmeshtex.cli import main
    from jmeshtex.io import save_mesh

    source, target, _ = coloured_sphere_pair(3)
    save_mesh(
        source.replace(vertex_colors=source.vertex_colors.astype(np.float32)), tmp_path / "src.ply"
    )
    save_mesh(target, tmp_path / "tgt.ply")
    out = tmp_path / "out"
    code = main(
        [
            "meshmatch",
            "transfer",
            "--source",
            str(tmp_path / "src.ply"),
            "--target",
            str(tmp_path / "tgt.ply"),
            "--out",
            str(out),
            "--quiet",
            "--steps",
            "2",
            "--seed",
            "3",
        ]
    )
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["levels"]) >= 2
    assert all(level["steps"] <= 2 for level in summary["levels"][1:])  # --steps: finer levels only
    for name in ("source.png", "target.png", "nnf.png", "target.ply"):
        assert (out / name).stat().st_size > 500
    back = load(out)  # the CLI also writes the result itself
    assert back.mesh.num_vertices == target.num_vertices and back.match.stats == summary_stats(
        summary
    )
    assert (
        main(
            [
                "meshmatch",
                "paint",
                "--mesh",
                str(tmp_path / "src.ply"),
                "--mask",
                str(tmp_path / "none.txt"),
                "--out",
                str(out),
            ]
        )
        == 2
    )  # missing mask file: a clear error, exit status 2


def summary_stats(summary: dict) -> dict:
    """The match statistics inside a CLI summary (the summary adds the file names)."""
    return {k: v for k, v in summary.items() if k not in ("mesh", "renders")}


def test_cli_takes_procedural_mesh_names(tmp_path):
    from jmeshtex.cli import main

    out = tmp_path / "out"
    code = main(
        [
            "meshmatch",
            "transfer",
            "--source",
            "striped-sphere:3",
            "--target",
            "icosphere:3",
            "--out",
            str(out),
            "--quiet",
            "--steps",
            "1",
        ]
    )
    assert code == 0
    assert load(out).mesh.vertex_colors.shape == (642, 3)

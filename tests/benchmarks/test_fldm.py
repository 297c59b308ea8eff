"""Smoke test of ``benchmarks/fldm.py --quick``: it runs end to end on Spot and its table has
every row with finite numbers; without Spot it exits with a message that says what is missing."""

from __future__ import annotations

import json
import math
import os
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "fldm.py"


def _run(args: list[str], env: dict[str, str], timeout: float = 300) -> subprocess.CompletedProcess:
    # a separate process: the benchmark runs in float32 without debug_nans, as from the command
    # line; it inherits the suite's XLA_FLAGS (its quick optimisation level, conftest.py), which keeps
    # this compile-bound smoke run cheaper (measured: 148 CPU-s, 190 with XLA's defaults)
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.mark.slow
@pytest.mark.shared_data
def test_quick_run_writes_a_table_with_every_row(shared_data, tmp_path):
    env = {**os.environ, "JMESHTEX_SHARED_DATA": str(shared_data)}
    work = tmp_path / "work"
    # about 2 min on 2 quiet cores (training, DDIM, DDPM, decoding, VGG); slack for a busy machine
    proc = _run(["--quick", "--out", str(tmp_path), "--work", str(work)], env, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    payload = json.loads((tmp_path / "fldm_spot.json").read_text())
    rows = {r["source"]: r for r in payload["rows"] if r["table"] == "quality"}
    sources = [
        "masked flat colour",
        "reconstruction",
        "shuffled latents",
        "random channel phases",
        "samples DDIM-3",
        "samples DDPM-1000",
        "exemplar (floor)",
    ]
    assert list(rows) == sources
    floor = rows.pop("exemplar (floor)")
    for r in rows.values():
        assert math.isfinite(r["fidelity_gram"]) and r["fidelity_gram"] >= 0, r
        assert all(math.isfinite(r[k]) for k in ("patch_gram", "patch_spectrum", "palette_tv")), r
    # the surface-patch measure and the palette: the exemplar against itself (the floor) and the
    # codec's reconstruction closer than a flat colour
    flat = rows["masked flat colour"]
    assert floor["patch_gram"] < flat["patch_gram"] and floor["palette_tv"] == 0
    assert rows["reconstruction"]["patch_gram"] < flat["patch_gram"]
    assert rows["reconstruction"]["palette_tv"] < flat["palette_tv"]
    # the codec reconstructs the exemplar better than the flat colour, the shuffled latents and the
    # latents with a random phase each (the decoder reads the relative phases)
    recon = rows["reconstruction"]
    for base in ("masked flat colour", "shuffled latents", "random channel phases"):
        assert recon["fidelity_gram"] < rows[base]["fidelity_gram"], base
    # the decoder-free statistics separate the baselines: shuffling removes the spatial statistic,
    # random phases the pointwise one
    assert recon["energy_corr"] > 0.4 and abs(rows["shuffled latents"]["energy_corr"]) < 0.1
    # the shipped FL-VAE's latents: R ≈ 0.5 (benchmarks/results/fldm_spot_flvae5k.md); random phases ≈ 0
    assert recon["concentration"] > 0.35 > 0.2 > rows["random channel phases"]["concentration"]
    assert abs(rows["shuffled latents"]["nearest_copy_corr"]) < 0.1 < recon["nearest_copy_corr"]
    assert rows["samples DDIM-3"]["n"] == 2 and rows["samples DDIM-3"]["diversity_lpips"] > 0
    curve = [r for r in payload["rows"] if r["table"] == "statistics"]
    assert [r["source"] for r in curve] == ["step 2", "step 4", "training copy 0 (data)"]
    assert all(math.isfinite(r["concentration"]) for r in curve)
    # the denoising probe: one denoiser call at five noise levels; at the lowest the estimate is
    # nearly the data (relative squared error well below 1) whatever the training
    probe = [r for r in payload["rows"] if r["table"] == "denoising"]
    assert len(probe) == 5 and all(math.isfinite(r["energy_corr"]) for r in probe)
    assert probe[0]["x0_error"] < 0.1 < probe[-1]["x0_error"]
    # the traced DDIM path: every fifth of 50 steps and the last; at t = 0 the estimate is the state
    path = [r for r in payload["rows"] if r["table"] == "trajectory"]
    assert len(path) == 11 and path[-1]["source"].startswith("step 49 of 50, t = 0")
    assert abs(path[-1]["energy_corr"] - path[-1]["input_energy_corr"]) < 0.05
    train = next(r for r in payload["rows"] if r["table"] == "training")
    assert train["n"] == payload["config"]["fldm"]["steps"] == 4
    assert train["s_per_step"] > 0 and train["cpu_s_per_step"] > 0
    assert (tmp_path / "fldm_spot.png").stat().st_size > 1000
    assert (work / "models" / "step_00004" / "card.json").is_file()
    from jmeshtex.io import Checkpoints

    with Checkpoints(work / "train") as ckpt:  # the checkpoint folder a re-run resumes
        assert ckpt.latest_step() == 4
    # evaluating a step without a snapshot says which ones there are
    proc = _run(
        ["--quick", "--eval-only", "--checkpoint-step", "3", "--out", str(tmp_path / "x")]
        + ["--work", str(work)],
        env,
    )
    assert proc.returncode != 0 and "no snapshot of step 3" in proc.stderr, proc.stderr[-2000:]


def test_missing_spot_exits_with_a_clear_message(tmp_path):
    env = {**os.environ, "JMESHTEX_SHARED_DATA": str(tmp_path / "nowhere")}
    proc = _run(["--quick", "--out", str(tmp_path)], env, timeout=120)
    assert proc.returncode != 0
    assert (
        "spot_triangulated.obj not found" in proc.stderr and "JMESHTEX_SHARED_DATA" in proc.stderr
    )
    assert not (tmp_path / "fldm_spot.json").exists()


def test_samples_are_drawn_at_the_training_density(monkeypatch):
    """The sampling mesh is Spot subdivided to the training copies' density (nearest in ratio):
    a 3K-vertex model samples on Spot itself, a 10K one on Spot subdivided once."""
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    import fldm as bench

    got = [bench.sampling_subdivisions(v, 2930) for v in (400, 3000, 5000, 10000, 40000)]
    assert got == [0, 0, 0, 1, 2]

"""Checkpoints: resume takes the newest readable step; read and write errors are one typed error."""

from __future__ import annotations

import errno
import json

import numpy as np
import pytest

from jmeshtex import CheckpointMismatchError, CheckpointSkippedWarning, MeshIOError
from jmeshtex.io import Checkpoints


def _two_steps(folder, **kw) -> Checkpoints:
    ckpt = Checkpoints(folder, fingerprint={"run": 1}, **kw)
    ckpt.save(1, {"w": np.full(3, 1.0)}, meta={"step": 1})
    ckpt.save(2, {"w": np.full(3, 2.0)}, meta={"step": 2})
    return ckpt


def test_a_corrupt_newest_step_resumes_from_the_previous(tmp_path):
    _two_steps(tmp_path).close()
    (tmp_path / "2" / "meta" / "metadata").write_bytes(b"\xff\xfe garbage")
    ckpt = Checkpoints(tmp_path, fingerprint={"run": 1})
    with pytest.warns(CheckpointSkippedWarning, match=r"2 skipped: unreadable meta"):
        assert ckpt.latest_step() == 1
    state, meta = ckpt.restore({"w": np.zeros(3)})
    assert state["w"].tolist() == [1.0, 1.0, 1.0] and meta == {"step": 1}
    # and the run goes on: step 2 is written again over the unreadable one
    ckpt.save(2, {"w": np.full(3, 4.0)}, meta={"step": 2})
    assert ckpt.latest_step() == 2
    assert ckpt.restore({"w": np.zeros(3)})[0]["w"].tolist() == [4.0, 4.0, 4.0]


def test_a_stray_or_empty_step_folder_is_skipped(tmp_path):
    _two_steps(tmp_path).close()
    (tmp_path / "999").mkdir()
    (tmp_path / "998").mkdir()
    (tmp_path / "998" / "notes.txt").write_text("not a checkpoint")
    ckpt = Checkpoints(tmp_path, fingerprint={"run": 1})
    with pytest.warns(CheckpointSkippedWarning) as record:
        assert ckpt.latest_step() == 2
    named = sorted(str(w.message).split(" skipped")[0].rsplit("/", 1)[1] for w in record)
    assert named == ["998", "999"]
    assert ckpt.read_meta()["step"] == 2
    assert ckpt.restore({"w": np.zeros(3)})[0]["w"].tolist() == [2.0, 2.0, 2.0]


def test_wrong_typed_meta_is_skipped_and_a_foreign_run_is_still_a_mismatch(tmp_path):
    _two_steps(tmp_path).close()
    (tmp_path / "2" / "meta" / "metadata").write_text(json.dumps([1, 2, 3]))
    ckpt = Checkpoints(tmp_path, fingerprint={"run": 1})
    with pytest.warns(CheckpointSkippedWarning, match="not a JSON object"):
        assert ckpt.latest_step() == 1
    other = Checkpoints(tmp_path, fingerprint={"run": 2})
    with (
        pytest.raises(CheckpointMismatchError, match="run"),
        pytest.warns(CheckpointSkippedWarning),
    ):
        other.restore({"w": np.zeros(3)})


def test_flipped_data_bytes_are_one_typed_error(tmp_path, capfd):
    _two_steps(tmp_path).close()
    data = [p for p in (tmp_path / "2" / "state").rglob("d/*") if p.is_file()]
    assert data
    for p in data:
        raw = bytearray(p.read_bytes())
        for i in range(0, len(raw), 7):
            raw[i] ^= 0xFF
        p.write_bytes(bytes(raw))
    ckpt = Checkpoints(tmp_path, fingerprint={"run": 1})
    with pytest.raises(MeshIOError, match=r"2 cannot be read|does not match"):
        ckpt.restore({"w": np.zeros(3)})
    assert ckpt.restore({"w": np.zeros(3)}, step=1)[0]["w"].tolist() == [1.0, 1.0, 1.0]
    assert "Event loop is closed" not in capfd.readouterr().err


def test_a_full_disk_is_one_typed_error_and_leaves_no_temporary_folder(tmp_path, monkeypatch):
    import orbax.checkpoint as ocp

    ckpt = _two_steps(tmp_path)

    def full(self, step, *args, **kwargs):
        (tmp_path / f"{step}.orbax-checkpoint-tmp-123").mkdir()
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(ocp.CheckpointManager, "save", full)
    with pytest.raises(MeshIOError, match="ENOSPC") as info:
        ckpt.save(3, {"w": np.full(3, 3.0)}, meta={"step": 3})
    assert "\n" not in str(info.value)
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["1", "2"]
    assert ckpt.latest_step() == 2


def test_sigkill_during_saves_resumes_to_a_complete_step(tmp_path):
    """A process killed (SIGKILL) while writing checkpoints leaves a folder that resumes exactly."""
    import os
    import signal
    import subprocess
    import sys
    import time
    import warnings

    code = (
        "import sys, numpy as np\n"
        "from jmeshtex.io import Checkpoints\n"
        "c = Checkpoints(sys.argv[1], fingerprint={'run': 1})\n"
        "for step in range(1, 10_000):\n"
        "    c.save(step, {'w': np.full(1 << 20, float(step))}, meta={'step': step})\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code, str(tmp_path)])
    try:
        deadline = time.monotonic() + 120
        while not (tmp_path / "3").is_dir() and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.37)  # somewhere inside a later save
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    assert (tmp_path / "3").exists() or any(p.name.isdigit() for p in tmp_path.iterdir())
    with warnings.catch_warnings():
        # a step folder half-deleted by the keep-2 cleanup may be skipped with a warning
        warnings.simplefilter("ignore", CheckpointSkippedWarning)
        ckpt = Checkpoints(tmp_path, fingerprint={"run": 1})
        step = ckpt.latest_step()
        assert step is not None and step >= 1
        state, meta = ckpt.restore({"w": np.zeros(1 << 20)})
    assert meta["step"] == step
    np.testing.assert_array_equal(state["w"], np.full(1 << 20, float(step)))

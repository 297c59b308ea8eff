"""Checkpoints: resume takes the newest readable step; read and write errors are one typed error."""

from __future__ import annotations

import errno
import json

import numpy as np
import pytest

from jmeshtex import CheckpointMismatchError, CheckpointSkippedWarning, InputError, MeshIOError
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
    # and the run goes on: step 2 is written again over the damaged one (it is jmeshtex's)
    ckpt.save(2, {"w": np.full(3, 4.0)}, meta={"step": 2})
    assert ckpt.latest_step() == 2
    assert ckpt.restore({"w": np.zeros(3)})[0]["w"].tolist() == [4.0, 4.0, 4.0]


def _data_files(step_folder):
    return sorted(p for p in (step_folder / "state").rglob("d/*") if p.is_file())


@pytest.mark.parametrize("damage", ["truncate", "flip", "delete", "manifest"])
def test_any_damage_to_the_newest_step_falls_back_to_the_older_one(tmp_path, damage, capfd):
    _two_steps(tmp_path).close()
    step = tmp_path / "2"
    if damage == "manifest":
        targets = [step / "state" / "manifest.ocdbt"]
    else:
        targets = _data_files(step)
    assert targets and all(p.is_file() for p in targets)
    for p in targets:
        raw = bytearray(p.read_bytes())
        if damage == "truncate":
            p.write_bytes(bytes(raw[: len(raw) // 2]))
        elif damage == "delete":
            p.unlink()
        else:
            for i in range(0, len(raw), 7):
                raw[i] ^= 0xFF
            p.write_bytes(bytes(raw))
    ckpt = Checkpoints(tmp_path, fingerprint={"run": 1})
    with pytest.warns(CheckpointSkippedWarning, match=r"2 skipped: its checksums differ"):
        assert ckpt.latest_step() == 1
    assert ckpt.restore({"w": np.zeros(3)})[0]["w"].tolist() == [1.0, 1.0, 1.0]
    assert "Event loop is closed" not in capfd.readouterr().err


def test_foreign_folders_are_ignored_and_never_deleted(tmp_path):
    """Numbered folders jmeshtex did not write (a user's photos, a '²') survive saves and retention."""
    for name in ("1", "100", "\u00b2", "998"):
        (tmp_path / name).mkdir()
    (tmp_path / "100" / "holiday.jpg").write_bytes(b"x")
    ckpt = Checkpoints(tmp_path, fingerprint={"run": 1}, keep=1)
    assert ckpt.latest_step() is None
    for step in (2, 3, 4):
        ckpt.save(step, {"w": np.full(3, float(step))}, meta={"step": step})
    names = sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("."))
    assert names == sorted(["1", "100", "\u00b2", "998", "4"])
    assert (tmp_path / "100" / "holiday.jpg").read_bytes() == b"x"
    assert ckpt.latest_step() == 4
    with pytest.raises(MeshIOError, match="jmeshtex did not write"):
        ckpt.save(100, {"w": np.zeros(3)})
    assert (tmp_path / "100" / "holiday.jpg").read_bytes() == b"x"


def test_a_symlinked_folder_and_bad_keep_are_typed_errors(tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    with pytest.raises(MeshIOError, match="symbolic link"):
        Checkpoints(tmp_path / "link")
    for keep in (0, -1, 1.5, "2", True):
        with pytest.raises(InputError, match="keep"):
            Checkpoints(tmp_path / "c", keep=keep)


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


def test_a_full_disk_is_one_typed_error_and_leaves_no_temporary_folder(tmp_path, monkeypatch):
    import orbax.checkpoint as ocp

    ckpt = _two_steps(tmp_path)

    def full(self, path, *args, **kwargs):
        path.parent.joinpath("state.orbax-checkpoint-tmp-123").mkdir()
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(ocp.Checkpointer, "save", full)
    with pytest.raises(MeshIOError, match="ENOSPC") as info:
        ckpt.save(3, {"w": np.full(3, 3.0)}, meta={"step": 3})
    assert "\n" not in str(info.value)
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == [".jmeshtex-checkpoints.json", "1", "2"]
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

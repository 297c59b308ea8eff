"""Two JAX processes on this machine (jax.distributed + gloo CPU collectives) train the FL-VAE as one
data-parallel program: the loss trajectory equals a one-process run on the same global batch."""

from __future__ import annotations

import json
import os
import pathlib
import socket
import subprocess
import sys

import jax
import numpy as np
import pytest

from jmeshtex import fl

sys.path.insert(0, str(pathlib.Path(__file__).parents[1] / "fl"))
from sharded_worker import CONFIG, images  # noqa: E402

WORKER = pathlib.Path(__file__).with_name("multiprocess_worker.py")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.few_steps
def test_two_processes_train_like_one(tmp_path):
    """Trainings of 3 steps: every program compiles at the suite's quick XLA level, the one-process
    run here (``few_steps``, conftest.py) and the two processes alike (they get the suite's
    ``XLA_FLAGS``, less any forced device count: each must see one device). Measured (-n 0, empty
    JAX cache): 68 CPU-s for the test when all three compiled their steps at XLA's full level, 48
    now."""
    port = _free_port()
    flags = [
        f
        for f in os.environ.get("XLA_FLAGS", "").split()
        if not f.startswith("--xla_force_host_platform_device_count")
    ]
    env = {**os.environ, "XLA_FLAGS": " ".join(flags), "JAX_PLATFORMS": "cpu"}
    procs = [
        subprocess.Popen(
            [sys.executable, str(WORKER), str(port), str(pid), str(tmp_path)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        for pid in (0, 1)
    ]
    logs = []
    try:
        for p in procs:
            logs.append(p.communicate(timeout=600)[0])
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
    assert all(p.returncode == 0 for p in procs), "\n----\n".join(log[-3000:] for log in logs)
    runs = [json.loads((tmp_path / f"losses_{pid}.json").read_text()) for pid in (0, 1)]
    assert len(runs[0]["devices"]) == 2
    # both processes see the same replicated loss
    np.testing.assert_array_equal(runs[0]["loss"], runs[1]["loss"])
    alone = fl.train(
        images(),
        CONFIG.replace(steps=3),
        key=jax.random.key(0),
        progress=False,
        devices=jax.devices()[:1],
    )
    # the gradient all-reduce across processes sums in another order: float32 round-off, compounded
    # over 3 Adam steps
    np.testing.assert_allclose(runs[0]["loss"], alone.losses["loss"], rtol=1e-4)
    assert np.ptp(alone.losses["loss"]) > 1e-3

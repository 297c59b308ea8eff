"""FL-VAE training data-parallel over 4 forced host devices (in a subprocess: the rest of the suite
keeps one device): a sharded step equals the one-device step, a resumed sharded run equals an
uninterrupted one, and checkpoints move between one device and four."""

from __future__ import annotations

import json
import pathlib
import sys

import jax
import numpy as np
import pytest

from jmeshtex import fl
from tests._four_devices import run_worker

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from sharded_worker import CONFIG, train  # noqa: E402

WORKER = pathlib.Path(__file__).with_name("sharded_worker.py")


@pytest.mark.few_steps
def test_sharded_fl_vae_training_matches_one_device_and_resumes_across_meshes(tmp_path):
    """Every training here runs 4 steps, so every program compiles at the suite's quick XLA level:
    the one-device runs here (``few_steps``, conftest.py) and the four-device process alike (it
    inherits the suite's ``XLA_FLAGS``). Measured (-n 0, empty JAX cache): 113 CPU-s for the test
    when both compiled their steps at XLA's full level, 71 now."""
    # a one-device checkpoint at step 2, for the four-device process to resume
    train(tmp_path / "ckpt_1", stop_after=2)
    run_worker(WORKER, tmp_path)
    out = json.loads((tmp_path / "result.json").read_text())

    # one step: four devices equal one device to float32 round-off (the gradient is reduced over devices
    # by XLA in another order); the barycentric decoder gathers corner latents across devices
    for decoder, step in out["step"].items():
        np.testing.assert_allclose(
            step["four"]["loss"], step["one"]["loss"], rtol=1e-5, err_msg=decoder
        )
        np.testing.assert_allclose(
            step["four"]["l1"], step["one"]["l1"], rtol=1e-5, err_msg=decoder
        )
        for a, b in zip(step["four"]["params"], step["one"]["params"], strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6, err_msg=decoder)
        assert step["one"]["loss"] > 0
    grads_4, grads_1 = (
        np.concatenate([np.array(g) for g in out["step"]["log"][k]["grads"]])
        for k in ("four", "one")
    )
    assert np.abs(grads_1).max() > 1e-3
    np.testing.assert_allclose(grads_4, grads_1, rtol=1e-4, atol=1e-5 * np.abs(grads_1).max())

    full_4 = np.array(out["full_4"])
    full_1 = train().losses["loss"]  # here: one device
    assert full_4.shape == (CONFIG.steps,) and np.isfinite(full_4).all()
    # 4 Adam steps: round-off of each step's reduction compounds a little (Adam divides by sqrt(v))
    np.testing.assert_allclose(full_4, full_1, rtol=1e-4)
    assert np.ptp(full_4) > 1e-3  # the trajectory moves: equality above is not of constants
    # resumed on the same mesh: the same program on the same state, so the same numbers
    np.testing.assert_allclose(out["resumed_4"], full_4, rtol=1e-6)
    # one-device checkpoint resumed on four devices
    assert out["from_1_resumed_from"] == 2
    np.testing.assert_allclose(out["from_1"], full_1, rtol=1e-4)

    # four-device checkpoint resumed here on one device, and the four-device model file loaded here
    back = train(tmp_path / "ckpt_4")
    assert back.resumed_from == 2
    np.testing.assert_allclose(back.losses["loss"], full_4, rtol=1e-4)
    model = fl.load(tmp_path / "model_4")
    assert model.config == CONFIG
    for a, b in zip(jax.tree.leaves(model.params), jax.tree.leaves(back.model.params), strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-4, atol=1e-6)

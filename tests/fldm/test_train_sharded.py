"""FLDM training data-parallel over 4 forced host devices (in a subprocess: the rest of the suite keeps
one device): the loss and its gradient on four devices equal one device's, a four-device run follows
the one-device trajectory, a resumed sharded run equals an uninterrupted one, checkpoints and model
files move between one device and four, and a batch that does not split raises a ConfigError."""

from __future__ import annotations

import json
import pathlib
import sys

import jax
import numpy as np
import pytest

from jmeshtex import ConfigError, fldm, parallel
from tests._four_devices import run_worker

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from fldm_sharded_worker import CONFIG, dataset, leaves  # noqa: E402

WORKER = pathlib.Path(__file__).with_name("fldm_sharded_worker.py")

#: every training here runs a few steps, so every program compiles at the suite's quick XLA level:
#: the one-device runs here (``few_steps``, conftest.py) and the four-device process alike (it
#: inherits the suite's ``XLA_FLAGS``)
pytestmark = pytest.mark.few_steps


#: the training run both processes follow
KEY = jax.random.key(5)


@pytest.fixture(scope="module")
def sharded(tmp_path_factory) -> tuple[pathlib.Path, dict]:
    """One four-device process for both tests (its start, imports and data set once): the work
    folder and the worker's ``result.json``. The parent first writes ``ckpt_1``, a one-device
    checkpoint at step 2, for the four-device process to resume."""
    work = tmp_path_factory.mktemp("sharded")
    fldm.train(
        dataset(), CONFIG, key=KEY, progress=False, checkpoint_dir=work / "ckpt_1", stop_after=2
    )
    run_worker(WORKER, work)
    return work, json.loads((work / "result.json").read_text())


def _close(a, b, *, rtol, atol_scale):
    """Leaf-wise closeness, the absolute tolerance a fraction of each reference leaf's largest entry."""
    for x, y in zip(a, b, strict=True):
        x, y = np.asarray(x), np.asarray(y)
        np.testing.assert_allclose(x, y, rtol=rtol, atol=atol_scale * np.abs(y).max())


def test_sharded_loss_and_gradient_equal_one_device(sharded):
    one, four = sharded[1]["step"]["one"], sharded[1]["step"]["four"]
    assert one["loss"] > 0
    # float32 round-off: XLA reduces the per-device sums over the batch in another order
    np.testing.assert_allclose(four["loss"], one["loss"], rtol=1e-5)
    g1, g4 = (np.concatenate([np.array(g) for g in s["grads"]]) for s in (one, four))
    assert np.abs(g1).max() > 1e-3
    np.testing.assert_allclose(g4, g1, rtol=1e-4, atol=1e-5 * np.abs(g1).max())


def test_sharded_training_follows_one_device_and_resumes_across_meshes(sharded):
    work, out = sharded
    data, key = dataset(), KEY

    # the optimiser steps (make_train_step on a mesh of four, EMA included) follow the one-device run here
    full_1 = fldm.train(data, CONFIG, key=key, progress=False)
    full_4 = np.array(out["full_4"])
    assert full_4.shape == (CONFIG.steps,) and np.isfinite(full_4).all()
    assert np.ptp(full_4) > 1e-3  # the trajectory moves: the equality below is not of constants
    # a few Adam steps: each step's round-off compounds a little (Adam divides by sqrt(v))
    np.testing.assert_allclose(full_4, full_1.losses["loss"], rtol=1e-4)
    # atol 5e-4 of each leaf's largest entry: the field convolution's reverse mode (JAX's transpose
    # of its blocked custom_jvp tangent) sums in another order on four devices, and Adam's
    # normalised step turns that round-off into up to 1.1e-6 absolute on an entry 1/80th of its
    # leaf's largest (measured: 1.9e-4 of the largest; a wrong sharding moves entries by O(1))
    _close(out["full_4_model"], leaves(full_1.model.params), rtol=1e-4, atol_scale=5e-4)
    # resumed on the same mesh: the same programs on the same state, so the same numbers
    assert out["resumed_4_from"] == 2
    np.testing.assert_allclose(out["resumed_4"], full_4, rtol=1e-6)
    _close(out["resumed_4_model"], out["full_4_model"], rtol=1e-6, atol_scale=1e-7)
    # a one-device checkpoint resumed on four devices
    assert out["from_1_resumed_from"] == 2
    np.testing.assert_allclose(out["from_1"], full_1.losses["loss"], rtol=1e-4)

    # a four-device checkpoint resumed here on one device, and the four-device model file loaded here
    back = fldm.train(data, CONFIG, key=key, progress=False, checkpoint_dir=work / "ckpt_4")
    assert back.resumed_from == 2
    np.testing.assert_allclose(back.losses["loss"], full_4, rtol=1e-4)
    _close(leaves(back.model.params), out["full_4_model"], rtol=1e-4, atol_scale=1e-4)
    model = fldm.load(work / "model_4")
    assert model.config == CONFIG
    _close(
        leaves(model.params), out["full_4_model"], rtol=0, atol_scale=0
    )  # the file holds the same numbers

    # a batch that four devices cannot split is an error, not a silently larger batch
    assert len(out["errors"]) == 1
    assert "batch_size=2" in out["errors"][0] and "multiple of 4" in out["errors"][0]


def test_train_takes_a_mesh_or_devices_not_both():
    with pytest.raises(ConfigError, match="mesh or devices"):
        fldm.train(
            dataset(),
            CONFIG,
            key=jax.random.key(0),
            progress=False,
            device_mesh=parallel.data_mesh(),
            devices=jax.devices(),
        )

"""Run by tests/fldm/test_train_sharded.py in a fresh process with 4 forced host devices (not a test).

argv: a work folder holding ``ckpt_1`` (a one-device checkpoint the parent wrote half-way). Writes
``result.json`` there, in one process (one start, one import, one data set for both tests):
- ``step``: the training loss and its gradient for the same parameters, batch and noise on one
  device (``one``) and on four (``four``);
- ``full_4``, ``full_4_model``: the losses and the (EMA) model's leaves of an uninterrupted run on
  four devices (the parent runs it on one: the optimiser step of one device against four);
- ``resumed_4``: the same run stopped half-way and resumed from its checkpoint, on four;
- ``from_1``: resumed on four devices from ``ckpt_1``;
- ``errors``: the message of the ConfigError of a batch that does not split over four devices.
Leaves ``ckpt_4`` (a four-device checkpoint half-way) and ``model_4`` (the four-device model) for
the parent to load on one device.
"""

from __future__ import annotations

import json
import pathlib
import shutil
import sys

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
jax.config.update("jax_debug_nans", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from jmeshtex import ConfigError, fldm, parallel  # noqa: E402
from jmeshtex.data import icosphere  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))  # the repository root
from tests._four_devices import compile_once  # noqa: E402
from tests._presets import FLDM_MICRO  # noqa: E402

# 4 copies per step (one per device), an EMA so the returned model is the replicated EMA
CONFIG = FLDM_MICRO.replace(
    n_copies=4, batch_size=4, steps=4, checkpoint_every=2, warmup_steps=1, ema_decay=0.9
)


def encode(mesh) -> np.ndarray:
    """A smooth two-channel latent field (the vertex positions as complex numbers)."""
    v = np.asarray(mesh.vertices)
    return (v[:, 0] + 1j * v[:, 1])[:, None] * np.array([1.0, 0.5j]) + v[:, 2:3]


def dataset() -> fldm.Dataset:
    return fldm.build_dataset(
        icosphere(1), CONFIG, encode=encode, key=jax.random.key(0), progress=False
    )


def leaves(tree) -> list[list[float]]:
    return [
        np.asarray(a, np.complex128).ravel().view(np.float64).tolist()
        for a in jax.tree.leaves(tree)
    ]


def one_gradient(data: fldm.Dataset, mesh) -> dict:
    """The training loss (ε-prediction, eq. 10) and its gradient for one batch, data-parallel on ``mesh``."""
    params = fldm.init(data, CONFIG, key=jax.random.key(1)).params
    z0, geo, _ = fldm.core.training_batch(data, 0, CONFIG.batch_size, key=jax.random.key(2))
    schedule = fldm.core.make_schedule(CONFIG.schedule, num_steps=CONFIG.diffusion_steps)
    t = np.arange(CONFIG.batch_size, dtype=np.int32) * 5 + 1
    eps = np.asarray(jax.random.normal(jax.random.key(3), z0.shape, jnp.complex64))

    def loss(p, z0, geo, t, eps):
        zt = fldm.core.q_sample(schedule, z0, t, eps)
        pred = jax.vmap(lambda z, tt, g: fldm.core.denoise(p, CONFIG, z, tt, g))(zt, t, geo)
        return fldm.core.epsilon_loss(pred, eps, geo.fine.vertex_mask)

    step = parallel.data_parallel(jax.value_and_grad(loss), mesh, batch_argnums=(1, 2, 3, 4))
    value, grads = parallel.fetch(step(params, z0, geo, t, eps))
    return {"loss": float(value), "grads": leaves(grads)}


def main(work: pathlib.Path) -> None:
    assert len(jax.devices()) == 4, jax.devices()
    data = dataset()
    one, four = parallel.data_mesh(jax.devices()[:1]), parallel.data_mesh()
    out = {"step": {"one": one_gradient(data, one), "four": one_gradient(data, four)}, "errors": []}
    key = jax.random.key(5)
    full = fldm.train(data, CONFIG, key=key, progress=False)
    out["full_4"] = full.losses["loss"].tolist()
    out["full_4_model"] = leaves(full.model.params)
    fldm.save(full.model, work / "model_4")
    fldm.train(
        data, CONFIG, key=key, progress=False, checkpoint_dir=work / "ckpt_4_resume", stop_after=2
    )
    shutil.copytree(work / "ckpt_4_resume", work / "ckpt_4")  # left at step 2 for the parent
    resumed = fldm.train(
        data, CONFIG, key=key, progress=False, checkpoint_dir=work / "ckpt_4_resume"
    )
    out["resumed_4"] = resumed.losses["loss"].tolist()
    out["resumed_4_from"] = resumed.resumed_from
    out["resumed_4_model"] = leaves(resumed.model.params)
    from_1 = fldm.train(data, CONFIG, key=key, progress=False, checkpoint_dir=work / "ckpt_1")
    out["from_1"] = from_1.losses["loss"].tolist()
    out["from_1_resumed_from"] = from_1.resumed_from
    try:
        fldm.train(data, CONFIG.replace(batch_size=2), key=key, progress=False)
    except ConfigError as err:
        out["errors"].append(str(err))
    (work / "result.json").write_text(json.dumps(out))


if __name__ == "__main__":
    compile_once(pathlib.Path(sys.argv[1]))
    main(pathlib.Path(sys.argv[1]))

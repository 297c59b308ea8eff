"""Run by tests/fl/test_train_sharded.py in a fresh process with 4 forced host devices (not a test).

argv: a work folder. Writes ``result.json`` there:
- ``step``: for each decoder, one training step from the same state and batch on one device and
  on four (loss, l1 and the updated parameters' leaves);
- ``full_4``: the losses of an uninterrupted 4-step run on four devices (the parent runs it on one);
- ``resumed_4``: the same run stopped after 2 steps and resumed from its checkpoint, on four;
- ``from_1``: resumed on four devices from ``ckpt_1`` (a checkpoint the parent wrote on one device).
Leaves ``ckpt_4`` (a four-device checkpoint at step 2) and ``model_4/`` for the parent to load.
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

import numpy as np  # noqa: E402

from jmeshtex import fl, parallel  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))  # the repository root
from tests._four_devices import compile_once  # noqa: E402
from tests._presets import FL_MICRO_MESHES, FL_SHORT_RUN  # noqa: E402

CONFIG = FL_MICRO_MESHES.replace(**FL_SHORT_RUN).replace(meshes_per_image=2, warmup_steps=1)


def images() -> list[np.ndarray]:
    y, x = np.mgrid[0:16, 0:16] / 16
    return [
        np.stack(
            [0.5 + 0.5 * np.cos(2 * np.pi * (i + 1) * x), y, 0.5 + 0.4 * np.sin(5 * y + i)], -1
        )
        for i in range(2)
    ]


def leaves(params) -> list[list[float]]:
    return [
        np.asarray(a, np.complex128).ravel().view(np.float64).tolist()
        for a in jax.tree.leaves(params)
    ]


def one_step(config: fl.Config, mesh) -> dict:
    rng = np.random.default_rng(3)
    meshes = [fl.core.planar_mesh(im, 12, rng=rng) for im in images()]
    batch = fl.core.mesh_batch(meshes, config, rng, num_vertices=24)
    params = fl.init(config, key=jax.random.key(1)).params
    state = fl.core.optimizer(config).init(params)
    out = {}
    if config.decoder == "log":  # the gradient itself (Adam's first update hides its scale)

        def loss(p, b):
            return fl.core.batch_loss(p, config, b, key=jax.random.key(2))[0]

        grads = parallel.data_parallel(jax.grad(loss), mesh, batch_argnums=(1,))(params, batch)
        out["grads"] = leaves(parallel.fetch(grads))
    params, _, loss, aux = fl.core.make_train_step(config, mesh)(
        params, state, batch, jax.random.key(2)
    )
    params = parallel.fetch(params)
    return out | {
        "loss": float(parallel.fetch(loss)),
        "l1": float(parallel.fetch(aux["l1"])),
        "params": leaves(params),
    }


def train(checkpoint_dir: pathlib.Path | None = None, *, stop_after: int | None = None):
    """``CONFIG``'s run on :func:`images` with key 0, the one run both processes train."""
    return fl.train(
        images(),
        CONFIG,
        key=jax.random.key(0),
        progress=False,
        checkpoint_dir=checkpoint_dir,
        stop_after=stop_after,
    )


def main(work: pathlib.Path) -> None:
    assert len(jax.devices()) == 4, jax.devices()
    one = parallel.data_mesh(jax.devices()[:1])
    four = parallel.data_mesh()
    out = {"step": {}}
    for decoder in ("log", "barycentric"):
        c = CONFIG.replace(decoder=decoder)
        out["step"][decoder] = {"one": one_step(c, one), "four": one_step(c, four)}
    full = train()
    out["full_4"] = full.losses["loss"].tolist()
    fl.save(full.model, work / "model_4")
    train(work / "ckpt_4_resume", stop_after=2)
    shutil.copytree(work / "ckpt_4_resume", work / "ckpt_4")  # left at step 2 for the parent
    out["resumed_4"] = train(work / "ckpt_4_resume").losses["loss"].tolist()
    resumed = train(work / "ckpt_1")
    out["from_1"] = resumed.losses["loss"].tolist()
    out["from_1_resumed_from"] = resumed.resumed_from
    (work / "result.json").write_text(json.dumps(out))


if __name__ == "__main__":
    compile_once(pathlib.Path(sys.argv[1]))
    main(pathlib.Path(sys.argv[1]))

"""Run by tests/parallel/test_multiprocess.py as one of two JAX processes (not a test).

argv: coordinator port, process id, work folder. Joins the run with jmeshtex.parallel.initialize
(gloo CPU collectives), trains the FL-VAE of tests/fl/sharded_worker.py for 3 steps on the mesh of
both processes' devices, and writes ``losses_<pid>.json``.
"""

from __future__ import annotations

import json
import pathlib
import sys

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
jax.config.update("jax_debug_nans", True)

from jmeshtex import fl, parallel  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).parents[1] / "fl"))
from sharded_worker import CONFIG, images  # noqa: E402

if __name__ == "__main__":
    port, pid, work = int(sys.argv[1]), int(sys.argv[2]), pathlib.Path(sys.argv[3])
    parallel.initialize(
        f"127.0.0.1:{port}", num_processes=2, process_id=pid, initialization_timeout=120
    )
    assert parallel.is_multiprocess() and len(jax.devices()) == 2 and len(jax.local_devices()) == 1
    mesh = parallel.data_mesh()
    result = fl.train(
        images(), CONFIG.replace(steps=3), key=jax.random.key(0), progress=False, device_mesh=mesh
    )
    (work / f"losses_{pid}.json").write_text(
        json.dumps(
            {
                "loss": result.losses["loss"].tolist(),
                "devices": [str(d) for d in mesh.devices.ravel()],
            }
        )
    )

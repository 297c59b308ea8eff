"""What the FL-VAE studies share: the held-out quality of a model beside the P1 codecs."""

from __future__ import annotations

import os

import jax
import numpy as np
from _study import Report  # noqa: F401  (puts the benchmarks on the path)
from fl_vae import baseline_metrics

from jmeshtex import fl


def load() -> float:
    return os.getloadavg()[0]


def held_out_quality(model, *, size: int = 96) -> dict:
    """Mean held-out atlas PSNR of ``model`` and of the P1 codecs (planar meshes at 26 ppv)."""
    rng = np.random.default_rng(0)
    rows = []
    for image in fl.held_out_images(max_size=size):
        mesh = fl.core.density_mesh(image, 26.0, rng=rng)
        r = fl.reconstruct(model, mesh, key=jax.random.key(0), size=size, lpips=False)
        base = baseline_metrics(mesh, r, lpips=False)
        rows.append(
            [r.metrics["psnr"], base["p1_oracle"]["psnr"], base["p1_fit"]["psnr"]]
            + [base["constant"]["psnr"]]
        )
    m = np.mean(rows, axis=0)
    return {"psnr": m[0], "p1_oracle_psnr": m[1], "p1_fit_psnr": m[2], "constant_psnr": m[3]}

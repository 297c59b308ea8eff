"""``Config.experimental.remat``: every FCResNet block under ``flax.linen.remat`` has the same parameters, and the same
output and gradient as without it (in float64, to round-off)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jmeshtex import fldm
from jmeshtex.data import icosphere

CFG = fldm.Config.tiny(latent_channels=2, widths=(4, 6), hdim=2, knn=5)


def test_remat_keeps_parameters_values_and_gradients():
    geo = fldm.core.denoiser_geometry(icosphere(2), knn=CFG.knn)
    # complex128, so that the comparison is not of float32 round-off (the recomputed pass fuses differently)
    params = fldm.core.init_denoiser(jax.random.key(0), CFG, dtype=jnp.complex128)
    with_remat = fldm.core.init_denoiser(
        jax.random.key(0), CFG.replace(remat=True), dtype=jnp.complex128
    )
    assert jax.tree.structure(with_remat) == jax.tree.structure(params)
    for a, b in zip(jax.tree.leaves(with_remat), jax.tree.leaves(params), strict=True):
        np.testing.assert_array_equal(a, b)
    z = jax.random.normal(jax.random.key(1), (geo.num_vertices, 2), jnp.complex128)
    t = jnp.array(7, jnp.int32)
    gj = jax.tree.map(jnp.asarray, geo)

    def loss(p, cfg):
        out = fldm.core.denoise(p, cfg, z, t, gj)
        return jnp.sum(jnp.abs(out - z) ** 2)

    runs = {}
    for remat in (False, True):
        cfg = CFG.replace(remat=remat)
        runs[remat] = jax.jit(jax.value_and_grad(lambda p, cfg=cfg: loss(p, cfg)))(params)
    (v0, g0), (v1, g1) = runs[False], runs[True]
    assert float(v0) > 0
    np.testing.assert_allclose(float(v1), float(v0), rtol=1e-10)
    for a, b in zip(jax.tree.leaves(g1), jax.tree.leaves(g0), strict=True):
        np.testing.assert_allclose(
            np.asarray(a), np.asarray(b), rtol=1e-8, atol=1e-10 * np.abs(np.asarray(b)).max()
        )

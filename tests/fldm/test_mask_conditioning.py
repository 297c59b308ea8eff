"""Inpainting conditioned on the mask (``Config.mask_conditioning``, §6.4): the denoiser's extra
inputs (parameter shapes, the mask and the known latents reach the output, padding, errors), the
random training masks, training with them, and inpainting that keeps the known region exactly."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import ConfigError, InputError
from jmeshtex.data import icosphere, stripe_encoder
from jmeshtex.fldm import Config, inpaint, random_mask, sample, train
from jmeshtex.fldm._masks import EMPTY_FRACTION
from jmeshtex.fldm.core import (
    denoise,
    denoiser_geometry,
    geometry_sizes,
    init_denoiser,
    pad_geometry,
    training_batch,
    training_masks,
)
from jmeshtex.ops import tangent_noise
from tests.fldm.conftest import TINY_TRAIN, uses_tiny_data

#: a training of 3 steps: its steps compile at the suite's quick XLA level (conftest.py)
pytestmark = pytest.mark.few_steps

CFG = Config.tiny(
    latent_channels=2, widths=(6, 8), hdim=4, knn=7, time_features=8, mask_conditioning=True
)


@pytest.fixture(scope="module")
def sphere():
    v, f = icosphere(2)
    return v, f, denoiser_geometry((v, f), knn=CFG.knn, pool_ratio=0.25)


def _shapes(config):
    return jax.eval_shape(
        lambda k: init_denoiser(k, config), jax.random.key(0)
    )  # traced, not compiled


def test_parameters_take_the_mask_and_the_known_latents():
    plain = _shapes(CFG.replace(mask_conditioning=False))
    cond = _shapes(CFG)
    d, c0 = CFG.latent_channels, CFG.widths[0]
    assert plain["lift"]["kernel"].shape == (d, c0)
    assert cond["lift"]["kernel"].shape == (2 * d, c0)  # z_t ⊕ mask · known
    # the mask is one more per-vertex filter input of each level's embedding MLP
    assert cond["embed_0_0"]["kernel"].shape == (CFG.time_features + 1, 4 * c0)
    assert cond["embed_1_0"]["kernel"].shape == (CFG.time_features + 1, 4 * c0)
    assert cond["out"]["kernel"].shape == (c0, d)
    labelled = _shapes(CFG.replace(num_labels=3))
    assert labelled["embed_0_0"]["kernel"].shape == (CFG.time_features + 3 + 1, 4 * c0)


def test_mask_and_known_latents_reach_the_output_and_padding_is_invariant(sphere):
    v, f, geo = sphere
    V = len(v)
    params = init_denoiser(jax.random.key(0), CFG, dtype=jnp.complex128)
    z = tangent_noise(jax.random.key(1), (V, 2), dtype=jnp.complex128)
    known = tangent_noise(jax.random.key(2), (V, 2), dtype=jnp.complex128)
    mask = jnp.asarray(v[:, 2] > 0)
    t = jnp.array(300)
    out = denoise(params, CFG, z, t, geo, mask=mask, known=known)
    assert out.shape == (V, 2) and out.dtype == jnp.complex128
    no_mask = denoise(params, CFG, z, t, geo, mask=jnp.zeros(V, bool), known=known)
    other_known = denoise(params, CFG, z, t, geo, mask=mask, known=known.at[mask].multiply(2.0))
    hidden = denoise(params, CFG, z, t, geo, mask=mask, known=known.at[~mask].multiply(2.0))
    assert float(jnp.abs(out - no_mask).max()) > 1e-3
    assert float(jnp.abs(out - other_known).max()) > 1e-3
    np.testing.assert_array_equal(out, hidden)  # known latents outside the mask are never read
    sizes = geometry_sizes(geo)
    padded = pad_geometry(geo, V0=sizes["V0"] + 13, V1=sizes["V1"] + 5, M=sizes["M"] + 2)
    pad = 3.0 + tangent_noise(jax.random.key(3), (13, 2), dtype=jnp.complex128)
    outp = denoise(
        params,
        CFG,
        jnp.concatenate([z, pad]),
        t,
        padded,
        mask=jnp.pad(mask, (0, 13), constant_values=True),
        known=jnp.concatenate([known, pad]),
    )
    np.testing.assert_allclose(outp[:V], out, rtol=1e-10, atol=1e-12)
    assert bool(jnp.all(outp[V:] == 0))


def test_mask_input_errors(sphere):
    v, f, geo = sphere
    V = len(v)
    z = jnp.zeros((V, 2), jnp.complex64)
    cond = init_denoiser(jax.random.key(0), CFG)
    with pytest.raises(InputError, match="mask_conditioning=True"):
        denoise(cond, CFG, z, 1, geo)
    with pytest.raises(InputError, match="mask must be"):
        denoise(cond, CFG, z, 1, geo, mask=jnp.zeros(V - 1, bool), known=z)
    with pytest.raises(InputError, match="known must be"):
        denoise(cond, CFG, z, 1, geo, mask=jnp.zeros(V, bool), known=z[:, :1])
    plain_cfg = CFG.replace(mask_conditioning=False)
    plain = init_denoiser(jax.random.key(0), plain_cfg)
    with pytest.raises(InputError, match="not mask-conditioned"):
        denoise(plain, plain_cfg, z, 1, geo, mask=jnp.zeros(V, bool), known=z)
    with pytest.raises(ConfigError, match="mask_conditioning"):
        CFG.replace(mask_conditioning=1)


def test_random_training_masks():
    masks = np.stack([random_mask(icosphere(2), key=jax.random.key(i)) for i in range(200)])
    empty = ~masks.any(1)
    assert abs(empty.mean() - EMPTY_FRACTION) < 0.1
    kept = masks[~empty].mean(1)
    assert kept.min() >= 0.15 and kept.max() <= 0.85  # a cap of 20-80 % of the vertices
    assert np.array_equal(
        random_mask(icosphere(2), key=jax.random.key(7)),
        random_mask(icosphere(2), key=jax.random.key(7)),
    )


CFG_TRAIN = TINY_TRAIN.replace(steps=3, mask_conditioning=True)


@pytest.fixture(scope="module")
def trained(tiny_data):
    # tiny_data is build_dataset(striped_sphere(subdivisions=2), CFG_TRAIN, encode=stripe_encoder,
    # key=jax.random.key(0)), built once per session (tests/fldm/conftest.py)
    assert uses_tiny_data(CFG_TRAIN)
    return tiny_data, train(tiny_data, CFG_TRAIN, key=jax.random.key(1), progress=False)


def test_training_masks_follow_the_batch(trained):
    data, _ = trained
    key = jax.random.key(4)
    m = training_masks(data, 3, 2, key=key)
    assert m.shape == (2, data.latents.shape[1]) and m.dtype == bool
    assert not m[:, 80:].any()  # padding is never "known"
    np.testing.assert_array_equal(m, training_masks(data, 3, 2, key=key))
    z0, _, _ = training_batch(data, 3, 2, key=key)
    assert z0.shape[:2] == m.shape


def test_a_mask_conditioned_model_trains_and_inpaints_exactly(trained):
    data, result = trained
    assert result.steps == 3 and np.isfinite(result.losses["loss"]).all()
    model = result.model
    assert model.params["lift"]["kernel"].shape == (4, CFG_TRAIN.widths[0])
    mesh = data.meshes[0]
    known = stripe_encoder(mesh)
    mask = mesh.vertices[:, 2] > 0
    z = inpaint(model, mesh, known, mask, key=jax.random.key(2), method="ddim", steps=4).latents
    np.testing.assert_allclose(
        z[0][mask], known[mask], rtol=1e-6, atol=1e-6
    )  # the float32 round trip of the scale
    assert np.isfinite(z).all() and not np.allclose(z[0][~mask], known[~mask], atol=1e-2)
    # plain sampling of a mask-conditioned model: an empty mask (what a quarter of the training saw)
    s = sample(model, mesh, key=jax.random.key(2), steps=4).latents
    assert s.shape == (1, 80, 2) and np.isfinite(s).all()
    again = inpaint(model, mesh, known, mask, key=jax.random.key(2), method="ddim", steps=4).latents
    np.testing.assert_array_equal(z, again)  # reproducible from the key

"""Diffusion maths: schedules, forward process, posterior identities, DDIM/DDPM with oracle denoisers,
a Gaussian data set whose exact denoiser is known, inpainting, latent scaling, reproducibility."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import ConfigError, InputError
from jmeshtex.fldm._diffusion import (
    Inpaint,
    ddim_step,
    ddpm_step,
    draw_sampling_noise,
    epsilon_from_output,
    epsilon_loss,
    latent_scale,
    make_schedule,
    prediction_target,
    q_sample,
    sample_from_noise,
    timestep_sequence,
)
from jmeshtex.ops import tangent_noise


def test_linear_and_cosine_schedules():
    lin = make_schedule("linear", num_steps=1000)
    np.testing.assert_allclose(lin.betas[[0, -1]], [1e-4, 0.02], rtol=1e-12)
    np.testing.assert_allclose(np.diff(lin.betas), (0.02 - 1e-4) / 999, rtol=1e-9)
    cos = make_schedule("cosine", num_steps=1000)
    t = np.arange(1, 1001) / 1000
    f = lambda x: np.cos((x + 0.008) / 1.008 * np.pi / 2) ** 2  # noqa: E731
    expect = f(t) / f(0.0)
    ok = cos.betas < 0.999  # the clip only acts at the very end
    np.testing.assert_allclose(cos.alpha_bars[ok], expect[ok], rtol=1e-9)
    for s in (lin, cos):
        assert np.all(np.diff(s.alpha_bars) < 0) and 0 < s.alpha_bars[-1] < 1e-4
        np.testing.assert_allclose(s.alpha_bars, np.cumprod(1 - s.betas), rtol=1e-12)
    with pytest.raises(ConfigError, match="schedule"):
        make_schedule("quadratic")
    with pytest.raises(ConfigError, match="num_steps"):
        make_schedule("linear", num_steps=1)
    # a shift divides every step's SNR by shift² (the clip at 0.999 only acts at the very end)
    for kind in ("linear", "cosine"):
        plain, shifted = make_schedule(kind), make_schedule(kind, shift=3.0)
        assert np.array_equal(make_schedule(kind, shift=1.0).betas, plain.betas)
        snr = lambda s: s.alpha_bars / (1 - s.alpha_bars)  # noqa: E731
        ok = np.cumsum(shifted.betas >= 0.999) == 0
        assert ok.sum() > 990
        np.testing.assert_allclose(snr(shifted)[ok], snr(plain)[ok] / 9.0, rtol=1e-9)
        np.testing.assert_allclose(shifted.alpha_bars, np.cumprod(1 - shifted.betas), rtol=1e-12)
    with pytest.raises(ConfigError, match="shift"):
        make_schedule("cosine", shift=0.0)


def test_q_sample_formula_batched():
    s = make_schedule("cosine", num_steps=100)
    key = jax.random.key(0)
    z0 = tangent_noise(key, (3, 5, 2), dtype=jnp.complex128)
    eps = tangent_noise(jax.random.key(1), (3, 5, 2), dtype=jnp.complex128)
    t = jnp.array([0, 50, 99])
    got = q_sample(s, z0, t, eps)
    z0, eps = np.asarray(z0), np.asarray(eps)
    for b in range(3):
        ab = s.alpha_bars[int(t[b])]
        np.testing.assert_allclose(
            got[b], np.sqrt(ab) * z0[b] + np.sqrt(1 - ab) * eps[b], rtol=1e-12
        )


def test_ddpm_step_is_the_posterior_mean_with_the_true_noise():
    """eq. 29–31: with ε̂ = ε, the DDPM mean equals μ̃(z_t, z_0) of q(z_{t-1} | z_t, z_0)."""
    s = make_schedule("linear", num_steps=200)
    z0 = tangent_noise(jax.random.key(2), (7, 3), dtype=jnp.complex128)
    eps = tangent_noise(jax.random.key(3), (7, 3), dtype=jnp.complex128)
    for t in (1, 17, 199):
        zt = q_sample(s, z0, jnp.array(t), eps)
        z0n, ztn = np.asarray(z0), np.asarray(zt)
        ab, ab_prev, beta, alpha = s.alpha_bars[t], s.alpha_bars[t - 1], s.betas[t], s.alphas[t]
        mu = (
            np.sqrt(ab_prev) * beta / (1 - ab) * z0n
            + np.sqrt(alpha) * (1 - ab_prev) / (1 - ab) * ztn
        )
        got = ddpm_step(s, zt, jnp.array(t), eps, jnp.zeros_like(zt))
        np.testing.assert_allclose(got, mu, rtol=1e-10, atol=1e-12)
        noise = jnp.ones_like(zt)
        sigma2 = beta * (1 - ab_prev) / (1 - ab)
        np.testing.assert_allclose(
            np.asarray(ddpm_step(s, zt, jnp.array(t), eps, noise) - got),
            np.sqrt(sigma2),
            rtol=1e-10,
        )


def _sample_in_10_of_60_steps(denoiser, s, method, *, key):
    """``method``'s samples of a (6, 2) complex128 field in 10 of the 60-step schedule ``s``."""
    zT, steps, _ = draw_sampling_noise(
        key, (6, 2), method=method, num_steps=10, diffusion_steps=60, dtype=jnp.complex128
    )
    return sample_from_noise(denoiser, s, zT, steps, method=method, num_steps=10)


@pytest.mark.parametrize("method", ["ddim", "ddpm"])
def test_oracle_denoiser_recovers_the_data(method):
    """A denoiser that knows z0 predicts ε exactly; DDIM (η=0) then lands on z0, and so does DDPM."""
    s = make_schedule("linear", num_steps=60)
    z0 = tangent_noise(jax.random.key(4), (6, 2), dtype=jnp.complex128)
    ab = jnp.asarray(s.alpha_bars).astype(jnp.complex128)  # strict promotion: complex coefficients

    def oracle(z, t):
        return (z - jnp.sqrt(ab[t]) * z0) / jnp.sqrt(1 - ab[t])

    out = _sample_in_10_of_60_steps(oracle, s, method, key=jax.random.key(5))
    np.testing.assert_allclose(out, z0, atol=1e-9)


@pytest.mark.parametrize("schedule", ["linear", "cosine"])
def test_v_prediction_reads_back_the_noise_and_splits_the_loss(schedule):
    """v = √ᾱ ε − √(1−ᾱ) z0 gives back ε exactly, and for any output v̂ the v-loss is the ε-loss plus
    the z0-loss of the estimates it implies: |v − v̂|² = |ε − ε̂|² + |z0 − ẑ0|²."""
    s = make_schedule(schedule, num_steps=100)
    z0 = tangent_noise(jax.random.key(10), (3, 9, 2), dtype=jnp.complex128)
    eps = tangent_noise(jax.random.key(11), (3, 9, 2), dtype=jnp.complex128)
    t = jnp.array([0, 37, 98])
    zt = q_sample(s, z0, t, eps)
    v = prediction_target(s, "v", z0, t, eps)
    np.testing.assert_allclose(epsilon_from_output(s, "v", zt, t, v), eps, atol=1e-12)
    np.testing.assert_array_equal(prediction_target(s, "epsilon", z0, t, eps), eps)
    np.testing.assert_array_equal(epsilon_from_output(s, "epsilon", zt, t, 2 * eps), 2 * eps)
    v_hat = v + tangent_noise(jax.random.key(12), v.shape, dtype=v.dtype)
    e_hat = epsilon_from_output(s, "v", zt, t, v_hat)
    ab = s.alpha_bars[np.asarray(t)][:, None, None]
    z0_hat = (np.asarray(zt) - np.sqrt(1 - ab) * np.asarray(e_hat)) / np.sqrt(ab)
    lhs = np.abs(np.asarray(v - v_hat)) ** 2
    rhs = np.abs(np.asarray(eps - e_hat)) ** 2 + np.abs(np.asarray(z0) - z0_hat) ** 2
    np.testing.assert_allclose(lhs, rhs, rtol=1e-9)
    with pytest.raises(ConfigError, match="prediction"):
        prediction_target(s, "x0", z0, t, eps)
    with pytest.raises(ConfigError, match="prediction"):
        epsilon_from_output(s, "score", zt, t, v)


@pytest.mark.parametrize("method", ["ddim", "ddpm"])
def test_v_oracle_through_the_conversion_recovers_the_data(method):
    """The samplers driven by a v-oracle (read back with epsilon_from_output) land on z0."""
    s = make_schedule("cosine", num_steps=60)
    z0 = tangent_noise(jax.random.key(13), (6, 2), dtype=jnp.complex128)
    ab = jnp.asarray(s.alpha_bars).astype(jnp.complex128)

    def v_oracle(z, t):
        eps = (z - jnp.sqrt(ab[t]) * z0) / jnp.sqrt(1 - ab[t])
        return epsilon_from_output(s, "v", z, t, prediction_target(s, "v", z0, t, eps))

    out = _sample_in_10_of_60_steps(v_oracle, s, method, key=jax.random.key(14))
    np.testing.assert_allclose(out, z0, atol=1e-8)


def _ddpm_gaussian_variance(s, v):
    """Exact output variance of ancestral DDPM on z0 ~ CN(0, v) with the exact denoiser (a loop over t)."""
    ab, abp = s.alpha_bars, np.concatenate([[1.0], s.alpha_bars[:-1]])
    var = 1.0
    for t in range(s.num_steps - 1, -1, -1):
        e = np.sqrt(1 - ab[t]) / (ab[t] * v + 1 - ab[t])
        a = (1 - s.betas[t] / np.sqrt(1 - ab[t]) * e) / np.sqrt(s.alphas[t])
        var = a * a * var + s.betas[t] * (1 - abp[t]) / (1 - ab[t])
    return var


def test_gaussian_data_with_the_exact_denoiser_gives_the_data_distribution():
    """z0 ~ CN(0, v): the optimal ε̂(z_t) = √(1-ᾱ) z_t / (ᾱ v + 1 - ᾱ). Ancestral sampling is then a
    linear recursion whose output variance a loop computes exactly; the sampler must match it, and
    with T = 1000 that variance is v to 1 % (eq. 11, 29–31)."""
    v = 4.0
    assert abs(_ddpm_gaussian_variance(make_schedule("linear", num_steps=1000), v) - v) < 0.01 * v
    s = make_schedule("linear", num_steps=100)
    expect = _ddpm_gaussian_variance(s, v)  # 3.76: coarse steps lose a little variance
    ab = jnp.asarray(s.alpha_bars).astype(jnp.complex128)  # strict promotion: complex coefficients

    def exact(z, t):
        return jnp.sqrt(1 - ab[t]) * z / (ab[t] * v + 1 - ab[t])

    draw = functools.partial(
        draw_sampling_noise, shape=(4000, 2), diffusion_steps=100, dtype=jnp.complex128
    )
    zT, steps, _ = draw(jax.random.key(6), method="ddpm", num_steps=0)
    out = sample_from_noise(exact, s, zT, steps, method="ddpm")
    power = float(jnp.mean(jnp.abs(out) ** 2))
    assert abs(power - expect) < 0.04 * expect, (
        power,
        expect,
    )  # 8000 samples: std of the estimate ~1.1 %
    assert abs(complex(jnp.mean(out**2))) < 0.1 * v  # circular: no preferred direction
    # DDIM with η=1 on a sub-sequence samples (nearly) the same law
    zT, steps, _ = draw(jax.random.key(7), method="ddim", num_steps=50)
    out = sample_from_noise(exact, s, zT, steps, method="ddim", num_steps=50, eta=1.0)
    assert abs(float(jnp.mean(jnp.abs(out) ** 2)) - v) < 0.15 * v


def test_ddim_step_interpolates_to_z0_estimate():
    s = make_schedule("linear", num_steps=100)
    z0 = tangent_noise(jax.random.key(8), (4, 1), dtype=jnp.complex128)
    e = tangent_noise(jax.random.key(9), (4, 1), dtype=jnp.complex128)
    zt = q_sample(s, z0, jnp.array(80), e)
    # same noise, deterministic: z_{t'} is exactly the forward process at t'
    np.testing.assert_allclose(
        ddim_step(s, zt, jnp.array(80), jnp.array(30), e, e),
        q_sample(s, z0, jnp.array(30), e),
        rtol=1e-10,
    )


def test_inpainting_keeps_the_known_latents_exactly():
    s = make_schedule("linear", num_steps=40)
    V, C = 30, 2
    z0 = tangent_noise(jax.random.key(10), (V, C), dtype=jnp.complex128)
    mask = jnp.arange(V) % 3 == 0
    for method in ("ddim", "ddpm"):
        zT, steps, known = draw_sampling_noise(
            jax.random.key(11),
            (V, C),
            method=method,
            num_steps=8,
            diffusion_steps=40,
            inpaint=True,
            dtype=jnp.complex128,
        )
        out = sample_from_noise(
            lambda z, t: 0.3 * z,
            s,
            zT,
            steps,
            method=method,
            num_steps=8,
            inpaint=Inpaint(z0, mask),
            inpaint_noise=known,
        )
        assert bool(jnp.all(out[mask] == z0[mask]))
        assert not bool(jnp.allclose(out[~mask], z0[~mask]))
    with pytest.raises(InputError, match="inpaint_noise"):
        sample_from_noise(lambda z, t: z, s, zT, steps, method="ddpm", inpaint=Inpaint(z0, mask))


def test_sampling_is_reproducible_with_a_fixed_key():
    s = make_schedule("cosine", num_steps=30)

    def run(key):
        zT, steps, _ = draw_sampling_noise(
            key, (9, 2), method="ddim", num_steps=5, diffusion_steps=30
        )
        return sample_from_noise(
            lambda z, t: jnp.tanh(z.real).astype(z.dtype) * 0.5,
            s,
            zT,
            steps,
            method="ddim",
            num_steps=5,
            eta=0.7,
        )

    a, b, c = run(jax.random.key(3)), run(jax.random.key(3)), run(jax.random.key(4))
    assert bool(jnp.all(a == b)) and not bool(jnp.allclose(a, c))


@pytest.mark.parametrize("prediction", ["epsilon", "v"])
def test_sampler_commutes_with_a_gauge_change_of_its_noise(prediction):
    """An equivariant denoiser (here: a per-vertex complex-linear map), read as ε or as v, and noise
    rotated by e^{-iα} give the sample rotated by e^{-iα}."""
    s = make_schedule("linear", num_steps=20)
    w = jnp.array([[0.3 + 0.1j, -0.2j], [0.05, 0.4 - 0.3j]])
    zT, steps, _ = draw_sampling_noise(
        jax.random.key(13),
        (11, 2),
        method="ddpm",
        num_steps=0,
        diffusion_steps=20,
        dtype=jnp.complex128,
    )
    turn = jnp.exp(-1j * jnp.linspace(0.0, 5.0, 11).astype(jnp.complex128))[:, None]

    def denoise(z, t):
        return epsilon_from_output(s, prediction, z, t, z @ w)

    a = sample_from_noise(denoise, s, zT, steps, method="ddpm")
    b = sample_from_noise(denoise, s, zT * turn, steps * turn, method="ddpm")
    np.testing.assert_allclose(b, a * turn, rtol=1e-12, atol=1e-13)
    assert float(jnp.max(jnp.abs(a))) > 0.1  # not a trivial (vanishing) sample


def test_latent_scale_and_loss():
    rng = np.random.default_rng(0)
    mu = (rng.standard_normal((50, 3)) + 1j * rng.standard_normal((50, 3))) * np.array(
        [0.1, 1.0, 7.0]
    )
    mask = np.arange(50) < 40
    sc = latent_scale(mu, mask)
    np.testing.assert_allclose((np.abs(mu[mask] * sc) ** 2).mean(0), 1.0, rtol=1e-12)
    with pytest.raises(InputError, match="not identically zero"):
        latent_scale(np.zeros((4, 2), complex))
    e = jnp.asarray(mu)
    assert float(epsilon_loss(e, e, jnp.asarray(mask))) == 0.0
    pad = jnp.where(jnp.asarray(mask)[:, None], 0, 100.0 + 0j)
    got = float(epsilon_loss(e + pad + 1.0, e, jnp.asarray(mask)))
    assert abs(got - 1.0) < 1e-12  # padded vertices (error 101) do not count


def test_argument_errors():
    s = make_schedule("linear", num_steps=10)
    z = jnp.zeros((3, 1), jnp.complex64)
    with pytest.raises(ConfigError, match="method"):
        sample_from_noise(lambda z, t: z, s, z, z[None], method="euler")
    with pytest.raises(InputError, match="step_noise"):
        sample_from_noise(lambda z, t: z, s, z, z[None], method="ddpm")
    with pytest.raises(ConfigError, match="sampling steps"):
        timestep_sequence(10, 11)


def test_the_cli_spells_out_the_predictions():
    from jmeshtex.cli._fldm import PREDICTIONS as CLI_PREDICTIONS
    from jmeshtex.fldm._diffusion import PREDICTIONS

    assert CLI_PREDICTIONS == PREDICTIONS

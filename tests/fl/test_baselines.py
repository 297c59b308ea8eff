"""The P1 codecs that bound FL-VAE reconstructions: exact on P1 data, above the flat colour on smooth."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jmeshtex import InputError, Mesh, metrics
from jmeshtex.data import grid
from jmeshtex.fl import Config, init, reconstruct
from jmeshtex.fl.core import p1_baselines, p1_interpolate, p1_least_squares
from jmeshtex.geometry import rasterize_uv


def _texels_of(v, f, size):
    """Texel points of a flat grid whose UVs are its xy positions."""
    texels = rasterize_uv(v[f][..., :2], size)
    return f[texels.face], texels.bary, texels


def test_least_squares_recovers_the_vertex_colours_of_a_p1_field():
    v, f = grid(4)
    colors = np.random.default_rng(0).random((len(v), 3))
    corners, bary, _ = _texels_of(v, f, 64)
    target = p1_interpolate(colors, corners, bary)
    fit = p1_least_squares(corners, bary, target, num_vertices=len(v))
    np.testing.assert_allclose(fit, colors, atol=1e-4)  # damping 1e-6: a relative O(ε) pull
    np.testing.assert_allclose(p1_interpolate(fit, corners, bary), target, atol=1e-4)


def test_least_squares_gives_untouched_vertices_the_mean_colour():
    corners = np.array([[0, 1, 2]] * 3)
    fit = p1_least_squares(corners, np.eye(3), np.array([[0.0], [1.0], [0.5]]), num_vertices=5)
    np.testing.assert_allclose(fit[:3, 0], [0.0, 1.0, 0.5], atol=1e-5)
    np.testing.assert_allclose(fit[3:, 0], 0.5, atol=1e-9)


def _sheet(texture, margin=0.0):
    v, f = grid(6)
    uv = margin + (1 - 2 * margin) * v[f][..., :2]
    return Mesh(v, f, uv=uv, texture=texture.astype(np.float32))


def _reconstruction(mesh, size):
    model = init(
        Config(features=8, num_heads=2, num_blocks=1, num_samples=4), key=jax.random.key(0)
    )
    return reconstruct(model, mesh, key=jax.random.key(1), size=size, lpips=False)


def test_the_oracle_is_exact_on_a_texture_that_is_p1_over_the_faces():
    # an affine colour field is linear over every face; bilinear texture lookups reproduce it
    # exactly away from the texture's border, so the UVs keep a margin of 10 % inside it
    size = 64
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    texture = np.stack([0.1 + 0.8 * x, 0.9 - 0.7 * y, 0.2 + 0.3 * x + 0.4 * y], -1)
    mesh = _sheet(texture, margin=0.1)
    r = _reconstruction(mesh, size)
    out = p1_baselines(mesh, r)
    for name in ("p1_oracle", "p1_fit"):
        err = np.abs(out[name] - r.target)[r.valid].max()
        assert err < 1e-4, (name, err)  # float32 texture; the fit's damping pulls by O(1e-6)
    flat = metrics.flat_baseline(r.target, mask=r.valid)
    assert np.abs(flat - r.target)[r.valid].max() > 0.2  # the test texture is far from flat


def test_the_oracle_and_the_fit_beat_the_flat_colour_on_a_smooth_texture():
    size = 64
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    texture = np.stack(
        [0.5 + 0.4 * np.sin(3 * x), 0.5 + 0.4 * np.cos(2 * y), 0.5 + 0.3 * np.sin(2 * (x + y))], -1
    )
    mesh = _sheet(texture)
    r = _reconstruction(mesh, size)
    out = p1_baselines(mesh, r)
    psnr = {k: float(metrics.psnr(a, r.target, mask=r.valid)) for k, a in out.items()}
    flat = float(
        metrics.psnr(metrics.flat_baseline(r.target, mask=r.valid), r.target, mask=r.valid)
    )
    assert psnr["p1_oracle"] > flat + 15, (psnr, flat)
    # the least-squares fit is the best P1 field in squared error, so at least the oracle's PSNR
    assert psnr["p1_fit"] >= psnr["p1_oracle"] - 1e-6, psnr


@pytest.mark.parametrize(
    "call, match",
    [
        (
            lambda: p1_interpolate(np.zeros((3, 3)), np.array([[0, 1, 3]]), np.ones((1, 3))),
            "lie in",
        ),
        (lambda: p1_interpolate(np.zeros((3, 3)), np.array([[0, 1]]), np.ones((1, 2))), "[N, 3]"),
        (
            lambda: p1_least_squares(
                np.array([[0, 1, 2]]), np.ones((1, 3)), np.ones((2, 3)), num_vertices=3
            ),
            "target must be",
        ),
        (
            lambda: p1_least_squares(
                np.zeros((0, 3), int), np.zeros((0, 3)), np.zeros((0, 3)), num_vertices=3
            ),
            "no points",
        ),
        (
            lambda: p1_least_squares(
                np.array([[0, 1, 2]]), np.ones((1, 3)), np.ones((1, 3)), num_vertices=3, damping=0
            ),
            "damping",
        ),
    ],
)
def test_bad_input_is_an_input_error(call, match):
    with pytest.raises(InputError, match=match):
        call()

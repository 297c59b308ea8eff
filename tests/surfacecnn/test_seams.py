"""Seamless frames and textures: frames continuous across UV seams, stripes where the frames say,
seam ratio of surface-CNN synthesis against UV-space 2D synthesis."""

import jax
import numpy as np
import pytest

from jmeshtex import ConfigError, InputError, Mesh
from jmeshtex.data import icosphere
from jmeshtex.geometry import tracer_geometry
from jmeshtex.metrics import load_vgg16, vgg_features
from jmeshtex.surfacecnn import Config, prepare_surface, synthesize, synthesize_uv, unwrap_uv
from jmeshtex.surfacecnn.core import (
    frame_seam_turn,
    gram_targets,
    opposite_source,
    seam_pairs,
    seam_ratio,
    texel_taps,
    texture_atlas,
    vgg_features_centre_padded,
)

LAYERS = ("relu1_1", "relu1_2", "pool1", "relu2_1")
#: frames may turn across a seam only by the change of projection plane between the two faces
TURN_BOUND = np.radians(1.0)


@pytest.fixture(scope="module")
def sphere():
    v, f = icosphere(3)
    return Mesh(v, f, uv=unwrap_uv(v, f))


def _stripes(n=32, period=8, axis=1):
    s = 0.5 + 0.5 * np.sin(2 * np.pi * np.arange(n) / period)
    img = np.repeat(s[None, :], n, 0) if axis == 1 else np.repeat(s[:, None], n, 1)
    return np.repeat(img[..., None], 3, 2)


def _tube(m=32, k=12, radius=0.5, height=1.5):
    """An open cylinder around z, outward normals."""
    a = 2 * np.pi * np.arange(m) / m
    z = np.linspace(0.0, height, k)
    v = np.stack(
        [np.tile(radius * np.cos(a), k), np.tile(radius * np.sin(a), k), np.repeat(z, m)], 1
    )
    faces = []
    for r in range(k - 1):
        for c in range(m):
            p, q = r * m + c, r * m + (c + 1) % m
            faces += [[p, q, q + m], [p, q + m, p + m]]
    return v, np.array(faces)


@pytest.mark.parametrize("frames", ["global", "smooth"])
def test_surface_frames_are_continuous_across_every_seam_and_uv_frames_are_not(sphere, frames):
    turn = frame_seam_turn(sphere, frames=frames)
    assert turn.size > 50  # xatlas cuts the sphere into charts
    assert turn.max() < TURN_BOUND
    uv_turn = frame_seam_turn(sphere, frames="uv")
    assert uv_turn.max() > TURN_BOUND and np.median(uv_turn) > 10 * TURN_BOUND


@pytest.mark.parametrize("frames", ["global", "smooth", "uv"])
def test_texel_frames_turn_across_seams_as_inside_charts(sphere, frames):
    v, f = sphere
    atlas = texture_atlas(v, f, sphere.uv, size=64, frames=frames)
    seam, inner = seam_pairs(atlas, texel_taps(v, f, atlas).nearest, tracer_geometry(v, f))
    t = atlas.frame[:, 0]

    def angle(pairs):
        return np.degrees(
            np.arccos(np.clip(np.sum(t[pairs[:, 0]] * t[pairs[:, 1]], axis=1), -1, 1))
        )

    # texels one step apart: world tangents differ by the surface's turn over a texel (~4° here),
    # across a seam as inside a chart for surface frames; UV frames jump by the charts' layouts
    across, within = np.median(angle(seam)), np.median(angle(inner))
    if frames == "uv":
        assert across > 10 * within
    else:
        assert across < 1.5 * within


def test_striped_exemplar_on_a_cylinder_follows_the_frame_field():
    v, f = _tube()
    mesh = Mesh(v, f, uv=unwrap_uv(v, f))
    config = Config(size=64, steps=80, layers=LAYERS, frame_vector=(0.0, 0.0, 1.0))
    surface = prepare_surface(
        mesh, size=64, levels=1, boundary=config.boundary, frame_vector=(0.0, 0.0, 1.0)
    )
    # the frame field says: t (the exemplar's growing column) along the axis
    assert np.abs(surface.atlas.frame[:, 0, 2]).min() > 0.999
    taps = surface.pyramid.nearest[0]
    a = np.repeat(np.arange(surface.atlas.num_texels), 4)
    b = np.asarray(taps.index)[:, [1, 3, 5, 7], 0].ravel()
    d = surface.atlas.point[b] - surface.atlas.point[a]
    along = np.abs(d[:, 2]) > 0.9 * np.linalg.norm(d, axis=1)
    around = np.abs(d[:, 2]) < 0.1 * np.linalg.norm(d, axis=1)
    ratios = []
    for axis in (1, 0):  # colour varying along columns (→ along t), then along rows (→ along d)
        r = synthesize(
            mesh,
            _stripes(axis=axis),
            config,
            key=jax.random.key(0),
            surface=surface,
            progress=False,
        )
        c = r.colors.astype(np.float64)
        diff = np.linalg.norm(c[a] - c[b], axis=1)
        ratios.append(diff[along].mean() / diff[around].mean())
    # stripes across the axis (rings) vary along z; the turned exemplar gives stripes along the axis
    assert ratios[0] > 2.0, ratios
    assert ratios[1] < 0.5, ratios


def test_surface_synthesis_hides_seams_that_uv_space_synthesis_shows(sphere):
    v, f = sphere
    config = Config(size=64, steps=80, layers=LAYERS)
    surface = prepare_surface(sphere, size=64, levels=1, boundary=config.boundary)
    g = tracer_geometry(v, f)
    ex = _stripes()
    ours = synthesize(sphere, ex, config, key=jax.random.key(1), surface=surface, progress=False)
    base = synthesize_uv(sphere, ex, config, key=jax.random.key(1), surface=surface, progress=False)
    r_ours = seam_ratio(ours.colors, surface.atlas, surface.pyramid.nearest[0], geometry=g)
    r_base = seam_ratio(base.colors, surface.atlas, surface.pyramid.nearest[0], geometry=g)
    assert base.final_loss < base.losses[0] and ours.final_loss < ours.losses[0]
    assert r_ours["ratio"] < 1.7 < r_base["ratio"], (r_ours, r_base)


def test_seam_ratio_needs_seams(sphere):
    from jmeshtex.data import grid

    v, f = grid(2)
    atlas = texture_atlas(v, f, v[f][..., :2], size=8)
    with pytest.raises(InputError, match="single chart"):
        seam_ratio(
            np.zeros((64, 3)),
            atlas,
            texel_taps(v, f, atlas).nearest,
            geometry=tracer_geometry(v, f),
        )


def test_opposite_boundary_rule_reads_the_mirrored_tap():
    from jmeshtex.data import grid

    v, f = grid(2)
    atlas = texture_atlas(v, f, v[f][..., :2], size=4)
    taps = texel_taps(v, f, atlas, boundary="opposite")
    # texel 0 (top-left corner): taps 0, 1, 2, 3, 6 leave the sheet; 0 → 8, 1 → 7, 3 → 5; 2 and 6 read
    # each other's mirror, which failed too, so they read the centre
    idx = taps.nearest.index[0, :, 0].tolist()
    assert idx == [5, 4, 0, 1, 0, 1, 0, 4, 5]
    assert (taps.nearest.weight[0] == 1).all()
    assert opposite_source(taps.stopped)[0].tolist() == [8, 7, 4, 5, 4, 5, 4, 7, 8]


@pytest.mark.parametrize("shape", [(5, 6), (1, 4), (3, 1), (1, 1)])
def test_centre_padding_matches_a_direct_computation(rng, shape):
    H, W = shape
    w = load_vgg16()
    img = rng.uniform(size=(H, W, 3))
    got = np.asarray(
        vgg_features_centre_padded(jax.numpy.asarray(img), w, layers=("conv1_1",))["conv1_1"]
    )
    x = np.asarray(w.preprocess(jax.numpy.asarray(img)))
    kernel, bias = (np.asarray(a, np.float64) for a in w.convs[0])
    want = np.zeros((H, W, 64))
    for i in range(H):
        for j in range(W):
            acc = np.array(bias)
            for ky in range(3):
                for kx in range(3):
                    r, c = i + ky - 1, j + kx - 1
                    src = x[r, c] if 0 <= r < H and 0 <= c < W else x[i, j]
                    acc = acc + src @ kernel[ky, kx]
            want[i, j] = acc
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10)
    # interior pixels are the SAME convolution's
    same = np.asarray(
        vgg_features(jax.numpy.asarray(img[None]), w, layers=("conv1_1",))["conv1_1"][0]
    )
    np.testing.assert_allclose(got[1:-1, 1:-1], same[1:-1, 1:-1], rtol=1e-10, atol=1e-10)
    g = gram_targets(img, w, layers=("relu1_1",), padding="centre")
    assert g["relu1_1"].shape == (64, 64)


def test_config_rules_for_frames_and_networks():
    with pytest.raises(ConfigError, match="frames"):
        Config(frames="uvw")
    with pytest.raises(ConfigError, match="weights_path"):
        Config(network="vgg19")
    with pytest.raises(ConfigError, match="frame_vector"):
        Config(frame_vector=(0.0, 0.0, 0.0))
    assert Config().boundary == "opposite" and Config().frames == "global"

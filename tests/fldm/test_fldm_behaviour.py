"""FLDM behaviours that can fail, each against a baseline (issue 19, "Tests that can fail"):

- inpainting: the kept region is exact and the colour discontinuity across the mask boundary is
  below that of the permuted baseline (the true colours shuffled over the generated region);
- labels: trained on a two-label sphere (stripes where label 1, a uniform colour where label 0),
  samples have more intensity variation where the label map says "stripes" than where it says
  "uniform", for the training-like map and for a map the model never saw (so the labels, not the
  position, decide);
- scale (§6.6): sampled on a coarser remesh of the same surface, the texture's autocorrelation
  length in world units grows (the exemplar's own stays put: the metric measures the texture);
- generative transfer (§6.6): sampled on a triaxial ellipsoid, the samples beat a flat colour and
  the shuffled training latents on the learning check's stripe statistic (VGG Gram distance).

Each uses the learning check's tiny configuration (``fldm.Config.demo()``: 4 copies × 500
vertices, 300 steps, T = 200) with the analytic stripe codec; the unconditional model is trained
once per session (``striped_model`` in ``tests/fldm/conftest.py``), the labelled one here.
Intensities are decoded with :func:`stripe_decoder`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex import Mesh, fldm
from jmeshtex.data import (
    icosphere,
    intensity_to_rgb,
    stripe_decoder,
    stripe_encoder,
    stripe_intensity,
)
from jmeshtex.geometry import remesh
from jmeshtex.metrics import gram_distance, load_vgg16, permuted_baseline
from jmeshtex.testing import render_intensity_views as render_views
from tests.fldm.conftest import DATA_KEY, TRAIN_KEY

SAMPLE_KEY = jax.random.key(5)


def _edges(faces: np.ndarray) -> np.ndarray:
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return np.unique(np.sort(e, 1), axis=0)


def boundary_jump(mesh: Mesh, s: np.ndarray, mask: np.ndarray) -> float:
    """Mean ``|s_u − s_v|`` over the edges with one end kept and the other generated."""
    e = _edges(mesh.faces)
    b = mask[e[:, 0]] != mask[e[:, 1]]
    return float(np.mean(np.abs(s[e[b, 0]] - s[e[b, 1]])))


def correlation_length(mesh: Mesh, s: np.ndarray, *, bins: int = 40) -> float:
    """World distance at which the intensity's autocorrelation first falls to ½.

    ``C(r) = E[(s_u − s̄)(s_v − s̄) | ‖x_u − x_v‖ ∈ bin(r)] / Var s`` over all vertex pairs ``u ≠ v``
    (chord distance, bins of 0.05 on the unit sphere; empty bins skipped, ``C(0) = 1``), linearly
    interpolated at the first crossing of ½.
    """
    x = mesh.vertices
    s = s - s.mean()
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    off = ~np.eye(len(x), dtype=bool)
    prod = (s[:, None] * s[None])[off]
    edges = np.linspace(0.0, 2.0, bins + 1)
    idx = np.clip(np.digitize(d[off], edges) - 1, 0, bins - 1)
    count = np.bincount(idx, minlength=bins)
    c = (
        np.bincount(idx, prod, minlength=bins)
        / np.maximum(count, 1)
        / max(float(np.mean(s * s)), 1e-12)
    )
    r = 0.5 * (edges[1:] + edges[:-1])
    keep = count > 0
    r, c = np.concatenate([[0.0], r[keep]]), np.concatenate([[1.0], c[keep]])
    i = int(np.nonzero(c < 0.5)[0][0])
    t = (c[i - 1] - 0.5) / (c[i - 1] - c[i])
    return float(r[i - 1] + t * (r[i] - r[i - 1]))


def _train(exemplar: Mesh, cfg, labels=None):
    data = fldm.build_dataset(
        exemplar, cfg, encode=stripe_encoder, key=DATA_KEY, labels=labels, progress=False
    )
    return fldm.train(data, cfg, key=TRAIN_KEY, progress=False).model


@pytest.fixture(scope="module")
def exemplar(striped_exemplar) -> Mesh:
    return striped_exemplar


@pytest.fixture(scope="module")
def model(striped_model) -> fldm.Model:
    """The tiny striped-sphere model (``tests/fldm/conftest.py``: trained once per session)."""
    return striped_model


@pytest.mark.slow
def test_inpainting_keeps_the_known_region_and_continues_it_across_the_boundary(exemplar, model):
    """Measured (DDPM, T = 200, upper half kept, 500-vertex remesh): boundary jump of the trained
    model's inpaintings 0.27 / 0.28 / 0.29 (3 keys) against 0.54 / 0.43 / 0.47 for the permuted
    baseline (true colours shuffled over the generated half) and 0.47 for the exemplar's own
    stripes (they change fastest at the equator); the samples' own interior edge jump 0.20-0.21.
    A mask-conditioned model (``mask_conditioning=True``, same training) gave 0.24 / 0.25 / 0.24."""
    mesh = remesh(exemplar, n_vertices=500, key=jax.random.key(77))
    known = stripe_encoder(mesh)
    mask = mesh.vertices[:, 2] > 0
    z = fldm.inpaint(model, mesh, known, mask, key=SAMPLE_KEY, num_samples=2).latents  # DDPM, all T
    np.testing.assert_allclose(
        z[:, mask], np.broadcast_to(known[mask], z[:, mask].shape), rtol=1e-6, atol=1e-6
    )
    truth = stripe_decoder(known)
    permuted = [
        boundary_jump(
            mesh, permuted_baseline(truth[:, None], key=jax.random.key(i), mask=~mask)[:, 0], mask
        )
        for i in range(3)
    ]
    jumps = [boundary_jump(mesh, stripe_decoder(zz), mask) for zz in z]
    print({"inpainted": np.round(jumps, 3).tolist(), "permuted": np.round(permuted, 3).tolist()})
    assert max(jumps) < 0.8 * np.mean(permuted), (jumps, permuted)


def _two_label_sphere(exemplar: Mesh) -> tuple[Mesh, np.ndarray]:
    """Stripes where ``z > 0`` (label 1), the uniform intensity ½ where ``z ≤ 0`` (label 0)."""
    v = exemplar.vertices
    s = np.where(v[:, 2] > 0, stripe_intensity(v), 0.5)
    return Mesh(v, exemplar.faces, vertex_colors=intensity_to_rgb(s).astype(np.float32)), (
        v[:, 2] > 0
    ).astype(np.int64)


def _std_ratios(model, mesh, region, labels=None, n=2):
    """``std(s | region) / std(s | not region)`` of each of ``n`` samples (DDIM 25)."""
    z = fldm.sample(
        model, mesh, key=jax.random.key(3), num_samples=n, steps=25, labels=labels
    ).latents
    return [
        float(np.std(stripe_decoder(zz)[region]) / np.std(stripe_decoder(zz)[~region])) for zz in z
    ]


@pytest.mark.slow
def test_labels_decide_where_the_stripes_go(exemplar, model):
    """Per-region standard deviation of the decoded intensity, label-1 ("stripes") region over
    label-0 ("uniform") region, for the training-like map (``z > 0``) and a map the model never saw
    (``x > 0``), against the same ratio for the unconditional model's samples on the same regions
    (the baseline: no labels, no reason for the regions to differ). Measured, in this test (x64
    on), three runs of the same keys (the trained weights differ between processes in round-off,
    which 300 steps and the sampler amplify): z > 0 1.60 / 1.94, 2.07 / 2.55, 2.38 / 2.36; x > 0
    1.28 / 1.31, 1.94 / 1.69, 1.91 / 1.58; unconditional 0.94-1.16 in the same runs. A separate run without x64 (its trained weights
    differ in round-off, 3 samples): z > 0 0.23 / 0.22 / 0.20 against 0.11 / 0.10 / 0.12
    (ratios 1.8-2.2), x > 0 0.22 / 0.20 / 0.24 against 0.11 / 0.11 / 0.11; the unconditional
    model: 1.01-1.18 (z > 0) and 0.83-1.09 (x > 0), 4 samples; the exemplar: 0.35 against 0."""
    colored, labels = _two_label_sphere(exemplar)
    cfg = fldm.Config.demo(num_labels=2)
    labelled = _train(colored, cfg, labels=labels)
    mesh = remesh(exemplar, n_vertices=500, key=jax.random.key(77))
    ratios, baseline = {}, {}
    for name, region in (("z>0", mesh.vertices[:, 2] > 0), ("x>0", mesh.vertices[:, 0] > 0)):
        ratios[name] = _std_ratios(labelled, mesh, region, labels=region.astype(np.int64))
        baseline[name] = _std_ratios(model, mesh, region)
    print({"labelled": ratios, "unconditional": baseline})
    for name in ratios:
        assert min(ratios[name]) > 1.2, (name, ratios, baseline)
        assert np.mean(ratios[name]) > max(baseline[name]) + 0.1, (name, ratios, baseline)


@pytest.mark.slow
def test_a_coarser_remesh_gives_a_larger_texture(exemplar, model):
    """§6.6: the filters see distances in units of the target's mean edge length, so on a mesh with
    4× fewer vertices the texture should be about 2× larger in world units. Measured (3 samples
    each, DDIM 25): autocorrelation length 0.126 / 0.124 / 0.128 on 1500 vertices, 0.228 / 0.228 /
    0.205 on 500 (the training resolution), 0.331 / 0.302 / 0.332 on 250; the exemplar's stripes on
    the same meshes 0.216 / 0.208 / 0.220 (fixed in world units, as they should be). Single samples
    spread: with round 28's field-convolution gradients (the same maths, other round-off, so other
    trained weights) three samples gave 0.152 / 0.162 / 0.024 on 1000 vertices and 0.218 / 0.344 /
    0.330 on 250 (means 0.113 / 0.297), where the first two of each failed the former per-sample
    bound (0.218 against 1.4 x 0.162); so the factor is asserted on the means of three samples, and
    every coarse sample must still be larger than every fine one."""
    lengths, truth = {}, {}
    for n in (1000, 250):
        mesh = remesh(exemplar, n_vertices=n, key=jax.random.key(n))
        z = fldm.sample(model, mesh, key=SAMPLE_KEY, num_samples=3, steps=25).latents
        lengths[n] = [correlation_length(mesh, stripe_decoder(zz)) for zz in z]
        truth[n] = correlation_length(mesh, stripe_intensity(mesh.vertices))
    print({"samples": lengths, "exemplar": truth})
    assert abs(truth[250] / truth[1000] - 1) < 0.15  # the metric sees the texture, not the mesh
    assert np.mean(lengths[250]) > 1.4 * np.mean(lengths[1000]), lengths  # √4 = 2 expected
    assert min(lengths[250]) > max(lengths[1000]), lengths


#: semi-axes of the transfer target, a triaxial ellipsoid (its bounding sphere is the unit sphere's,
#: so renders frame it at the exemplar's scale)
ELLIPSOID_AXES = (1.0, 0.8, 0.9)


def _area(mesh: Mesh) -> float:
    v, f = mesh.vertices, mesh.faces
    return float(
        0.5
        * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1).sum()
    )


def transfer_target(train_vertices: int) -> Mesh:
    """A remeshed triaxial ellipsoid with the training copies' mean edge length (vertex count
    ``train_vertices`` × area ratio), so the texture keeps its world scale (§6.6)."""
    v, f = icosphere(4)
    ellipsoid = Mesh(v * np.asarray(ELLIPSOID_AXES), f, name="ellipsoid")
    n = int(round(train_vertices * _area(ellipsoid) / _area(Mesh(v, f))))
    return remesh(ellipsoid, n_vertices=n, key=jax.random.key(21))


def transfer_grams(model: fldm.Model, data: fldm.Dataset, *, n: int = 2) -> dict:
    """The learning check's stripe statistic on the transfer target: the mean VGG Gram distance of
    central-crop renders to the exemplar's stripes painted on the same target (``stripe_intensity``
    of its vertices), for ``n`` samples of ``model`` (DDIM 25), a flat colour (the training copy's
    mean intensity) and the training latents shuffled onto the target's vertices (3 draws of a random
    subset of copy 0's latents: the right marginal, no spatial structure)."""
    target = transfer_target(data.meshes[0].num_vertices)
    weights = load_vgg16()
    ref = render_views(target, stripe_intensity(target.vertices), size=96, crop=True)

    def gram(s):
        img = render_views(target, s, size=96, crop=True)
        return float(
            np.mean(np.asarray(gram_distance(jnp.asarray(img), jnp.asarray(ref), weights=weights)))
        )

    z_copy = data.latents[0, : data.meshes[0].num_vertices]
    rng = np.random.default_rng(0)
    z = fldm.sample(model, target, key=SAMPLE_KEY, num_samples=n, steps=25).latents
    return {
        "vertices": target.num_vertices,
        "samples": [gram(stripe_decoder(zz)) for zz in z],
        "flat": gram(np.full(target.num_vertices, stripe_decoder(z_copy).mean())),
        "shuffled": [
            gram(
                stripe_decoder(z_copy[rng.choice(len(z_copy), target.num_vertices, replace=False)])
            )
            for _ in range(3)
        ],
    }


@pytest.mark.slow
def test_generative_transfer_to_an_ellipsoid_keeps_the_stripe_statistics(striped_data, model):
    """Generative transfer (§6.6): the model trained on copies of the striped sphere samples on a
    triaxial ellipsoid (another surface, tessellation and vertex count: 404 vertices at the copies'
    edge length) whose samples must be closer to the exemplar's stripes (painted on the ellipsoid)
    than a flat colour and than the shuffled training latents, by a margin. Measured (Gram
    distance, 2 samples, x64 on): trained 3.70 / 3.10, flat 7.33, shuffled 9.66 / 10.61 / 11.32;
    the untrained weights the training started from (``fldm.init`` with the same keys, checked by
    hand through :func:`transfer_grams`): 8.07 / 8.06, so the test fails for them (above the flat
    colour itself, let alone 0.75 of it)."""
    g = transfer_grams(model, striped_data)
    print(g)
    assert max(g["samples"]) < 0.75 * g["flat"], g
    assert max(g["samples"]) < 0.75 * min(g["shuffled"]), g

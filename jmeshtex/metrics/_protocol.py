"""The multi-view evaluation protocol every method reports: one camera rig, one renderer, the same
metrics, and the baselines that bound them (flat colour, permuted colours, the exemplar itself).

View level (:func:`evaluate_images`): SIFID-style Fréchet distance and Gram distance of VGG-16
features (one VGG pass serves both), LPIPS, PSNR and DSSIM, masked to the object, averaged over
views. Mesh level (:func:`evaluate_views`, :func:`baseline_table`): the colouring rendered from the
standard rig (:class:`Protocol`: 8 azimuths × 2 elevations, 256² per view) with
:func:`jmeshtex.render.render_views`, compared with renders of a reference colouring from the same
views or with a 2D exemplar.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._random import check_key, host_rng
from .._types import ArrayLike, Float
from ._baselines import flat_baseline, permuted_baseline
from ._image import dssim, psnr
from ._perceptual import lpips
from ._sifid import SIFID_LAYERS, as_float_images, as_masks, host_stats, sifid_from_stats
from ._vgg import VGGWeights
from ._vgg_load import load_vgg16

GRAM_LAYERS = ("relu1_1", "relu2_1", "relu3_1", "relu4_1")
"""The layers of the protocol's Gram distance (those of :func:`gram_distance`'s default)."""

DISTRIBUTION_METRICS = ("sifid", "gram")
"""Metrics that compare feature distributions: valid between images of different sizes and views."""

RECONSTRUCTION_METRICS = ("lpips", "psnr", "dssim")
"""Metrics that compare two images pixel by pixel (same view, same size)."""

_CHUNK = 4  # views per VGG call: bounds memory at 256² (16 views at once need ~1 GB of activations)
_lpips_jit = jax.jit(lpips)


def _choose_metrics(metrics, per_view: bool) -> tuple[str, ...]:
    known = DISTRIBUTION_METRICS + RECONSTRUCTION_METRICS
    if metrics is None:
        return known if per_view else DISTRIBUTION_METRICS
    metrics = tuple(metrics)
    bad = [m for m in metrics if m not in known]
    if bad or not metrics:
        raise InputError(
            f"unknown metrics {bad}; choose from {known}" if bad else "no metric requested"
        )
    if not per_view and any(m in RECONSTRUCTION_METRICS for m in metrics):
        raise InputError(
            f"{RECONSTRUCTION_METRICS} compare views pixel by pixel: pass one reference image per "
            "view, not a single exemplar"
        )
    return metrics


def _chunked_stats(
    images: np.ndarray, masks: np.ndarray, weights: VGGWeights, layers, name: str
) -> dict:
    """:func:`host_stats` over fixed-size chunks of images (the last padded), concatenated."""
    parts = []
    n = len(images)
    for start in range(0, n, _CHUNK):
        idx = (
            np.minimum(np.arange(start, start + _CHUNK), n - 1)
            if n > _CHUNK
            else np.arange(start, n)
        )
        parts.append(
            (host_stats(images[idx], masks[idx], weights, layers, name), min(_CHUNK, n - start))
        )
    return {
        layer: tuple(np.concatenate([p[layer][k][:keep] for p, keep in parts]) for k in range(4))
        for layer in layers
    }


def evaluate_images(
    results: Float[ArrayLike, "N H W 3"],
    references: Float[ArrayLike, "N H W 3"] | Float[ArrayLike, "H2 W2 3"],
    *,
    masks: Float[ArrayLike, "N H W"] | None = None,
    metrics: Sequence[str] | None = None,
    weights: VGGWeights | None = None,
    sifid_layers: tuple[str, ...] = SIFID_LAYERS,
    gram_layers: tuple[str, ...] = GRAM_LAYERS,
) -> dict[str, float]:
    """The protocol's metrics between result views and reference views, averaged over views.

    For each view ``i`` (lower is better except PSNR):

    - ``sifid``: :func:`sifid` of result ``i`` against reference ``i`` (VGG-16 features; *not*
      comparable in value with the Inception SIFID of Sin3DM / FLDM);
    - ``gram``: :func:`gram_distance`, ``Σ_l mean((G_l − G_l^ref)²)`` with masked Gram matrices
      ``G = Σ_p w_p f_p f_pᵀ / Σ_p w_p`` (equal to :func:`gram_distance` without a mask);
    - ``lpips``: :func:`lpips` with the mask; ``psnr`` / ``dssim``: :func:`psnr` / :func:`dssim` over
      the pixels where the mask is ≥ ½.

    With one ``[H2, W2, 3]`` exemplar as ``references`` every view is compared with it; only the
    distribution metrics (``sifid``, ``gram``) apply, and the mask applies to the results alone.
    One VGG pass per image serves both distribution metrics.

    Args:
      results: ``[N, H, W, 3]`` views, uint8 or float in [0, 1].
      references: ``[N, H, W, 3]`` reference views (same cameras), or one ``[H2, W2, 3]`` exemplar.
      masks: ``[N, H, W]`` pixel weights in [0, 1] (e.g. a render's coverage alpha); default all.
      metrics: names to compute (default: all that apply).
      weights: the VGG (default :func:`load_vgg16`).
      sifid_layers, gram_layers: VGG activations of the two distribution metrics.

    Returns:
      ``{metric: mean over views}`` (Python floats) plus ``"views": N``.

    Raises:
      InputError: shapes that do not match, unknown metrics, reconstruction metrics against a single
        exemplar, masks too small for the VGG layers.

    Example:
      >>> rng = np.random.default_rng(0)
      >>> x = rng.random((2, 32, 32, 3))
      >>> out = evaluate_images(x, x)
      >>> sorted(out), round(out["sifid"], 6), out["psnr"]
      (['dssim', 'gram', 'lpips', 'psnr', 'sifid', 'views'], 0.0, inf)
    """
    weights = load_vgg16() if weights is None else weights
    a = as_float_images(results, "evaluate_images", batched=True)
    per_view = np.ndim(references) == 4
    b = as_float_images(references, "evaluate_images", batched=per_view)
    b = (b if per_view else b[None]).astype(a.dtype)
    if per_view and b.shape != a.shape:
        raise InputError(
            f"evaluate_images: references must match results {a.shape}, got {b.shape} (or pass one "
            "[H, W, 3] exemplar)"
        )
    chosen = _choose_metrics(metrics, per_view)
    n = len(a)
    m = as_masks(masks, a.shape[:3], "evaluate_images", a.dtype)
    mb = m if per_view else np.ones(b.shape[:3], a.dtype)
    out: dict[str, float] = {}
    dist = [x for x in chosen if x in DISTRIBUTION_METRICS]
    if dist:
        layers = tuple(
            dict.fromkeys(
                (sifid_layers if "sifid" in dist else ()) + (gram_layers if "gram" in dist else ())
            )
        )
        sa = _chunked_stats(a, m, weights, layers, "evaluate_images")
        sb = (
            sa
            if (per_view and np.array_equal(a, b))
            else _chunked_stats(b, mb, weights, layers, "evaluate_images")
        )
        ref = (lambda i: i) if per_view else (lambda i: 0)
        if "sifid" in dist:
            out["sifid"] = float(
                np.mean([sifid_from_stats(sa, sb, sifid_layers, i, ref(i)) for i in range(n)])
            )
        if "gram" in dist:
            out["gram"] = float(
                np.mean(
                    [
                        sum(np.mean((sa[L][3][i] - sb[L][3][ref(i)]) ** 2) for L in gram_layers)
                        for i in range(n)
                    ]
                )
            )
    if "lpips" in chosen:
        kw = {} if masks is None else {"mask": jnp.asarray(m)}
        d = [
            np.asarray(
                _lpips_jit(
                    jnp.asarray(a[s : s + _CHUNK]),
                    jnp.asarray(b[s : s + _CHUNK]),
                    weights=weights,
                    **({k: v[s : s + _CHUNK] for k, v in kw.items()}),
                )
            )
            for s in range(0, n, _CHUNK)
        ]
        out["lpips"] = float(np.mean(np.concatenate(d)))
    pixel_masks = m >= 0.5
    if "psnr" in chosen:
        out["psnr"] = float(np.mean([psnr(a[i], b[i], mask=pixel_masks[i]) for i in range(n)]))
    if "dssim" in chosen:
        out["dssim"] = float(np.mean([dssim(a[i], b[i], mask=pixel_masks[i]) for i in range(n)]))
    out["views"] = n
    return out


@dataclasses.dataclass(frozen=True)
class Protocol:
    """The standard evaluation rig: which views, how large, which way is up.

    Every method's benchmark uses the default, so its numbers are comparable; change ``up`` for
    Y-up meshes (most OBJ files).

    Attributes:
      azimuths: views per elevation, evenly spaced (or a list of azimuths in degrees).
      elevations: camera elevations in degrees.
      size: pixels per side of each (square) view.
      up: world up axis (``"x"|"y"|"z"|"-x"|"-y"|"-z"``).
      supersample: antialiasing samples per pixel side.

    Example:
      >>> Protocol().views
      16
    """

    azimuths: int | tuple[float, ...] = 8
    elevations: tuple[float, ...] = (20.0, -10.0)
    size: int = 256
    up: str = "z"
    supersample: int = 2

    @property
    def views(self) -> int:
        """The number of views of the rig."""
        n_az = self.azimuths if isinstance(self.azimuths, int) else len(self.azimuths)
        return n_az * len(self.elevations)

    def cameras(self, mesh) -> list:
        """The rig framed on ``mesh`` (:func:`jmeshtex.render.orbit_cameras`)."""
        from .. import render

        return render.orbit_cameras(
            mesh,
            azimuths=self.azimuths,
            elevations=self.elevations,
            up=self.up,
            size=(self.size, self.size),
        )

    def angles(self) -> list[tuple[float, float]]:
        """``(elevation, azimuth)`` of every view, elevation-major (as :meth:`cameras`)."""
        az = (
            [360.0 * k / self.azimuths for k in range(self.azimuths)]
            if isinstance(self.azimuths, int)
            else list(self.azimuths)
        )
        return [(float(e), float(a)) for e in self.elevations for a in az]


def protocol_views(
    mesh: Mesh | tuple,
    *,
    cameras: Sequence | None = None,
    protocol: Protocol | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Render a colouring from the protocol's rig: the views and the object's coverage masks.

    Renders with :func:`jmeshtex.render.render_views` (white background) from ``cameras`` or
    ``protocol.cameras(mesh)``; the masks are the coverage alpha of one transparent render of the
    same geometry.

    Args:
      mesh: the colouring, a :class:`~jmeshtex.Mesh` with ``vertex_colors`` ``[V, 3]`` in [0, 1]
        or ``uv`` ``[F, 3, 2]`` with ``texture`` ``[H, W, 3]`` (a bare ``(vertices, faces)``
        pair renders grey).
      cameras: :class:`jmeshtex.render.Camera` list (default: the protocol's rig).
      protocol: the rig (default :class:`Protocol`).

    Returns:
      ``(images [N, H, W, 3] uint8, masks [N, H, W] float32 in [0, 1])``.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> rig = Protocol(azimuths=2, elevations=(0.0,), size=32)
      >>> img, mask = protocol_views(icosphere(2), protocol=rig)
      >>> img.shape, mask.shape, bool(mask[:, 16, 16].min() == 1.0 and mask[:, 0, 0].max() == 0.0)
      ((2, 32, 32, 3), (2, 32, 32), True)
    """
    from .. import render

    mesh = as_mesh(mesh)
    protocol = Protocol() if protocol is None else protocol
    black = Mesh(mesh.vertices, mesh.faces, vertex_colors=np.zeros((mesh.num_vertices, 3)))
    render_views = getattr(render, "render_views", None)
    if render_views is None:  # the matplotlib renderer: one call per (elevation, azimuth)
        if cameras is not None:
            raise InputError(
                "protocol_views: this jmeshtex.render has no render_views; cameras cannot be used"
            )
        size = (protocol.size, protocol.size)
        views = [render.render_mesh(mesh, view=va, size=size) for va in protocol.angles()]
        cover = [render.render_mesh(black, view=va, size=size) for va in protocol.angles()]
        masks = np.stack([(c.mean(-1) < 128).astype(np.float32) for c in cover])
        return np.stack(views), masks
    cams = protocol.cameras(mesh) if cameras is None else list(cameras)
    views = render_views(mesh, cams, supersample=protocol.supersample)
    alpha = render_views(black, cams, supersample=protocol.supersample, background="transparent")[
        ..., 3
    ]
    return views[..., :3], (alpha.astype(np.float32) / np.float32(255))


def evaluate_views(
    mesh: Mesh | tuple,
    *,
    reference_images: Float[ArrayLike, "N H W 3"] | None = None,
    exemplar: Float[ArrayLike, "H2 W2 3"] | None = None,
    cameras: Sequence | None = None,
    protocol: Protocol | None = None,
    metrics: Sequence[str] | None = None,
    weights: VGGWeights | None = None,
) -> dict[str, float]:
    """Render a colouring from the standard rig and score it (:func:`evaluate_images`).

    Against ``reference_images`` (e.g. :func:`protocol_views` of the ground-truth colouring from
    the same cameras) every metric applies; against a 2D ``exemplar`` (texture synthesis) the
    distribution metrics only. Metrics are masked to the object (the renders' coverage).

    Args:
      mesh: the colouring, a :class:`~jmeshtex.Mesh` with ``vertex_colors`` or ``uv`` with
        ``texture`` (as :func:`protocol_views`).
      reference_images: ``[N, H, W, 3]`` reference views from the same cameras.
      exemplar: one ``[H2, W2, 3]`` image (exactly one of ``reference_images`` and ``exemplar``).
      cameras, protocol: the views (default: :class:`Protocol`'s rig).
      metrics, weights: as :func:`evaluate_images`.

    Returns:
      ``{metric: mean over views, "views": N}``.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> mesh = icosphere(2)
      >>> mesh = mesh.replace(vertex_colors=0.5 * (mesh.vertices + 1))
      >>> rig = Protocol(azimuths=2, elevations=(0.0,), size=48)
      >>> ref, _ = protocol_views(mesh, protocol=rig)
      >>> out = evaluate_views(mesh, reference_images=ref, protocol=rig)
      >>> out["psnr"], round(out["lpips"], 6)
      (inf, 0.0)
    """
    if (reference_images is None) == (exemplar is None):
        raise InputError(
            "evaluate_views: pass exactly one of reference_images (one per view) and exemplar"
        )
    views, masks = protocol_views(mesh, cameras=cameras, protocol=protocol)
    refs = reference_images if exemplar is None else exemplar
    return evaluate_images(views, refs, masks=masks, metrics=metrics, weights=weights)


@dataclasses.dataclass(frozen=True)
class BaselineTable:
    """A method's protocol numbers next to the protocol's own floor and ceiling.

    Attributes:
      rows: ``{row: {metric: value}}`` for ``"result"``, ``"flat"`` (mean colour), ``"permuted"``
        (the reference colours permuted) and ``"exemplar"`` (the reference itself: the metric's
        zero), in that order.
      note: what was compared (views, size, features) — print it with the table.

    Example:
      >>> t = BaselineTable({"result": {"sifid": 1.0}, "flat": {"sifid": 3.0}}, "2 views")
      >>> print(t.markdown())
      | row | sifid |
      | --- | --- |
      | result | 1 |
      | flat | 3 |
      <BLANKLINE>
      2 views
    """

    rows: dict[str, dict[str, float]]
    note: str

    def markdown(self) -> str:
        """The table in markdown, one row per colouring, then the note."""
        metrics = [k for k in next(iter(self.rows.values())) if k != "views"]
        lines = ["| row | " + " | ".join(metrics) + " |", "| --- |" + " --- |" * len(metrics)]
        lines += [
            f"| {r} | " + " | ".join(f"{v[m]:.4g}" for m in metrics) + " |"
            for r, v in self.rows.items()
        ]
        return "\n".join(lines) + "\n\n" + self.note

    def to_dict(self) -> dict:
        """Plain dict (JSON-ready)."""
        return {"rows": self.rows, "note": self.note}


def baseline_table(
    result: Mesh,
    *,
    key,
    reference: Mesh | None = None,
    exemplar: Float[ArrayLike, "H2 W2 3"] | None = None,
    texel_mask: ArrayLike | None = None,
    cameras: Sequence | None = None,
    protocol: Protocol | None = None,
    metrics: Sequence[str] | None = None,
    weights: VGGWeights | None = None,
) -> BaselineTable:
    """Score a result colouring and the protocol's baselines from the same views.

    Two settings:

    - **reference colouring on the same mesh** (reconstruction, transfer with a ground truth):
      ``reference``, the same geometry with the true ``vertex_colors`` or ``texture`` (on its
      ``uv``, default the result's). Reference views are its renders; rows: the result,
      :func:`flat_baseline` and :func:`permuted_baseline` of the reference colouring (over
      vertices / texels, within ``texel_mask`` if given), and the reference itself (0, or ``inf``
      PSNR, by construction).
    - **2D exemplar** (texture synthesis): each view is compared with ``exemplar`` (distribution
      metrics); flat = the exemplar's mean colour on every vertex; permuted = exemplar pixels drawn
      at random without replacement (with, if the exemplar has fewer) onto the result's vertices /
      texels (the exemplar's histogram, no structure); exemplar = the exemplar against itself.

    Args:
      result: the result, a :class:`~jmeshtex.Mesh` with ``vertex_colors`` ``[V, 3]`` or ``uv``
        ``[F, 3, 2]`` with ``texture`` ``[H, W, 3]`` (the texture is used when it has both).
      key: JAX PRNG key for the permutation.
      reference: the reference colouring on the same geometry (setting 1).
      exemplar: ``[H2, W2, 3]`` image (setting 2).
      texel_mask: ``[H, W]`` used texels of the reference texture (setting 1, textures).
      cameras, protocol, metrics, weights: as :func:`evaluate_views`.

    Returns:
      A :class:`BaselineTable`.

    Raises:
      InputError: not exactly one of ``reference`` and ``exemplar``, no result or reference
        colouring, a reference on other geometry, bad shapes.
    """
    if (reference is None) == (exemplar is None):
        raise InputError("baseline_table: pass exactly one of reference and exemplar")
    check_key(key)
    result = as_mesh(result, what="baseline_table: result")
    textured = result.uv is not None and result.texture is not None
    if not textured and result.vertex_colors is None:
        raise InputError(
            "baseline_table: the result needs a colouring (a Mesh with vertex_colors, or uv with "
            "texture)"
        )
    geometry = Mesh(result.vertices, result.faces)
    protocol = Protocol() if protocol is None else protocol
    cams = protocol.cameras(geometry) if cameras is None else list(cameras)
    weights = load_vgg16() if weights is None else weights

    def views(**colouring):
        return protocol_views(geometry.replace(**colouring), cameras=cams, protocol=protocol)

    if textured:
        own = {"uv": result.uv, "texture": result.texture}
    else:
        own = {"vertex_colors": result.vertex_colors}
    result_views, masks = views(**own)
    kw = {"masks": masks, "metrics": metrics, "weights": weights}
    if exemplar is not None:
        ex = as_float_images(exemplar, "baseline_table", batched=False)
        flat, permuted = _exemplar_baselines(result, ex, key=key)
        rows = {
            "result": evaluate_images(result_views, ex, **kw),
            "flat": evaluate_images(views(**flat)[0], ex, **kw),
            "permuted": evaluate_images(views(**permuted)[0], ex, **kw),
            "exemplar": evaluate_images(ex[None], ex, metrics=metrics, weights=weights),
        }
        note = (
            f"{len(cams)} views at {protocol.size}², each compared with the {ex.shape[1]}×{ex.shape[0]} "
            "exemplar; SIFID/Gram on VGG-16 features (SIFID not comparable in value with Inception SIFID)"
        )
        return BaselineTable(rows, note)
    ref, flat, perm = _reference_baselines(result, reference, texel_mask, key=key)
    ref_views = views(**ref)[0]
    rows = {
        "result": evaluate_images(result_views, ref_views, **kw),
        "flat": evaluate_images(views(**flat)[0], ref_views, **kw),
        "permuted": evaluate_images(views(**perm)[0], ref_views, **kw),
        "exemplar": evaluate_images(ref_views, ref_views, **kw),
    }
    note = (
        f"{len(cams)} views at {protocol.size}², each compared with the reference's render from the same "
        "camera, masked to the object; SIFID/Gram on VGG-16 features (SIFID not comparable in value with "
        "Inception SIFID)"
    )
    return BaselineTable(rows, note)


def _exemplar_baselines(result: Mesh, ex: np.ndarray, *, key) -> tuple[dict, dict]:
    """The colourings of the 2D-exemplar setting's baselines, ``(flat, permuted)``: the exemplar's
    mean colour on every vertex, and exemplar pixels drawn onto the result's vertices / texels."""
    textured = result.uv is not None and result.texture is not None
    pool = ex.reshape(-1, 3)
    target = np.asarray(result.texture if textured else result.vertex_colors)
    sites = int(np.prod(target.shape[:-1]))
    pick = host_rng(key).choice(len(pool), sites, replace=sites > len(pool))
    drawn = pool[pick].reshape(*target.shape[:-1], 3).astype(np.float64)
    mean_colors = np.broadcast_to(pool.astype(np.float64).mean(0), (result.num_vertices, 3)).copy()
    permuted = {"uv": result.uv, "texture": drawn} if textured else {"vertex_colors": drawn}
    return {"vertex_colors": mean_colors}, permuted


def _reference_baselines(result: Mesh, reference, texel_mask, *, key) -> tuple[dict, dict, dict]:
    """The colourings of the reference setting, ``(reference, flat, permuted)``, checked: the
    reference on the result's geometry, with vertex colours or a texture (on uv)."""
    reference = as_mesh(reference, what="baseline_table: reference")
    if reference.num_vertices != result.num_vertices or reference.num_faces != result.num_faces:
        raise InputError(
            "baseline_table: the reference must be the result's geometry with the true colouring, "
            f"got {reference.num_vertices} vertices / {reference.num_faces} faces for "
            f"{result.num_vertices} / {result.num_faces}"
        )
    if reference.texture is not None:
        ruv = result.uv if reference.uv is None else reference.uv
        if ruv is None:
            raise InputError(
                "baseline_table: the reference texture needs uv (its own or the result's)"
            )
        rtex = np.asarray(reference.texture)
        return (
            {"uv": ruv, "texture": rtex},
            {"uv": ruv, "texture": flat_baseline(rtex, mask=texel_mask)},
            {"uv": ruv, "texture": permuted_baseline(rtex, key=key, mask=texel_mask)},
        )
    if reference.vertex_colors is not None:
        rc = np.asarray(reference.vertex_colors)
        return (
            {"vertex_colors": rc},
            {"vertex_colors": flat_baseline(rc)},
            {"vertex_colors": permuted_baseline(rc, key=key)},
        )
    raise InputError("baseline_table: the reference has no vertex_colors and no texture")

"""Gram-matching texture synthesis and style transfer on a mesh (Kovács et al. 2024, Sec. 5).

The texel colours ``x`` are optimised so that the Gram matrices of the mesh CNN's feature maps
match those of the 2D exemplar run through the 2D network (Gatys et al. 2015):

.. math:: \\mathcal L_{style}(x) = \\frac{1}{|L|} \\sum_{l \\in L} \\operatorname{mean}_{c,d}
   \\big(G^l(x) - G^l(E)\\big)_{cd}^2, \\qquad G^l_{cd} = \\frac{1}{N_l} \\sum_n F^l_{nc} F^l_{nd}

with Adam (lr 0.1, halved every 200 steps, 500 steps), colours clipped to [0, 1] after every step and
initialised uniformly in [0, 0.2]. Style transfer adds ``w_c · mean((F^c(x) − F^c(x_content))²)`` at
one content layer and starts from the content texture.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._errors import InputError
from .._mesh import Mesh
from .._types import Array, Float
from ..geometry import to_jax, tracer_geometry
from ..ops import gram_matrix
from ._atlas import TextureAtlas, image_to_texels, texels_to_image, texture_atlas
from ._config import SurfaceCNNConfig
from ._neighborhood import texel_taps
from ._network import cnn_features_2d, mesh_cnn_features, required_levels
from ._pyramid import TexelPyramid, texel_pyramid
from ._weights import CNNWeights, layer_names, vgg16_weights


class Surface(NamedTuple):
    """The precomputed surface of a mesh CNN: texel atlas and pooling pyramid (host arrays).

    Attributes:
      atlas: :class:`~jmeshtex.surfacecnn.TextureAtlas`.
      pyramid: :class:`~jmeshtex.surfacecnn.TexelPyramid`.
      seconds: ``{"atlas": s, "taps": s, "pyramid": s}`` host time of each stage.
    """

    atlas: TextureAtlas
    pyramid: TexelPyramid
    seconds: dict


class SynthesisResult(NamedTuple):
    """Outcome of :func:`synthesize_texture` / :func:`stylize_texture`.

    Attributes:
      texture: ``[size, size, 3]`` float32 image in the mesh's UV layout (row 0 = v 1), invalid
        texels filled with the nearest valid colour.
      colors: ``[N, 3]`` float32 colours of the valid texels.
      mesh: the input :class:`~jmeshtex.Mesh` with ``uv`` (unwrapped if it had none) and ``texture``.
      losses: ``[steps]`` float64 loss before each step's update.
      final_loss: loss of the returned colours.
      surface: the :class:`Surface` used.
      stats: timings (seconds) and sizes.
    """

    texture: Float[np.ndarray, "S S 3"]
    colors: Float[np.ndarray, "N 3"]
    mesh: Mesh
    losses: np.ndarray
    final_loss: float
    surface: Surface
    stats: dict


def default_layers(weights: CNNWeights) -> tuple[str, ...]:
    """Every ReLU and pooling output: the reference tool's style layers."""
    return layer_names(weights)


def prepare_surface(
    vertices: Float[np.ndarray, "V 3"],
    faces: np.ndarray,
    uv: Float[np.ndarray, "F 3 2"] | None,
    *,
    size: int,
    levels: int,
    boundary: str = "zero",
    rotation: float | np.ndarray = 0.0,
) -> Surface:
    """Atlas, level-0 taps and the pooling pyramid of a mesh (the whole host precomputation).

    Args:
      vertices, faces: the mesh (consistently oriented, manifold).
      uv: ``[F, 3, 2]`` per-corner UVs, or None to unwrap with xatlas.
      size: texture resolution.
      levels: pooling levels (:func:`~jmeshtex.surfacecnn.required_levels`).
      boundary: failed-walk rule (:func:`~jmeshtex.surfacecnn.texel_taps`).
      rotation: tap-frame rotation (radians, scalar or per texel).

    Returns:
      :class:`Surface`.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> s = prepare_surface(v, f, v[f][..., :2], size=8, levels=2)
      >>> s.atlas.num_texels, [len(r) for r in s.pyramid.representative]
      (64, [64, 16, 4])
    """
    t0 = time.perf_counter()
    geometry = tracer_geometry(vertices, faces)
    atlas = texture_atlas(vertices, faces, uv, size=size, geometry=geometry)
    t1 = time.perf_counter()
    taps = texel_taps(vertices, faces, atlas, boundary=boundary, rotation=rotation, geometry=geometry)
    t2 = time.perf_counter()
    pyramid = texel_pyramid(vertices, faces, atlas, levels=levels, boundary=boundary, rotation=rotation,
                            taps=taps, geometry=geometry)
    t3 = time.perf_counter()
    return Surface(atlas, pyramid, {"atlas": t1 - t0, "taps": t2 - t1, "pyramid": t3 - t2})


def gram_targets(
    exemplar: Float[Array, "H W 3"], weights: CNNWeights, *, layers: tuple[str, ...], pool: str = "mean",
    dtype=jnp.float32,
) -> dict[str, Float[Array, "C C"]]:
    """Gram matrices of the exemplar's 2D feature maps, ``G_cd = mean_pixels F_c F_d``.

    Example:
      >>> g = gram_targets(np.full((8, 8, 3), 0.5), vgg16_weights(), layers=("relu1_1",))
      >>> g["relu1_1"].shape
      (64, 64)
    """
    image = _check_image(exemplar, "exemplar")
    feats = cnn_features_2d(jnp.asarray(image, dtype)[None], weights, layers=layers, pool=pool)
    return {k: gram_matrix(v[0].reshape(-1, v.shape[-1])) for k, v in feats.items()}


def _check_image(image, name: str) -> np.ndarray:
    image = np.asarray(image)
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    if image.ndim != 3 or image.shape[2] not in (1, 3, 4) or min(image.shape[:2]) < 1:
        raise InputError(f"{name} must be an [H, W, 3] RGB image (or grey / RGBA), got shape {image.shape}")
    if image.shape[2] == 1:
        image = np.repeat(image, 3, axis=2)
    image = image[..., :3]
    if np.issubdtype(image.dtype, np.integer):
        image = image / 255.0
    image = image.astype(np.float64)
    if not np.isfinite(image).all() or image.min() < 0 or image.max() > 1:
        raise InputError(f"{name} colours must be finite and in [0, 1] (or uint8)")
    return image


def style_loss(
    colors: Float[Array, "N 3"],
    network_arrays,
    weights: CNNWeights,
    targets: dict[str, Array],
    *,
    pool: str = "mean",
) -> Float[Array, ""]:
    """Layer-averaged mean squared Gram difference of the mesh CNN's feature maps (module docstring).

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> s = prepare_surface(v, f, v[f][..., :2], size=8, levels=0)
      >>> w = vgg16_weights()
      >>> img = np.full((8, 8, 3), 0.5)
      >>> t = gram_targets(img, w, layers=("relu1_1", "relu1_2"))
      >>> float(style_loss(jnp.full((64, 3), 0.5, jnp.float32), s.pyramid.network_arrays(), w, t)) < 1e-9
      True
    """
    feats = mesh_cnn_features(colors, network_arrays, weights, layers=tuple(targets), pool=pool)
    return _gram_term(feats, targets)


def _gram_term(feats: dict, targets: dict) -> Array:
    terms = [jnp.mean((gram_matrix(feats[k]) - targets[k].astype(feats[k].dtype)) ** 2) for k in targets]
    return sum(terms) / len(terms)


def _save_checkpoint(path, x, state, step: int, losses, fingerprint) -> None:
    import io
    import pathlib

    from ..io import atomic_write

    arrays = {"x": np.asarray(x), "step": np.asarray(step), "losses": np.asarray(losses, np.float64),
              "fingerprint": np.asarray(fingerprint, np.float64)}
    for i, leaf in enumerate(jax.tree.leaves(state)):
        arrays[f"opt_{i:03d}"] = np.asarray(leaf)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write(pathlib.Path(path), buf.getvalue())


def _load_checkpoint(path, x0, state0, fingerprint):
    from .._errors import MeshIOError

    try:
        with np.load(path, allow_pickle=False) as data:
            saved = {k: data[k] for k in data.files}
    except (OSError, ValueError) as err:
        raise MeshIOError(f"cannot read surface-CNN checkpoint {path}: {err}") from err
    leaves, treedef = jax.tree.flatten(state0)
    try:
        same = np.array_equal(saved["fingerprint"], np.asarray(fingerprint, np.float64))
        x = saved["x"]
        opt = [saved[f"opt_{i:03d}"] for i in range(len(leaves))]
        step, losses = int(saved["step"]), list(saved["losses"])
    except KeyError as err:
        raise MeshIOError(f"{path}: incomplete surface-CNN checkpoint (missing {err})") from err
    if not same or x.shape != x0.shape or any(a.shape != np.shape(b) for a, b in zip(opt, leaves, strict=True)):
        raise InputError(
            f"{path} is a checkpoint of a different run (texels, learning rate or task differ); delete it or "
            "write this run elsewhere"
        )
    state = jax.tree.unflatten(treedef, [jnp.asarray(a, b.dtype) for a, b in zip(opt, leaves, strict=True)])
    return jnp.asarray(x, x0.dtype), state, step, losses


def _optimize(x0, loss_fn, aux, config: SurfaceCNNConfig, progress: bool, desc: str, checkpoint=None,
              checkpoint_every: int = 50, task: int = 0):
    """Adam with the halving schedule, clipped to [0, 1] after every step; one jitted step.

    ``loss_fn(x, aux)``: the arrays (taps, groups, weights, targets) travel in ``aux`` as arguments
    of the jitted step, never as constants baked into the compiled program (hundreds of MB at 1024²,
    and XLA would try to constant-fold through them).

    With ``checkpoint`` the colours, the Adam state and the loss curve are written there atomically
    every ``checkpoint_every`` steps and at the end; an existing checkpoint of the same run is resumed.
    """
    import pathlib

    boundaries = {k * config.halve_every: 0.5 for k in range(1, config.steps // config.halve_every + 1)}
    schedule = optax.piecewise_constant_schedule(config.learning_rate, boundaries)
    optimizer = optax.adam(schedule)

    @jax.jit
    def step(x, state, aux):
        loss, grad = jax.value_and_grad(loss_fn)(x, aux)
        with jax.numpy_dtype_promotion("standard"):
            updates, state = optimizer.update(grad, state, x)
            x = optax.apply_updates(x, updates)
        return jnp.clip(x, 0.0, 1.0).astype(x0.dtype), state, loss

    with jax.numpy_dtype_promotion("standard"):
        state = optimizer.init(x0)
    x, start, losses = x0, 0, []
    fingerprint = (x0.shape[0], config.learning_rate, config.halve_every, task)
    if checkpoint is not None and pathlib.Path(checkpoint).is_file():
        x, state, start, losses = _load_checkpoint(checkpoint, x0, state, fingerprint)
        start = min(start, config.steps)
        losses = losses[:start]
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=config.steps, initial=start, desc=desc, unit="step", dynamic_ncols=True)
    t0 = time.perf_counter()
    compile_s = 0.0
    for i in range(start, config.steps):
        x, state, loss = step(x, state, aux)
        losses.append(loss)
        if i == start:
            jax.block_until_ready(x)
            compile_s = time.perf_counter() - t0
        if bar is not None:
            bar.update(1)
            if i % 10 == 0 or i == config.steps - 1:
                bar.set_postfix(loss=f"{float(loss):.4g}")
        if checkpoint is not None and (i + 1) % checkpoint_every == 0 and i + 1 < config.steps:
            _save_checkpoint(checkpoint, x, state, i + 1, [float(v) for v in losses], fingerprint)
    jax.block_until_ready(x)
    total = time.perf_counter() - t0
    if bar is not None:
        bar.close()
    final = float(jax.jit(loss_fn)(x, aux))
    losses = np.asarray([float(v) for v in losses], np.float64)
    if checkpoint is not None:
        _save_checkpoint(checkpoint, x, state, config.steps, losses, fingerprint)
    ran = config.steps - start
    steady = (total - compile_s) / max(ran - 1, 1)
    return x, losses, final, {"optimize_s": total, "first_step_s": compile_s, "step_s": steady,
                              "resumed_at": start}


def _mesh_parts(mesh) -> tuple[Mesh, np.ndarray, np.ndarray, np.ndarray | None]:
    if isinstance(mesh, Mesh):
        return mesh, mesh.vertices, mesh.faces, mesh.uv
    if isinstance(mesh, tuple) and len(mesh) in (2, 3):
        v, f = np.asarray(mesh[0], np.float64), np.asarray(mesh[1], np.int64)
        uv = None if len(mesh) == 2 or mesh[2] is None else np.asarray(mesh[2], np.float64)
        return Mesh(v, f, uv=uv), v, f, uv
    raise InputError("mesh must be a jmeshtex.Mesh or a tuple (vertices, faces[, uv])")


def _setup(mesh, config, weights, layers, surface, extra_layers=()):
    weights = vgg16_weights() if weights is None else weights
    layers = default_layers(weights) if (layers or config.layers) is None else tuple(layers or config.layers)
    levels = required_levels(weights, tuple(layers) + tuple(extra_layers))
    base, v, f, uv = _mesh_parts(mesh)
    if surface is None:
        surface = prepare_surface(v, f, uv, size=config.size, levels=levels, boundary=config.boundary)
    elif surface.pyramid.levels < levels or surface.atlas.size != config.size:
        raise InputError(
            f"surface was prepared with size {surface.atlas.size} and {surface.pyramid.levels} levels; this run "
            f"needs size {config.size} and {levels} levels"
        )
    dtype = jnp.dtype(config.dtype)
    arrays = to_jax(surface.pyramid.network_arrays(), dtype)
    weights = jax.tree.map(lambda a: jnp.asarray(a, dtype), weights)
    return base, weights, layers, surface, arrays, dtype


def _result(base: Mesh, surface: Surface, x, losses, final, stats) -> SynthesisResult:
    colors = np.asarray(x, np.float32)
    texture = texels_to_image(surface.atlas, colors).astype(np.float32)
    mesh = base.replace(uv=surface.atlas.uv, texture=texture)
    stats = {**stats, **{f"{k}_s": v for k, v in surface.seconds.items()},
             "texels": surface.atlas.num_texels, "size": surface.atlas.size,
             "initial_loss": float(losses[0]) if len(losses) else final, "final_loss": final}
    return SynthesisResult(texture, colors, mesh, losses, final, surface, stats)


def synthesize_texture(
    mesh: Mesh | tuple,
    exemplar: Float[np.ndarray, "H W 3"],
    *,
    config: SurfaceCNNConfig | None = None,
    key: jax.Array,
    weights: CNNWeights | None = None,
    layers: tuple[str, ...] | None = None,
    surface: Surface | None = None,
    progress: bool = True,
    checkpoint=None,
    checkpoint_every: int = 50,
) -> SynthesisResult:
    """Synthesise a texture for a mesh whose CNN Gram statistics match a 2D exemplar's.

    Minimises :func:`style_loss` over the texel colours (module docstring; Kovács et al. 2024, eq. 1,
    after Gatys et al. 2015) with Adam, lr ``config.learning_rate`` halved every
    ``config.halve_every`` steps, clipped to [0, 1], from uniform(``init_low``, ``init_high``) colours.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` (its UVs are used; without UVs it is unwrapped with xatlas) or
        ``(vertices, faces[, uv])``.
      exemplar: ``[H, W, 3]`` RGB image in [0, 1] (or uint8).
      config: :class:`~jmeshtex.surfacecnn.SurfaceCNNConfig` (default: the paper's settings).
      key: PRNG key of the initial colours.
      weights: CNN weights (default: the embedded VGG-16, :func:`vgg16_weights`).
      layers: Gram layers (default ``config.layers``, else every ReLU and pool output).
      surface: a precomputed :class:`Surface` (:func:`prepare_surface`) to reuse.
      progress: show a tqdm bar with the loss.
      checkpoint: a ``.npz`` path: colours, Adam state and losses are saved there atomically every
        ``checkpoint_every`` steps and at the end; if it already holds this run (same texels, learning
        rate and task), the optimisation resumes from it (a different run raises :class:`InputError`).
      checkpoint_every: steps between checkpoints.

    Returns:
      :class:`SynthesisResult`.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> ex = np.random.default_rng(0).uniform(size=(16, 16, 3))
      >>> r = synthesize_texture((v, f, v[f][..., :2]), ex, config=SurfaceCNNConfig(size=16, steps=20),
      ...                        key=jax.random.key(0), layers=("relu1_1",), progress=False)
      >>> r.texture.shape, bool(r.final_loss < r.losses[0])
      ((16, 16, 3), True)
    """
    config = SurfaceCNNConfig() if config is None else config
    base, weights, layers, surface, arrays, dtype = _setup(mesh, config, weights, layers, surface)
    t0 = time.perf_counter()
    targets = gram_targets(_check_image(exemplar, "exemplar"), weights, layers=layers, pool=config.pool, dtype=dtype)
    targets = jax.block_until_ready(targets)
    target_s = time.perf_counter() - t0
    x0 = jax.random.uniform(key, (surface.atlas.num_texels, 3), dtype, config.init_low, config.init_high)

    def loss_fn(x, aux):
        arrays, weights, targets = aux
        return style_loss(x, arrays, weights, targets, pool=config.pool)

    x, losses, final, stats = _optimize(x0, loss_fn, (arrays, weights, targets), config, progress,
                                        "surfacecnn synthesize", checkpoint,
                                        checkpoint_every, task=0)
    return _result(base, surface, x, losses, final, {**stats, "targets_s": target_s})


def stylize_texture(
    mesh: Mesh | tuple,
    content: Float[np.ndarray, "H W 3"],
    style: Float[np.ndarray, "H2 W2 3"],
    *,
    config: SurfaceCNNConfig | None = None,
    weights: CNNWeights | None = None,
    layers: tuple[str, ...] | None = None,
    surface: Surface | None = None,
    progress: bool = True,
    checkpoint=None,
    checkpoint_every: int = 50,
) -> SynthesisResult:
    """Neural style transfer on a mesh texture: Gram term of ``style`` plus a content term.

    .. math:: \\mathcal L(x) = \\mathcal L_{style}(x) + w_c\\, \\operatorname{mean}\\big(
       (F^c(x) - F^c(x_{content}))^2\\big)

    ``F^c`` is the mesh CNN's feature map ``config.content_layer``; ``x_content`` the content
    texture read at the valid texels (it must be in the mesh's UV layout); optimisation starts from
    it (Gatys et al. 2016; Kovács et al. 2024, Sec. 6).

    Args:
      mesh: a :class:`~jmeshtex.Mesh` with UVs (or ``(vertices, faces, uv)``).
      content: ``[H, W, 3]`` texture in the mesh's UV layout (resampled to ``config.size``).
      style: ``[H2, W2, 3]`` style image.
      config, weights, layers, surface, progress, checkpoint, checkpoint_every: as in
        :func:`synthesize_texture`.

    Returns:
      :class:`SynthesisResult`.

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> rng = np.random.default_rng(0)
      >>> r = stylize_texture((v, f, v[f][..., :2]), rng.uniform(size=(16, 16, 3)), rng.uniform(size=(16, 16, 3)),
      ...                     config=SurfaceCNNConfig(size=16, steps=5, content_layer="relu1_2"),
      ...                     layers=("relu1_1",), progress=False)
      >>> r.colors.shape
      (256, 3)
    """
    config = SurfaceCNNConfig() if config is None else config
    _, _, _, uv = _mesh_parts(mesh)
    if uv is None:
        raise InputError("stylize_texture: the mesh has no UVs, so a content texture cannot be placed on it; "
                         "use synthesize_texture or give a mesh with UVs")
    base, weights, layers, surface, arrays, dtype = _setup(mesh, config, weights, layers, surface,
                                                           extra_layers=(config.content_layer,))
    content_colors = jnp.asarray(image_to_texels(surface.atlas, _check_image(content, "content")), dtype)
    targets = gram_targets(_check_image(style, "style"), weights, layers=layers, pool=config.pool, dtype=dtype)
    content_feats = mesh_cnn_features(content_colors, arrays, weights, layers=(config.content_layer,),
                                      pool=config.pool)[config.content_layer]
    weight = jnp.asarray(config.content_weight, dtype)

    def loss_fn(x, aux):
        arrays, weights, targets, content_feats = aux
        feats = mesh_cnn_features(x, arrays, weights, layers=tuple(dict.fromkeys((*layers, config.content_layer))),
                                  pool=config.pool)
        content_term = jnp.mean((feats[config.content_layer] - content_feats) ** 2)
        return _gram_term(feats, targets) + weight * content_term

    aux = (arrays, weights, targets, content_feats)
    x, losses, final, stats = _optimize(content_colors, loss_fn, aux, config, progress, "surfacecnn stylize",
                                        checkpoint, checkpoint_every, task=1)
    return _result(base, surface, x, losses, final, stats)


def save_result(
    result: SynthesisResult,
    out_dir,
    *,
    exemplar: np.ndarray | None = None,
    title: str = "surface CNN",
    render_size: tuple[int, int] = (420, 400),
) -> dict:
    """Write a synthesis result: the texture PNG (UV layout), the textured mesh, renders, a summary.

    Files in ``out_dir``: ``texture.png``; ``textured.obj`` (+ ``textured.mtl``, ``textured.png``);
    ``render_front.png``, ``render_back.png``, ``surfacecnn.png`` (exemplar and both views side by
    side); ``summary.json`` (timings, sizes, the loss curve). Every file is written atomically.

    Returns:
      The summary dict (also in ``summary.json``), with the paths written under ``"files"``.

    Example:
      >>> import tempfile
      >>> from jmeshtex.data import grid
      >>> v, f = grid(2)
      >>> r = synthesize_texture((v, f, v[f][..., :2]), np.full((8, 8, 3), 0.5), key=jax.random.key(0),
      ...                        config=SurfaceCNNConfig(size=8, steps=2), layers=("relu1_1",), progress=False)
      >>> sorted(p.rsplit("/", 1)[-1] for p in save_result(r, tempfile.mkdtemp())["files"])[:3]
      ['render_back.png', 'render_front.png', 'summary.json']
    """
    import json
    import pathlib

    from .. import render
    from ..io import atomic_write, save_mesh, save_png

    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    save_png(result.texture, out / "texture.png")
    save_mesh(result.mesh.replace(name="textured"), out / "textured.obj")
    m = result.mesh
    views = []
    for name, view in (("render_front.png", (20.0, -60.0)), ("render_back.png", (20.0, 120.0))):
        views.append(render.render_mesh(m.vertices, m.faces, out / name, uv=m.uv, texture=result.texture,
                                         view=view, size=render_size, title=f"{title} ({name[7:-4]})"))
    panels, titles = list(views), [None, None]
    if exemplar is not None:
        panels.insert(0, _check_image(exemplar, "exemplar"))
        titles.insert(0, "exemplar")
    panels.append(result.texture)
    titles.append("texture (UV layout)")
    height = max(np.shape(v)[0] for v in views)  # small images enlarged (nearest, integer factor) to the renders'
    panels = [np.repeat(np.repeat(pn, max(1, height // np.shape(pn)[0]), 0), max(1, height // np.shape(pn)[0]), 1)
              for pn in panels]
    render.render_grid(panels, out / "surfacecnn.png", titles=titles, columns=len(panels))
    files = [str(out / n) for n in ("texture.png", "textured.obj", "render_front.png", "render_back.png",
                                    "surfacecnn.png", "summary.json")]
    summary = {**{k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in result.stats.items()},
               "losses": [float(x) for x in result.losses], "files": files}
    atomic_write(out / "summary.json", (json.dumps(summary, indent=2) + "\n").encode())
    return summary

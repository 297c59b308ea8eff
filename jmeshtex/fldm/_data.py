"""FLDM training data: re-triangulated copies of one mesh, their geometry, and their cached latents.

Mitchel et al. (2024, §6.1) train the denoiser on many re-triangulations of the single input mesh so
that it learns the texture and not the connectivity. For each copy ``i`` (:func:`copy_mesh`):

1. :func:`jmeshtex.geometry.remesh` with a seed drawn from ``(key, i)`` (same surface, new
   triangles; ``copy_vertices`` vertices);
2. the denoiser's geometry (:func:`~jmeshtex.fldm.core.denoiser_geometry`: k-NN neighbourhoods of
   the copy and of one coarse level, pooling map);
3. its latents from an ``encode`` callable ``Mesh -> complex [V, d]`` — normally the FL-VAE reading
   the *original* surface's colours at the copy's one-ring samples (:func:`fl_vae_encoder`), in the
   copy's ``one_ring_neighborhood`` frames, which are the denoiser's fine frames;
4. with ``config.experimental.phase_sync`` (beyond the paper), every encoding's phases synchronised over the
   copy's k-NN connection (:func:`~jmeshtex.fldm.core.synchronize_phases`; ``"flat"``: textured
   rings, :func:`~jmeshtex.fldm.core.ring_color_spread` ≥ ``flat_spread``, pinned);
5. optional per-vertex labels, carried from the original by the closest surface point.

Copies are cached on disk one ``.npz`` each (``copy_0000.npz`` …) next to ``data.json`` that records
what they were built from: the geometry, colours (texture, UVs, vertex colours) and labels of the
input, the encoder's identity, every config field that changes a copy, and the cache format
(``DATA_VERSION``); a rebuild reuses them only when all of these agree. All copies are then padded
to one bucketed shape (``V₀``, ``V₁`` rounded up to a multiple of ``config.bucket``) and stacked.
"""

from __future__ import annotations

import hashlib
import json
import os
import pathlib
from collections.abc import Callable
from typing import NamedTuple

import jax
import numpy as np

from .._errors import ConfigError, InputError, MeshIOError
from .._mesh import Mesh, as_mesh
from .._random import key_ints
from ..geometry import PoolingMap, VertexNeighborhood, remesh, surface_correspondence
from ._config import Config
from ._denoiser import (
    DenoiserGeometry,
    _bucketed_vertices,
    denoiser_geometry,
    geometry_sizes,
    pad_geometry,
)
from ._diffusion import latent_scale
from ._phase import ring_color_spread, synchronize_phases

DATA_FILE = "data.json"
#: format of the cached copies; a cache written with another one is rebuilt
DATA_VERSION = 2


class Dataset(NamedTuple):
    """Stacked, padded training copies (what :func:`build_dataset` returns and :func:`train` reads).

    Attributes:
      latents: ``[N, V₀, d]`` complex128 latents (unscaled; zero on padding).
      geometry: :class:`~jmeshtex.fldm.core.DenoiserGeometry` with a leading ``[N]`` axis on every leaf.
      labels: ``[N, V₀]`` int32 labels, or None.
      num_vertices: ``[N]`` real vertex count of each copy.
      scale: ``[d]`` per-channel latent scale (eq. 38–39) over all copies.
      meshes: the copies as :class:`~jmeshtex.Mesh` (host, for rendering and checks).
      encodings: ``[N, K − 1, V₀, d]`` complex64 further encodings of every copy (fresh one-ring
        samplings; ``config.experimental.encodings_per_copy = K``), or None (one encoding per copy).
    """

    latents: np.ndarray
    geometry: DenoiserGeometry
    labels: np.ndarray | None
    num_vertices: np.ndarray
    scale: np.ndarray
    meshes: tuple[Mesh, ...]
    encodings: np.ndarray | None = None

    @property
    def num_copies(self) -> int:
        """How many copies the data set holds."""
        return int(self.latents.shape[0])


def fl_vae_encoder(vae, original: Mesh, *, key: jax.Array) -> Callable[[Mesh], np.ndarray]:
    """An ``encode`` callable: the FL-VAE means ``μ`` of a copy, colours read on ``original``'s surface.

    Args:
      vae: the FL-VAE (:class:`jmeshtex.fl.Model`, e.g. :func:`jmeshtex.fl.load_pretrained`).
      original: the textured (or vertex-coloured) :class:`~jmeshtex.Mesh` the copies are made from.
      key: PRNG key; the ``n``-th call encodes with ``fold_in(key, n)``.

    Returns:
      ``encode(copy: Mesh) -> complex128 [V, d]`` (``d = vae.config.latent_dim``), with an
      ``identity`` attribute naming the encoder's weights and config (so that :func:`build_dataset`
      does not reuse a cache built with another encoder; the decoder's weights do not enter it).

    Example:
      >>> import jax
      >>> from jmeshtex import Mesh, fl
      >>> from jmeshtex.data import grid
      >>> v, f = grid(4)
      >>> m = Mesh(v, f, vertex_colors=np.tile(v[:, :1], (1, 3)))
      >>> vae = fl.init(fl.Config(features=8, num_heads=2, num_blocks=1, num_samples=8, encode_chunk=16),
      ...               key=jax.random.key(0))
      >>> enc = fl_vae_encoder(vae, m, key=jax.random.key(1))
      >>> enc(m).shape
      (25, 8)
    """
    from .. import fl

    if not isinstance(vae, fl.Model):
        raise InputError(
            f"fl_vae_encoder: expected a jmeshtex.fl.Model (fl.load_pretrained()), got {type(vae).__name__}"
        )
    colors = fl.core.surface_colors(as_mesh(original, what="original"))
    counter = [0]

    def encode(copy: Mesh) -> np.ndarray:
        counter[0] += 1
        k = jax.random.fold_in(key, counter[0])
        return np.asarray(fl.encode(vae, copy, colors=colors, key=k).mu, np.complex128)

    # the encoder's weights only: a decoder fine-tuned later leaves the latents, and so the cache, valid
    encode.identity = (  # type: ignore[attr-defined]
        f"fl_vae_encoder:{_digest(jax.tree.leaves(vae.params.encoder))}:{vae.config!r}:"
        f"colors={_digest(_color_arrays(original))}:key={key_ints(key)}"
    )
    encode.colors = colors  # type: ignore[attr-defined]
    return encode


def encode(
    vae,
    mesh: Mesh,
    config: Config,
    *,
    key: jax.Array,
    geometry: DenoiserGeometry | None = None,
    colors=None,
) -> np.ndarray:
    """A mesh's texture as the latents a model with ``config`` was trained on (e.g. the known part of
    :func:`~jmeshtex.fldm.inpaint`, or the reference beside a model's samples).

    The FL-VAE's means ``μ`` (as :func:`fl_vae_encoder` gives them), then, with
    ``config.experimental.phase_sync``, the phases synchronised as :func:`build_dataset` synchronised
    every training copy's (:func:`~jmeshtex.fldm.core.synchronize_phases`; ``"flat"`` pins the rings
    whose :func:`~jmeshtex.fldm.core.ring_color_spread` reaches ``flat_spread``).

    Args:
      vae: the FL-VAE the model's data were encoded with (:class:`jmeshtex.fl.Model`).
      mesh: a textured or vertex-coloured :class:`~jmeshtex.Mesh`.
      config: the model's :class:`Config` (``model.config``).
      key: PRNG key of the encoder's one-ring samples.
      geometry: ``mesh``'s :class:`~jmeshtex.fldm.core.DenoiserGeometry` (default: built from
        ``config.knn`` and ``config.pool_ratio``; pass the sampler's to avoid building it twice).
      colors: the surface colours (:func:`jmeshtex.fl.core.surface_colors`) when ``mesh`` is a
        re-triangulation of a textured original; default: ``mesh``'s own.

    Returns:
      ``complex128 [V, d]`` latents (``d = vae.config.latent_dim``).

    Raises:
      InputError: ``vae`` is not an FL-VAE, or ``mesh`` has no colours.

    Example:
      >>> import jax
      >>> from jmeshtex import Mesh, fl
      >>> from jmeshtex.data import icosphere
      >>> v, f = icosphere(1)
      >>> m = Mesh(v, f, vertex_colors=np.tile((v[:, :1] > 0) * 1.0, (1, 3)))
      >>> vae = fl.init(fl.Config(features=8, num_heads=2, num_blocks=1, num_samples=8, encode_chunk=16),
      ...               key=jax.random.key(0))
      >>> z = encode(vae, m, Config.tiny(latent_channels=8, phase_sync="flat"), key=jax.random.key(1))
      >>> z.shape, z.dtype
      ((42, 8), dtype('complex128'))
    """
    from .. import fl

    if not isinstance(vae, fl.Model):
        raise InputError(f"fldm.encode: expected a jmeshtex.fl.Model, got {type(vae).__name__}")
    mesh = as_mesh(mesh, what="mesh")
    if colors is None:
        colors = fl.core.surface_colors(mesh)
    mu = np.asarray(fl.encode(vae, mesh, colors=colors, key=key).mu, np.complex128)
    if config.experimental.phase_sync == "none":
        return mu
    if geometry is None:
        geometry = denoiser_geometry(mesh, knn=config.knn, pool_ratio=config.pool_ratio)
    return np.asarray(_synchronized(mu, mesh, geometry, config, colors), np.complex128)


def _synchronized(mu, copy: Mesh, geo: DenoiserGeometry, config: Config, colors):
    """``mu`` with ``config.experimental.phase_sync`` applied on ``copy`` (``colors``: its surface
    colours, needed for ``"flat"``)."""
    pinned = None
    if config.experimental.phase_sync == "flat":
        pinned = ring_color_spread(copy, colors) >= config.experimental.flat_spread
    return synchronize_phases(mu, geo.fine, pinned=pinned)


def _digest(arrays) -> str:
    h = hashlib.sha1()
    for a in arrays:
        a = np.ascontiguousarray(np.asarray(a))
        h.update(f"{a.dtype.str}{a.shape}".encode())  # equal bytes in another shape differ
        h.update(a.tobytes())
    return h.hexdigest()[:16]


def _color_arrays(mesh: Mesh) -> list[np.ndarray]:
    """What a mesh's colours are read from (absent parts as empty arrays, so that they differ)."""
    return [
        np.zeros(0) if a is None else np.asarray(a)
        for a in (mesh.uv, mesh.texture, mesh.vertex_colors)
    ]


def transfer_labels(original: Mesh, labels: np.ndarray, target: Mesh) -> np.ndarray:
    """Per-vertex labels of ``original`` at ``target``'s vertices (largest barycentric corner of the
    closest surface point).

    Example:
      >>> from jmeshtex.data import grid
      >>> v, f = grid(3)
      >>> transfer_labels(Mesh(v, f), (v[:, 0] > 0.5).astype(int), Mesh(v[:4], f[:1])).tolist()
      [0, 0, 1, 1]
    """
    original, target = as_mesh(original, what="original"), as_mesh(target)
    labels = np.asarray(labels)
    if labels.shape != (original.num_vertices,) or not np.issubdtype(labels.dtype, np.integer):
        raise InputError(
            f"labels must be integers [V] = ({original.num_vertices},), got {labels.dtype} {labels.shape}"
        )
    face, bary = surface_correspondence(original.vertices, original.faces, target.vertices)
    corner = np.argmax(bary, axis=1)
    return labels[original.faces[face, corner]].astype(np.int32)


def copy_mesh(mesh: Mesh, config: Config, i: int, *, key: jax.Array) -> Mesh:
    """Re-triangulated copy ``i`` of ``mesh`` (``copy_vertices`` vertices, or the input's count)."""
    mesh = as_mesh(mesh)
    n = config.copy_vertices or mesh.num_vertices
    return remesh(mesh, n_vertices=int(n), key=jax.random.fold_in(key, i))


def _geometry_arrays(geo: DenoiserGeometry) -> dict[str, np.ndarray]:
    out = {}
    for part in ("fine", "coarse", "pool"):
        for name, value in getattr(geo, part)._asdict().items():
            if value is not None:  # optional fields (log_unit) default to None
                out[f"{part}.{name}"] = np.asarray(value)
    return out


def _geometry_from(arrays: dict[str, np.ndarray]) -> DenoiserGeometry:
    def part(cls, name):
        return cls(**{f: arrays[f"{name}.{f}"] for f in cls._fields if f"{name}.{f}" in arrays})

    return DenoiserGeometry(
        part(VertexNeighborhood, "fine"),
        part(VertexNeighborhood, "coarse"),
        part(PoolingMap, "pool"),
    )


def _save_copy(
    path: pathlib.Path, copy: Mesh, geo: DenoiserGeometry, mu: np.ndarray, labels, extra=None
) -> None:
    from ..io import atomic_save_npz

    arrays = {"vertices": copy.vertices, "faces": copy.faces, "mu": mu, **_geometry_arrays(geo)}
    if labels is not None:
        arrays["labels"] = labels
    if extra is not None:
        arrays["mu_extra"] = extra
    atomic_save_npz(path, arrays)


def _load_copy(path: pathlib.Path):
    from ..io import load_npz

    a = load_npz(path, "FLDM training copy")
    try:
        copy = (Mesh(a["vertices"], a["faces"]), _geometry_from(a), a["mu"], a.get("labels"))
        return (*copy, a["mu_extra"]) if "mu_extra" in a else copy
    except KeyError as err:
        raise MeshIOError(
            f"{path}: incomplete FLDM training copy (missing {err}); delete it to rebuild"
        ) from err


def stack_copies(
    copies: list[tuple[Mesh, DenoiserGeometry, np.ndarray, np.ndarray | None]], config: Config
) -> Dataset:
    """Pad every copy to the bucketed common shape and stack them (see the module docstring).

    Args:
      copies: one ``(mesh, geometry, latents [V, d], labels [V] or None)`` per copy (labels all
        given or all None), optionally with a fifth entry ``[K − 1, V, d]`` further encodings
        (all copies or none).
      config: :class:`~jmeshtex.fldm.Config` (``bucket``, ``latent_scaling``).

    Returns:
      :class:`~jmeshtex.fldm.Dataset`; ``V₀`` and ``V₁`` rounded up to a multiple of ``bucket`` (``bucket // 4``
      for the coarse level).

    Example:
      >>> from jmeshtex.data import icosphere
      >>> m = icosphere(1)
      >>> g = denoiser_geometry(m, knn=7)
      >>> d = stack_copies([(m, g, np.ones((42, 1), complex), None)], Config.tiny(bucket=32))
      >>> d.latents.shape, d.num_vertices.tolist(), d.scale.tolist()
      ((1, 64, 1), [42], [1.0])
    """
    extras = [c[4] if len(c) > 4 else None for c in copies]
    copies = [tuple(c[:4]) for c in copies]
    if any(e is None for e in extras) != all(e is None for e in extras):
        raise InputError("stack_copies: give further encodings for every copy or for none")
    sizes = [geometry_sizes(g) for _, g, _, _ in copies]
    V0, V1 = _bucketed_vertices(
        max(s["V0"] for s in sizes), max(s["V1"] for s in sizes), config.bucket
    )
    M = max(s["M"] for s in sizes)
    geos = [pad_geometry(g, V0=V0, V1=V1, M=M) for _, g, _, _ in copies]
    geometry = jax.tree.map(lambda *xs: np.stack(xs), *geos)
    d = copies[0][2].shape[1]
    latents = np.zeros((len(copies), V0, d), np.complex128)
    labels = None if copies[0][3] is None else np.zeros((len(copies), V0), np.int32)
    for i, (m, _, mu, lab) in enumerate(copies):
        latents[i, : m.num_vertices] = mu
        if labels is not None:
            labels[i, : m.num_vertices] = lab
    encodings = None
    if extras[0] is not None:
        encodings = np.zeros((len(copies), extras[0].shape[0], V0, d), np.complex64)
        for i, (m, _, _, _) in enumerate(copies):
            encodings[i, :, : m.num_vertices] = extras[i]
    nv = np.array([m.num_vertices for m, _, _, _ in copies])
    mask = np.arange(V0)[None] < nv[:, None]
    scale = latent_scale(
        latents,
        mask,
        per_channel=config.latent_scaling == "per_channel",
        released=config.latent_scaling == "released",
    )
    return Dataset(
        latents, geometry, labels, nv, scale, tuple(m for m, _, _, _ in copies), encodings
    )


def build_dataset(
    mesh: Mesh,
    config: Config,
    *,
    encode: Callable[[Mesh], np.ndarray],
    key: jax.Array,
    labels: np.ndarray | None = None,
    cache_dir: str | os.PathLike | None = None,
    progress: bool = True,
) -> Dataset:
    """Re-triangulated copies of ``mesh`` with geometry and latents, cached on disk, padded and stacked.

    Args:
      mesh: the textured (or vertex-coloured) input :class:`~jmeshtex.Mesh`.
      config: :class:`Config` (``n_copies``, ``copy_vertices``, ``knn``, ``pool_ratio``,
        ``bucket``; ``num_labels`` when ``labels`` are given).
      encode: ``Mesh -> complex [V, d]`` latents of a copy in its one-ring frames
        (:func:`fl_vae_encoder`, or any stand-in with the same contract). An ``identity`` attribute,
        if present, is recorded so that a cache built with another encoder is not reused.
      key: PRNG key of the re-triangulations (the same key gives the same copies).
      labels: optional ``[V]`` int labels on ``mesh`` in ``[0, num_labels)``.
      cache_dir: folder for ``copy_####.npz`` and ``data.json`` (None: no cache).
      progress: tqdm bar.

    With ``config.experimental.encodings_per_copy = K > 1`` each copy is encoded ``K`` times (``encode`` is
    called again; :func:`fl_vae_encoder` draws new one-ring samples each call): the first in
    ``latents`` (and the scale), the others in ``Dataset.encodings``.

    Returns:
      :class:`Dataset`.

    Raises:
      ConfigError: ``encode`` not callable; labels given but ``num_labels`` is 0 (or labels out of
        range); latents with the wrong channel count.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> import jax
      >>> cfg = Config.tiny(n_copies=2, copy_vertices=60, latent_channels=1, bucket=32)
      >>> enc = lambda m: m.vertices[:, :1] + 0j
      >>> data = build_dataset(icosphere(1), cfg, encode=enc, key=jax.random.key(0), progress=False)
      >>> data.latents.shape, data.num_vertices.tolist()
      ((2, 64, 1), [60, 60])
    """
    from tqdm.auto import tqdm

    mesh = as_mesh(mesh)
    _check_encoder_and_labels(encode, labels, config)
    sync = _phase_synchronizer(mesh, config, encode)
    meta = _cache_record(mesh, config, encode, labels, key)
    cache, reuse = _open_cache(cache_dir, meta)
    copies = []
    bar = tqdm(range(config.n_copies), desc="FLDM copies", unit="copy", disable=not progress)
    for i in bar:
        path = None if cache is None else cache / f"copy_{i:04d}.npz"
        if path is not None and reuse and path.is_file():
            copies.append(_load_copy(path))
            continue
        copy = _build_copy(mesh, config, i, key=key, encode=encode, labels=labels, sync=sync)
        if path is not None:
            _save_copy(path, *copy)
        copies.append(copy)
    return stack_copies(copies, config)


def _check_encoder_and_labels(encode, labels: np.ndarray | None, config: Config) -> None:
    """Refuse a non-callable ``encode`` and labels that do not match ``config.num_labels``."""
    if not callable(encode):  # checked before the cache is touched: a stale cache is cleared below
        raise ConfigError(
            f"encode must be a callable Mesh -> complex [V, d] (e.g. fl_vae_encoder), got {encode!r}"
        )
    if labels is not None:
        if not config.num_labels:
            raise ConfigError(
                "labels given but config.num_labels is 0; set num_labels to the number of classes"
            )
        lab = np.asarray(labels)
        if lab.size and (lab.min() < 0 or lab.max() >= config.num_labels):
            raise ConfigError(
                f"labels must lie in [0, {config.num_labels}), got {lab.min()}..{lab.max()}"
            )
    elif config.num_labels:
        raise ConfigError(f"config.num_labels={config.num_labels} but no labels were given")


def _cache_record(mesh: Mesh, config: Config, encode, labels, key: jax.Array) -> dict:
    """What ``data.json`` records: everything a cached copy was built from (module docstring)."""
    return {
        "format": DATA_VERSION,
        "mesh": _digest([mesh.vertices, mesh.faces]),
        "colors": _digest(_color_arrays(mesh)),
        "labels": None if labels is None else _digest([np.asarray(labels)]),
        "encoder": getattr(encode, "identity", None),
        "copy_vertices": config.copy_vertices,
        "knn": config.knn,
        "pool_ratio": config.pool_ratio,
        "key": key_ints(key),
        "latent_channels": config.latent_channels,
        "encodings_per_copy": config.experimental.encodings_per_copy,
        "phase_sync": config.experimental.phase_sync,
        "flat_spread": config.experimental.flat_spread
        if config.experimental.phase_sync == "flat"
        else None,
    }


def _open_cache(cache_dir, meta: dict) -> tuple[pathlib.Path | None, bool]:
    """The cache folder (None: no cache) and whether its copies can be reused: its ``data.json``
    equals ``meta`` and the encoder has an identity; otherwise its copies are deleted and ``meta``
    written."""
    if cache_dir is None:
        return None, False
    cache = pathlib.Path(cache_dir)
    cache.mkdir(parents=True, exist_ok=True)
    meta_path = cache / DATA_FILE
    reuse = (
        meta_path.is_file()
        and meta["encoder"] is not None
        and json.loads(meta_path.read_text()) == meta
    )
    if not reuse:
        from ..io import atomic_write

        for old in cache.glob("copy_*.npz"):
            old.unlink()
        atomic_write(meta_path, json.dumps(meta, indent=2).encode())
    return cache, reuse


def _build_copy(mesh: Mesh, config: Config, i: int, *, key, encode, labels, sync) -> tuple:
    """Copy ``i`` (module docstring, steps 1–5): ``(mesh, geometry, latents, labels)`` plus, with
    ``config.experimental.encodings_per_copy > 1``, its further encodings ``[K − 1, V, d]`` complex64."""
    copy = copy_mesh(mesh, config, i, key=key)
    geo = denoiser_geometry(copy, knn=config.knn, pool_ratio=config.pool_ratio)
    mu = np.asarray(encode(copy))
    if mu.shape != (copy.num_vertices, config.latent_channels) or not np.iscomplexobj(mu):
        raise ConfigError(
            f"encode returned {mu.dtype} {mu.shape}; expected complex [V, d] = ({copy.num_vertices}, "
            f"{config.latent_channels}) (set latent_channels to the FL-VAE's latent_dim)"
        )
    lab = None if labels is None else transfer_labels(mesh, labels, copy)
    fix = sync(copy, geo)
    mu = fix(mu)
    if config.experimental.encodings_per_copy <= 1:
        return (copy, geo, mu, lab)
    extra = np.stack(
        [fix(np.asarray(encode(copy))) for _ in range(config.experimental.encodings_per_copy - 1)]
    ).astype(np.complex64)
    return (copy, geo, mu, lab, extra)


def _phase_synchronizer(mesh: Mesh, config: Config, encode):
    """``sync(copy, geometry) -> (mu -> mu)``: ``config.experimental.phase_sync`` applied to one copy's encodings."""
    if config.experimental.phase_sync == "none":
        return lambda copy, geo: lambda mu: mu
    colors = None
    if config.experimental.phase_sync == "flat":
        colors = getattr(encode, "colors", None)
        if colors is None:
            if not (mesh.has_texture or mesh.vertex_colors is not None):
                raise ConfigError(
                    "phase_sync='flat' needs the input's colours to find its flat rings, but the mesh "
                    "has neither a texture nor vertex colours; use phase_sync='none' (or 'all')"
                )
            from .. import fl

            colors = fl.core.surface_colors(mesh)

    return lambda copy, geo: lambda mu: _synchronized(mu, copy, geo, config, colors)


def batch_geometry(data: Dataset, index: np.ndarray) -> DenoiserGeometry:
    """The geometry of some copies (leading axis ``len(index)``)."""
    return jax.tree.map(lambda a: a[index], data.geometry)

"""Run generators trained with the official DGTS code (amirhertz/geometric-textures) in jmeshtex.

The official ``SingleMeshGenerator`` keeps one ``MultiMeshConv`` per level under
``levels.<l>.layers.<i>...`` in its ``state_dict``: ``Conv1d`` weights ``[out, in, 1]``, layer 0 on
the 4 features of each edge, layers ``i ≥ 1`` on ``[x_across ; x_self]`` (``in = 2C``), every layer
but the last followed by ``InstanceNorm1d`` (no affine) and ``LeakyReLU(0.2)``. Its conventions
differ from :mod:`jmeshtex.ops`' in two places, which the converter absorbs into the weights:

- feature order: official ``(x, y, z, length)`` per edge, jmeshtex ``(length, x, y, z)``;
- the in-plane axis: official ``y = x × n``, jmeshtex ``y = n × x`` (:func:`~jmeshtex.ops.edge_frames`),
  so the official ``y`` feature changes sign (folded into the first layer's weights, exact: the
  map is linear before the max over edges) and so does the ``y`` displacement coefficient. That
  one cannot be folded into the last layer (a max over neighbours follows its linear map:
  ``max(−a) ≠ −max(a)``); a converted model carries ``Config(official_axes=True)`` instead, which
  makes the generator read its ``y`` coefficient along ``x × n`` (:attr:`Config.y_sign`).

Everything else (edge ``k`` = ``(f[k], f[(k+1) % 3])``, apex of the face across edge ``k`` minus the
edge midpoint, the max over the three edges, the mean over a vertex's corners) agrees, so a
converted level reproduces the official stack output and ``forward_level`` to float32 rounding
(tested against the official network's outputs, ``tests/dgts/test_official_parity.py``). One difference remains on open meshes:
on a boundary edge the official features use the edge midpoint (all zero), jmeshtex the face's own
apex (:func:`~jmeshtex.ops.face_features`); closed meshes are unaffected.

To run a model trained with the official code, export its generator's ``state_dict`` to ``.npz``
once (in the official environment)::

    np.savez("official.npz", **{k: v.cpu().numpy() for k, v in generator.state_dict().items()})

then ``model = dgts.load_official("official.npz")`` and use it with :func:`~jmeshtex.dgts.transfer`.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping

import jax
import numpy as np

from .._errors import ConfigError, InputError, MeshIOError
from ..ops import FaceConvParams, FaceConvStackParams, FaceEmbedParams
from ._config import Config
from ._model import Model
from ._networks import init_level

#: official feature index of each jmeshtex feature (length, x, y, z) and its sign
_FEATURE_FROM_OFFICIAL = np.array([3, 0, 1, 2])
_FEATURE_SIGN = np.array([1.0, 1.0, -1.0, 1.0])

_KEY = re.compile(r"^(?:module\.)?levels\.(\d+)\.layers\.(\d+)\.(?:0\.)?conv\.(weight|bias)$")


def _official_layers(
    state_dict: Mapping[str, np.ndarray],
) -> dict[int, dict[int, dict[str, np.ndarray]]]:
    """``{level: {layer: {"weight", "bias"}}}`` from official state-dict names (other keys ignored)."""
    levels: dict[int, dict[int, dict[str, np.ndarray]]] = {}
    for name in state_dict:
        m = _KEY.match(str(name))
        if m is None:
            continue
        level, layer, kind = int(m[1]), int(m[2]), m[3]
        levels.setdefault(level, {}).setdefault(layer, {})[kind] = np.asarray(
            state_dict[name], np.float32
        )
    return levels


def official_level_params(
    state_dict: Mapping[str, np.ndarray], level: int, *, critic: bool = False
) -> FaceConvStackParams:
    """Convert one level of an official ``SingleMeshGenerator`` (or ``SingleMeshDiscriminator``)
    state dict to jmeshtex parameters.

    With ``W_i`` the official ``Conv1d`` weights ``[out, in, 1]``:

    .. math:: E = \\operatorname{diag}(s)\\, W_0[:, \\pi, 0]^\\top,\\quad \\pi = (3, 0, 1, 2),
       \\ s = (1, 1, -1, 1);\\qquad C_i = W_i[:, :, 0]^\\top

    (the feature reorder and the ``y`` sign of the module docstring). The output coefficients are
    the official ones, ``(c_x, c_y, c_z)`` with ``c_y`` along ``x × n``: run the level with
    ``generator_level(..., y_sign=-1.0)`` (what ``Config(official_axes=True)`` does). A critic's
    single score needs no such care: its converted level gives the official scores as they are.

    Args:
      state_dict: name → array, e.g. ``np.load("official.npz")`` (names ``levels.<l>.layers.<i>.0.conv.weight``
        / ``.bias``, the last layer without the ``.0``); other keys are ignored.
      level: which level to convert.
      critic: a discriminator's level (last width 1) instead of a generator's (last width 3).

    Returns:
      :class:`~jmeshtex.ops.FaceConvStackParams` (float32) for :func:`~jmeshtex.dgts.core.generator_level`.

    Raises:
      InputError: the level is missing, a layer lacks its weight or bias, or shapes do not chain.

    Example:
      >>> import numpy as np
      >>> sd = {"levels.0.layers.0.0.conv.weight": np.ones((8, 4, 1)), "levels.0.layers.0.0.conv.bias": np.zeros(8),
      ...       "levels.0.layers.1.conv.weight": np.ones((3, 16, 1)), "levels.0.layers.1.conv.bias": np.zeros(3)}
      >>> p = official_level_params(sd, 0)
      >>> p.embed.weight.shape, p.convs[0].weight.shape, p.embed.weight[:, 0].tolist()
      ((4, 8), (16, 3), [1.0, 1.0, -1.0, 1.0])
    """
    levels = _official_layers(state_dict)
    if level not in levels:
        raise InputError(
            f"official_level_params: no level {level} in the state dict (levels found: "
            f"{sorted(levels)}); names must look like 'levels.<l>.layers.<i>.0.conv.weight'"
        )
    out = _official_level_arrays(levels[level], level)
    w0, b0 = out[0]
    if w0.shape[0] != 4:
        raise InputError(
            f"official_level_params: layer 0 must take the 4 edge features, got in = {w0.shape[0]}"
        )
    embed = FaceEmbedParams(
        (w0[_FEATURE_FROM_OFFICIAL] * _FEATURE_SIGN[:, None]).astype(np.float32), b0
    )
    convs = []
    width = w0.shape[1]
    for i, (w, b) in enumerate(out[1:], start=1):
        if w.shape[0] != 2 * width:
            raise InputError(
                f"official_level_params: level {level} layer {i} takes in = {w.shape[0]}, but the "
                f"previous layer gives {width} channels (expected in = {2 * width})"
            )
        width = w.shape[1]
        convs.append([w, b])
    if width != (1 if critic else 3):
        raise InputError(
            "official_level_params: the last layer must give "
            f"{'1 critic score' if critic else '3 displacement coefficients'}, got {width}"
        )
    return FaceConvStackParams(
        embed,
        tuple(
            FaceConvParams(np.asarray(w, np.float32), np.asarray(b, np.float32)) for w, b in convs
        ),
    )


def _official_level_arrays(layers: Mapping[int, dict], level: int) -> list[tuple]:
    """``(weight [in, out], bias [out])`` of each layer of one official level, checked."""
    if sorted(layers) != list(range(len(layers))) or len(layers) < 2:
        raise InputError(
            f"official_level_params: level {level} has layers {sorted(layers)}; expected 0 … n−1, n ≥ 2"
        )
    out = []
    for i in range(len(layers)):
        entry = layers[i]
        if set(entry) != {"weight", "bias"}:
            raise InputError(
                f"official_level_params: level {level} layer {i} lacks its "
                f"{'bias' if 'weight' in entry else 'weight'}"
            )
        w, b = entry["weight"], entry["bias"]
        if w.ndim != 3 or w.shape[2] != 1 or b.shape != w.shape[:1]:
            raise InputError(
                f"official_level_params: level {level} layer {i}: Conv1d weight [out, in, 1] and "
                f"bias [out] expected, got {w.shape} and {b.shape}"
            )
        out.append((w[:, :, 0].T.copy(), b.copy()))
    return out


def to_official_state_dict(model: Model) -> dict[str, np.ndarray]:
    """The inverse of :func:`~jmeshtex.dgts.from_official_state_dict`: a model's generators under official names.

    Only a model with ``config.experimental.official_axes`` (a converted one, or one trained with that flag) has
    an exact official equivalent: with jmeshtex's axis the ``y`` displacement would need a min
    where the official network takes a max.

    Returns:
      ``{"levels.<l>.layers.<i>.0.conv.weight": [out, in, 1], ...}`` float32 (the last layer of a level
      without the ``.0``, as ``MultiMeshConv`` names it), loadable by the official
      ``SingleMeshGenerator.load_state_dict`` (its generator part).

    Raises:
      ConfigError: ``model.config.experimental.official_axes`` is False.

    Example:
      >>> import jax
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4, official_axes=True)
      >>> g = init_level(c, 0, generator=True, key=jax.random.key(0))
      >>> m = Model(c, (g,), (init_level(c, 0, generator=False, key=jax.random.key(1)),), np.zeros((12, 3), np.float32))
      >>> sorted(to_official_state_dict(m))[:2]
      ['levels.0.layers.0.0.conv.bias', 'levels.0.layers.0.0.conv.weight']
    """
    if not model.config.experimental.official_axes:
        raise ConfigError(
            "to_official_state_dict: the model uses jmeshtex's in-plane axis (n × x); only a model "
            "with Config(official_axes=True) has an exact official equivalent"
        )
    out = {}
    for level, p in enumerate(model.generators):
        out.update(official_level_state(p, level))
    return out


def official_level_state(params: FaceConvStackParams, level: int) -> dict[str, np.ndarray]:
    """The inverse of :func:`official_level_params`: one level under official state-dict names.

    Linear in ``params`` (a reorder and one sign), so it also maps gradients and Adam first
    moments of a converted level to the official layout (second moments: take ``abs`` after).

    Args:
      params: a level's stack (a generator's or a critic's).
      level: the level index in the names.

    Returns:
      ``{"levels.<level>.layers.<i>.0.conv.weight": [out, in, 1], ...}`` float32, the last layer
      without the ``.0``.

    Example:
      >>> import jax
      >>> from jmeshtex.ops import init_face_conv_stack
      >>> p = init_face_conv_stack(jax.random.key(0), (8, 1))
      >>> sorted(official_level_state(p, 2))[-1], official_level_state(p, 2)["levels.2.layers.1.conv.weight"].shape
      ('levels.2.layers.1.conv.weight', (1, 16, 1))
    """
    w0 = np.zeros((4, np.shape(params.embed.weight)[1]), np.float32)
    w0[_FEATURE_FROM_OFFICIAL] = (
        np.asarray(params.embed.weight, np.float32) * _FEATURE_SIGN[:, None]
    )
    layers = [(w0, np.asarray(params.embed.bias, np.float32))]
    for c in params.convs:
        layers.append((np.asarray(c.weight, np.float32), np.asarray(c.bias, np.float32)))
    out = {}
    for i, (w, b) in enumerate(layers):
        name = f"levels.{level}.layers.{i}" + ("" if i == len(layers) - 1 else ".0")
        out[f"{name}.conv.weight"] = np.ascontiguousarray(w.T[:, :, None], np.float32)
        out[f"{name}.conv.bias"] = np.asarray(b, np.float32)
    return out


def from_official_state_dict(
    state_dict: Mapping[str, np.ndarray],
    *,
    config: Config | None = None,
    z_star: np.ndarray | None = None,
) -> Model:
    """A :class:`~jmeshtex.dgts.Model` from an official ``SingleMeshGenerator`` state dict (all levels).

    Every level ``0 … L−1`` found is converted with :func:`~jmeshtex.dgts.core.official_level_params`; the widths must be
    those of ``config`` (default :class:`~jmeshtex.dgts.Config`, the official default ``Options``:
    7 layers, 32 → 128 channels); the model's config is ``config`` with ``official_axes=True``.
    The official discriminators are not part of a generator's state
    dict: the model gets freshly initialised critics (key 0; they only matter to continue training).

    Args:
      state_dict: name → array (other keys are ignored).
      config: the architecture the weights were trained with (its noise amplitude and scale factor
        are used by :func:`~jmeshtex.dgts.transfer`).
      z_star: ``[V_0, 3]`` the official run's fixed reconstruction noise, if known (needed only by
        :func:`~jmeshtex.dgts.reconstruct` / conditional generation); default ``[0, 3]``.

    Returns:
      The :class:`~jmeshtex.dgts.Model`.

    Raises:
      InputError: no level found, levels not ``0 … L−1``, or a level's shapes do not convert.
      ConfigError: a level's widths differ from ``config.level_features``.

    Example:
      >>> import jax
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4, official_axes=True)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(2))
      >>> m = Model(c, gs, gs, np.zeros((12, 3), np.float32))
      >>> back = from_official_state_dict(to_official_state_dict(m), config=c)
      >>> back.num_levels, back.config.experimental.official_axes, bool(np.allclose(back.generators[1].embed.weight, gs[1].embed.weight))
      (2, True, True)
    """
    config = (Config() if config is None else config).replace(official_axes=True)
    found = sorted(_official_layers(state_dict))
    if not found:
        raise InputError(
            "from_official_state_dict: no 'levels.<l>.layers.<i>...conv.weight' keys found"
        )
    if found != list(range(len(found))):
        raise InputError(
            f"from_official_state_dict: levels {found} found; a model needs levels 0 … L−1 "
            "(convert a single level with official_level_params)"
        )
    gens, discs = [], []
    for level in found:
        p = official_level_params(state_dict, level)
        widths = (int(np.shape(p.embed.weight)[1]), *(int(np.shape(c.weight)[1]) for c in p.convs))
        expected = config.level_features(level, generator=True)
        if widths != expected:
            raise ConfigError(
                f"from_official_state_dict: level {level} has widths {widths}, the config gives "
                f"{expected}; pass the Config (num_layers, start/min/max_features) it was trained with"
            )
        gens.append(p)
        discs.append(
            init_level(
                config, level, generator=False, key=jax.random.fold_in(jax.random.key(0), level)
            )
        )
    z = np.zeros((0, 3), np.float32) if z_star is None else np.asarray(z_star, np.float32)
    if z.ndim != 2 or z.shape[1] != 3:
        raise InputError(f"from_official_state_dict: z_star must be [V_0, 3], got {z.shape}")
    return Model(config, tuple(gens), tuple(discs), z)


def load_official(
    path: str | os.PathLike, *, config: Config | None = None, z_star: np.ndarray | None = None
) -> Model:
    """Read an official generator state dict saved as ``.npz`` (module docstring) into a Model.

    Args:
      path: the ``.npz`` (arrays only; read with ``allow_pickle=False``).
      config, z_star: as :func:`from_official_state_dict`.

    Returns:
      The :class:`~jmeshtex.dgts.Model`.

    Raises:
      MeshIOError: the file cannot be read as ``.npz``.
      InputError, ConfigError: as :func:`from_official_state_dict`.

    Example:
      >>> import jax, tempfile, pathlib
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4, official_axes=True)
      >>> gs = (init_level(c, 0, generator=True, key=jax.random.key(0)),)
      >>> path = pathlib.Path(tempfile.mkdtemp()) / "official.npz"
      >>> np.savez(path, **to_official_state_dict(Model(c, gs, gs, np.zeros((12, 3), np.float32))))
      >>> load_official(path, config=c).num_levels
      1
    """
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files if _KEY.match(k)}
    except (OSError, ValueError) as err:
        raise MeshIOError(f"cannot read {path} as an .npz of official DGTS weights: {err}") from err
    return from_official_state_dict(arrays, config=config, z_star=z_star)

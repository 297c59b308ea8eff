"""Registers the FL-VAE encoder and decoder in the equivariance harness (:mod:`jmeshtex.testing`).

The one-ring samples of the registered operators come from the deterministic per-wedge rule of
:func:`~jmeshtex.fl.core.one_ring_samples` (``rng=None``), so relabelling a mesh only reorders the sample
set; colours at the samples are the barycentric interpolation of a random per-vertex colour field.

- ``fl.encoder.mu``: μ is a tangent field — it turns with gauge changes (``μ_p e^{-iα_p}``) and is
  unchanged by isometries and relabelling (everything is computed from edge lengths);
- ``fl.encoder.log_sigma``: invariant (a vertex scalar);
- ``fl.decoder``: decoded colours at each vertex and averaged over its samples, from a random latent
  field: invariant scalars.

Importing this module registers the entries (:func:`jmeshtex.testing.load_entries` imports it).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from .. import Entry, Field, register
from .._fields import VERTEX_SCALAR, VERTEX_TANGENT
from .._registry import EXACT

#: exact transforms asserted for every FL-VAE entry (1e-10 in float64): the intrinsic operators'
#: exact transforms but the reflection
FL_TRANSFORMS = tuple(t for t in EXACT if t != "reflection")
#: smooth isometries: the decoder converges at order ~1.8 and is asserted; the encoder is reported
#: only — its errors do fall with refinement (4e-4 at 48² on the cylinder) but the per-halving ratio
#: dips below the harness's bound of 3 (observed 1.7–3.6): the attention softmax amplifies the
#: O(h²) metric error unevenly across vertices. Re-triangulation moves the samples: reported only.
SMOOTH = ("cylinder", "cone")


def _config():
    from ...fl import Config

    return Config(latent_dim=3, features=8, num_heads=2, num_blocks=1, decoder_features=16)


def _init(key, dtype):
    from ...fl import init

    return init(_config(), key=key, dtype=dtype).params


def _samples(state):
    """Deterministic one-ring samples in the state's gauge (host, cached per state)."""
    from ...fl.core import one_ring_samples

    def build():
        s = one_ring_samples(state.vertices, state.faces, 1, rng=None, center=True)
        log = s.log * np.exp(-1j * state.gauge)[:, None]
        return s._replace(log=log)

    return state.cached("fl_samples", build)


@functools.lru_cache(maxsize=1)
def _jitted():
    """Jitted encoder/decoder (op-by-op dispatch under ``jax_debug_nans`` is ~50x slower)."""
    from ...fl.core import decode_points, encode_samples

    return jax.jit(encode_samples, static_argnums=1), jax.jit(decode_points, static_argnums=1)


def _encode(state, params, c, cfg=None):
    encode_samples = _jitted()[0]
    s = _samples(state)
    corners = state.cached("fl_corners", lambda: state.faces[_samples(state).face])  # [V, S, 3]
    rgb = jnp.einsum(
        "vsk,vskc->vsc", jnp.asarray(s.bary, state.dtype), jnp.asarray(c, state.dtype)[corners]
    )
    return encode_samples(
        params, cfg or _config(), jnp.asarray(s.log, state.complex_dtype), rgb, jnp.asarray(s.mask)
    )


def _encoder_mu(state, params, c):
    return Field(VERTEX_TANGENT, _encode(state, params, c).mu)


def _encoder_sigma(state, params, c):
    return Field(VERTEX_SCALAR, _encode(state, params, c).log_sigma)


def _decoder(state, params, z, cfg=None):
    from ...fl.core import decode_vertex_colors_from_latents

    decode_points = _jitted()[1]
    s = _samples(state)
    cfg = cfg or _config()
    pred = decode_points(params, cfg, z, jnp.asarray(s.log, state.complex_dtype))
    m = jnp.asarray(s.mask, pred.dtype)[..., None]
    mean = jnp.sum(pred * m, axis=1) / jnp.maximum(jnp.sum(m, axis=1), 1)
    return Field(
        VERTEX_SCALAR,
        jnp.concatenate([decode_vertex_colors_from_latents(params, cfg, z), mean], axis=1),
    )


#: what every FL-VAE entry shares: the test network's parameters, the group, the resolutions
_COMMON = {"init": _init, "group": "models", "resolutions": (6, 12, 24, 48)}
ENTRIES = (
    Entry(
        "fl.encoder.mu",
        _encoder_mu,
        {"c": (VERTEX_SCALAR, 3)},
        FL_TRANSFORMS,
        report=(*SMOOTH, "retriangulate"),
        doc="FL-VAE encoder mean: tangent latents turn with the gauge, invariant to isometries",
        **_COMMON,
    ),
    Entry(
        "fl.encoder.log_sigma",
        _encoder_sigma,
        {"c": (VERTEX_SCALAR, 3)},
        FL_TRANSFORMS,
        report=(*SMOOTH, "retriangulate"),
        doc="FL-VAE encoder log σ: invariant scalars",
        **_COMMON,
    ),
    Entry(
        "fl.decoder",
        _decoder,
        {"z": (VERTEX_TANGENT, 3)},
        (*FL_TRANSFORMS, *SMOOTH),
        report=("retriangulate",),
        doc="FL-VAE decoder: colours at vertices and one-ring samples are gauge-invariant",
        **_COMMON,
    ),
)


def _preset(name):
    """The network of ``Config.<name>()`` (training fields at their defaults)."""
    from ...fl import Config

    return getattr(Config, name)().architecture()


def _preset_init(name, key, dtype):
    from ...fl import init

    return init(_preset(name), key=key, dtype=dtype).params


def _preset_mu(name, state, params, c):
    return Field(VERTEX_TANGENT, _encode(state, params, c, _preset(name)).mu)


def _preset_decoder(name, state, params, z):
    return _decoder(state, params, z, _preset(name))


#: transforms of the paper-size encoder that are only reported by the registry: its float32 round-off
#: through 8 VN-Transformer layers reaches 1.7e-5 relative under a gauge change or a face relabelling
#: (above the harness's float32 bound of 1e-5); in float64 they are exact (≤ 1e-10) and
#: tests/fl/test_vae_equivariance.py asserts them there
PAPER_FLOAT32_REPORTED = ("gauge", "permute_faces", "rotate_corners")


def _preset_transforms(name):
    if name == "paper":
        return tuple(
            t for t in FL_TRANSFORMS if t not in PAPER_FLOAT32_REPORTED
        ), PAPER_FLOAT32_REPORTED
    return FL_TRANSFORMS, ()


#: the presets' networks (``Config.small()``, ``Config.paper()``: C = 128, 8 layers × 8 heads, decoder
#: 5 × 512) on the exact transforms; their latent width is the paper's d = 8
PRESET_ENTRIES = tuple(
    entry
    for name in ("small", "paper")
    for entry in (
        Entry(
            f"fl.{name}.encoder.mu",
            functools.partial(_preset_mu, name),
            {"c": (VERTEX_SCALAR, 3)},
            _preset_transforms(name)[0],
            init=functools.partial(_preset_init, name),
            group="models",
            report=_preset_transforms(name)[1],
            doc=f"FL-VAE encoder mean at Config.{name}(): tangent latents turn with the gauge",
        ),
        Entry(
            f"fl.{name}.decoder",
            functools.partial(_preset_decoder, name),
            {"z": (VERTEX_TANGENT, 8)},
            FL_TRANSFORMS,
            init=functools.partial(_preset_init, name),
            group="models",
            doc=f"FL-VAE decoder at Config.{name}(): decoded colours are gauge-invariant",
        ),
    )
)

for _entry in (*ENTRIES, *PRESET_ENTRIES):
    register(_entry)

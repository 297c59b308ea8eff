"""Registers the FLDM denoiser and sampler in the equivariance harness (:mod:`jmeshtex.testing`).

- ``fldm.denoiser``: ``ε̂(z_t, t)`` at a fixed timestep: tangent latents in, tangent noise out.
  Equivariant to gauge changes, relabelling, rigid motions and exact isometries (folds, hinges);
  the coarse level comes from a greedy decimation, which is not a continuous function of the metric,
  so smooth bendings (cylinder) are reported, not asserted (as for ``ops.tangent_pool_unpool``).
- ``fldm.denoiser_labels``: the same with a per-vertex label map in the filters (labels are the
  argmax of a random scalar field, so they follow relabelling and are unchanged by isometries).
- ``fldm.denoiser_reference_argument`` (negative control): the same denoiser with the reference
  code's filter argument (``get_rel_pos``: ``log_p(q)`` paired with the neighbour's feature
  direction in the *neighbour's* frame, untransported). With log maps in ``p``'s frame that argument
  moves by ``e^{i(α_q − α_p)}`` under a gauge change, so the harness must flag ``gauge``; vertex
  permutations (which keep every frame) must still pass.
- ``fldm.sampler``: *distributional* equivariance. A sampler is a random map; with every random
  draw made an input (initial noise ``z_T`` and the per-step noise of a stochastic DDIM, η = 0.5),
  it is a deterministic map from noise to samples. Tangent noise has the same law in every gauge,
  so pushing the same noise forward by a transform (what the harness does to tangent inputs) must
  give the transformed sample: that is the statement "samples commute with the transform".

- ``fldm.denoiser_mask``: the mask-conditioned denoiser (``Config.mask_conditioning``): the
  inpainting mask (``s > 0`` of a random scalar field, so it follows relabelling) in the filters and
  the known latents (a second tangent input) as extra channels; with the invariant stream
  (``Config.experimental.invariants``: each block's filters also see the powers of its input and their
  neighbourhood means), so one entry covers both per-vertex filter inputs.
- ``fldm.sampler_inpaint``: ancestral DDPM (a 4-step schedule) with the mask-conditioned denoiser
  and replacement inpainting (eq. 14), as a map of its noise (initial, per-step and the known
  region's) and of the known latents.

Importing this module registers the entries (:func:`jmeshtex.testing.load_entries` does).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ...fldm import Config
from ...fldm.core import make_schedule, sample_from_noise
from .. import EXACT, Entry, Field, register
from .._fields import VERTEX_SCALAR, VERTEX_TANGENT
from .._state import regauge_neighborhood

#: transforms the FLDM networks must commute with (smooth bending of the decimation: reported)
FLDM_TRANSFORMS = EXACT
FLDM_REPORT = ("cylinder",)

CONFIG = Config.tiny(
    latent_channels=2,
    widths=(4, 6),
    hdim=4,
    knn=7,
    mlp_layers=2,
    filter_layers=2,
    activation="silu",
    time_features=8,
)
LABEL_CONFIG = CONFIG.replace(num_labels=3)
MASK_CONFIG = CONFIG.replace(mask_conditioning=True, invariants=True)
DDPM_SCHEDULE = make_schedule("linear", num_steps=4)
SAMPLER_STEPS = 3
SAMPLER_SCHEDULE = make_schedule("linear", num_steps=50)
TIMESTEP = 37


def _geometry(state):
    """Denoiser geometry of the state's mesh, fine frames turned to the state's gauge."""
    from ...fldm.core import denoiser_geometry
    from ...geometry import to_jax

    def build():
        geo = denoiser_geometry((state.vertices, state.faces), knn=CONFIG.knn, pool_ratio=0.5)
        fine = regauge_neighborhood(geo.fine, state.gauge)
        pm = geo.pool
        turn = np.exp(1j * state.gauge)
        pm = pm._replace(
            to_parent=pm.to_parent * turn,
            children_transport=np.where(
                pm.children_mask, pm.children_transport * turn[pm.children], pm.children_transport
            ),
        )
        return to_jax(geo._replace(fine=fine, pool=pm), state.dtype)

    return state.cached("fldm_geometry", build)


def _init_for(config):
    def init(key, dtype):
        from ...data import icosahedron
        from ...fldm.core import denoiser_geometry, init_denoiser

        cdt = jnp.complex128 if jnp.dtype(dtype) == jnp.float64 else jnp.complex64
        geo = denoiser_geometry(icosahedron(), knn=config.knn, pool_ratio=0.5)
        params = init_denoiser(key, config, geo, dtype=cdt)
        # random (not unit) FRN gains so the check is not blind to any channel
        return jax.tree.map(
            lambda p: (
                p * (1.0 + 0.5 * jnp.cos(jnp.arange(p.size).reshape(p.shape)).astype(p.dtype))
            ),
            params,
        )

    return init


def _denoiser(state, params, z):
    from ...fldm.core import denoise

    out = denoise(params, CONFIG, z, jnp.asarray(TIMESTEP, jnp.int32), _geometry(state))
    return Field(VERTEX_TANGENT, out)


def _denoiser_labels(state, params, z, s):
    from ...fldm.core import denoise

    labels = jnp.argmax(s, axis=1).astype(jnp.int32)
    out = denoise(
        params, LABEL_CONFIG, z, jnp.asarray(TIMESTEP, jnp.int32), _geometry(state), labels=labels
    )
    return Field(VERTEX_TANGENT, out)


def _denoiser_reference_argument(state, params, z):
    from ...fldm.core import denoise

    out = denoise(
        params,
        CONFIG,
        z,
        jnp.asarray(TIMESTEP, jnp.int32),
        _geometry(state),
        filter_argument="untransported",
    )
    return Field(VERTEX_TANGENT, out)


def _denoiser_mask(state, params, z, known, s):
    from ...fldm.core import denoise

    out = denoise(
        params,
        MASK_CONFIG,
        z,
        jnp.asarray(TIMESTEP, jnp.int32),
        _geometry(state),
        mask=s[:, 0] > 0,
        known=known,
    )
    return Field(VERTEX_TANGENT, out)


def _sampler_inpaint(state, params, z_T, noise, known_noise, known, s):
    from ...fldm.core import Inpaint, denoise

    geo = _geometry(state)
    V, C = z_T.shape
    S = DDPM_SCHEDULE.num_steps
    mask = s[:, 0] > 0

    def steps(x):
        return jnp.transpose(x.reshape(V, S, C), (1, 0, 2))

    def eps(z, t):
        return denoise(params, MASK_CONFIG, z, t, geo, mask=mask, known=known)

    out = sample_from_noise(
        eps,
        DDPM_SCHEDULE,
        z_T,
        steps(noise),
        method="ddpm",
        inpaint=Inpaint(known, mask),
        inpaint_noise=steps(known_noise),
    )
    return Field(VERTEX_TANGENT, out)


def _sampler(state, params, z_T, noise):
    from ...fldm.core import denoise

    geo = _geometry(state)
    V, C = z_T.shape
    step_noise = jnp.transpose(noise.reshape(V, SAMPLER_STEPS, C), (1, 0, 2))

    def eps(z, t):
        return denoise(params, CONFIG, z, t, geo)

    out = sample_from_noise(
        eps, SAMPLER_SCHEDULE, z_T, step_noise, method="ddim", num_steps=SAMPLER_STEPS, eta=0.5
    )
    return Field(VERTEX_TANGENT, out)


def _fldm_entry(name: str, apply, inputs: dict, config, doc: str) -> Entry:
    """Register an FLDM entry: the FLDM transforms and reports, parameters of ``config``."""
    return register(
        Entry(
            name,
            apply,
            inputs,
            FLDM_TRANSFORMS,
            init=_init_for(config),
            group="fldm",
            report=FLDM_REPORT,
            doc=doc,
        )
    )


#: a tangent input with the latent channels of ``CONFIG``
_LATENTS = (VERTEX_TANGENT, CONFIG.latent_channels)
ENTRIES = (
    _fldm_entry(
        "fldm.denoiser",
        _denoiser,
        {"z": _LATENTS},
        CONFIG,
        "FLDM U-Net ε̂(z_t, t): field convs with timestep in the filters, pool/unpool",
    ),
    _fldm_entry(
        "fldm.denoiser_labels",
        _denoiser_labels,
        {"z": _LATENTS, "s": (VERTEX_SCALAR, 3)},
        LABEL_CONFIG,
        "FLDM U-Net with a per-vertex label map (argmax of s) in the filters",
    ),
    register(
        Entry(
            "fldm.denoiser_reference_argument",
            _denoiser_reference_argument,
            {"z": _LATENTS},
            ("permute_vertices",),
            init=_init_for(CONFIG),
            expect_fail=("gauge",),
            group="negative",
            doc="FLDM U-Net with the reference code's untransported filter argument: breaks gauge",
        )
    ),
    _fldm_entry(
        "fldm.denoiser_mask",
        _denoiser_mask,
        {"z": _LATENTS, "known": _LATENTS, "s": (VERTEX_SCALAR, 1)},
        MASK_CONFIG,
        "mask-conditioned FLDM U-Net: inpainting mask in the filters, known latents as channels",
    ),
    _fldm_entry(
        "fldm.sampler_inpaint",
        _sampler_inpaint,
        {
            "z_T": _LATENTS,
            "noise": (VERTEX_TANGENT, CONFIG.latent_channels * DDPM_SCHEDULE.num_steps),
            "known_noise": (VERTEX_TANGENT, CONFIG.latent_channels * DDPM_SCHEDULE.num_steps),
            "known": _LATENTS,
            "s": (VERTEX_SCALAR, 1),
        },
        MASK_CONFIG,
        "ancestral DDPM inpainting (4 steps) with the mask-conditioned denoiser, as a map of its noise",
    ),
    _fldm_entry(
        "fldm.sampler",
        _sampler,
        {"z_T": _LATENTS, "noise": (VERTEX_TANGENT, CONFIG.latent_channels * SAMPLER_STEPS)},
        CONFIG,
        "DDIM sampler (3 steps, η=0.5) as a map of its noise: samples commute with transforms",
    ),
)

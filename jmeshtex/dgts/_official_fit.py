"""The reference code's level-fitting schedule (``PrepareConfig(schedule="official")``, DGTS §3.3).

amirhertz/geometric-textures ``GroundTruthGenerator.optimize`` runs, per level, ``level_iters``
(3000) iterations of ``triangulation_iters`` (3) Adam steps on the regularisers (edge-length spread,
edge entropy, "gravity" Laplacian) followed by ``ch_iters`` (2) Adam steps on the Chamfer and normal
terms, one Adam state for both, learning rate 1e-4, ``3000·(l+1)`` fresh samples on each surface
per Chamfer step. Here the Chamfer steps find nearest neighbours with a KD-tree on the host
(``scipy.spatial.cKDTree``: ``O(n log n)`` per step instead of the ``O(n²)`` dense search, which is
what makes the finest levels (tens of thousands of samples) affordable), then take the gradient step
with the correspondences fixed inside a jit-compiled function (the nearest neighbour is piecewise
constant, so its gradient is the same). Reached through :func:`~jmeshtex.dgts.core.fit_level`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
import optax
import scipy.spatial

from .._training import optimizer_update
from .._types import Array, Float, PRNGKey
from ..ops import safe_norm
from ._config import PrepareConfig
from ._multiscale import (
    _FitGeometry,
    chamfer_objective,
    fit_samples,
    regularizer_loss,
    sample_points,
)


@functools.partial(jax.jit, static_argnames=("config",))
def _reg_steps(v, state, geo, *, config: PrepareConfig):
    """``config.regularizer_steps`` Adam steps on the regularisers (one compiled call)."""
    opt = optax.adam(config.learning_rate)

    def body(_, carry):
        v, state = carry
        g = jax.grad(lambda x: regularizer_loss(x, geo, config=config)[0])(v)
        return optimizer_update(opt, g, state, v)

    return jax.lax.fori_loop(0, config.regularizer_steps, body, (v, state))


_sample = jax.jit(fit_samples, static_argnames=("num_samples",))


def _chamfer_loss(v, geo, key, pt, nt, s2t, t2s, *, config: PrepareConfig, num_samples: int):
    """The Chamfer and normal terms with the correspondences ``s2t``, ``t2s`` fixed."""
    c = config

    def dist(a, b):
        d = safe_norm(a - b)
        return d * d if c.squared_chamfer else d

    ps, ns = sample_points(v, geo.faces, num_samples, key=jax.random.split(key)[0])
    terms = {
        "s2t": jnp.mean(dist(ps, pt[s2t])),
        "t2s": jnp.mean(dist(pt, ps[t2s])),
        "normal_s2t": jnp.mean(1 - jnp.sum(ns * nt[s2t], -1)),
        "normal_t2s": jnp.mean(1 - jnp.sum(nt * ns[t2s], -1)),
    }
    return chamfer_objective(terms, c), terms


@functools.partial(jax.jit, static_argnames=("config", "num_samples"))
def _chamfer_step(v, state, geo, key, pt, nt, s2t, t2s, *, config, num_samples):
    (_, terms), g = jax.value_and_grad(_chamfer_loss, has_aux=True)(
        v, geo, key, pt, nt, s2t, t2s, config=config, num_samples=num_samples
    )
    v, state = optimizer_update(optax.adam(config.learning_rate), g, state, v)
    return v, state, terms


@functools.partial(jax.jit, static_argnames=("config", "num_samples"))
def _chamfer_terms(v, geo, key, pt, nt, s2t, t2s, *, config, num_samples):
    return _chamfer_loss(v, geo, key, pt, nt, s2t, t2s, config=config, num_samples=num_samples)[1]


def _correspondences(v, geo, key, num_samples: int):
    """Fresh samples on both surfaces and their nearest neighbours (KD-trees on the host)."""
    ps, _, pt, nt = jax.device_get(_sample(v, geo, key, num_samples=num_samples))
    s2t = scipy.spatial.cKDTree(pt).query(ps, workers=1)[1]
    t2s = scipy.spatial.cKDTree(ps).query(pt, workers=1)[1]
    return (
        jnp.asarray(pt),
        jnp.asarray(nt),
        jnp.asarray(s2t, jnp.int32),
        jnp.asarray(t2s, jnp.int32),
    )


def fit_official(
    vertices: Float[Array, "V 3"],
    geo: _FitGeometry,
    *,
    config: PrepareConfig,
    num_samples: int,
    key: PRNGKey,
    progress: Callable[[int], None] | None = None,
) -> tuple[Float[Array, "V 3"], dict[str, float]]:
    """``config.steps`` official iterations on one level (module docstring); returns ``(vertices, terms)``."""
    kw = {"config": config, "num_samples": int(num_samples)}
    v = vertices
    state = optax.adam(config.learning_rate).init(v)  # one Adam state for both kinds of step
    for it in range(int(config.steps)):
        if config.regularizer_steps:
            v, state = _reg_steps(v, state, geo, config=config)
        for j in range(config.chamfer_steps):
            k = jax.random.fold_in(jax.random.fold_in(key, it), j)
            pairs = _correspondences(v, geo, k, kw["num_samples"])
            v, state, _ = _chamfer_step(v, state, geo, k, *pairs, **kw)
        if progress is not None and ((it + 1) % 50 == 0 or it + 1 == config.steps):
            progress(it + 1)
    k = jax.random.fold_in(key, int(config.steps) + 1)  # the final terms, on fresh samples
    terms = _chamfer_terms(v, geo, k, *_correspondences(v, geo, k, kw["num_samples"]), **kw)
    reg = regularizer_loss(v, geo, config=config)[1]
    out = {k: float(x) for k, x in {**jax.device_get(terms), **jax.device_get(reg)}.items()}
    return v, out

"""Tangent-feature pooling and unpooling between two levels of a mesh hierarchy.

Features at the fine level live in fine vertices' frames, features at the coarse level in coarse
vertices' frames. Moving a tangent vector between the two levels therefore needs the parallel
transport stored in the :class:`~jmeshtex.PoolingMap` (built on the host by the hierarchy
builder): ``children_transport`` / ``to_parent`` take coordinates in a child's frame to its parent's
frame. Both ops are gauge-equivariant: rotating the frame of a fine vertex by ``β_f`` and of a coarse
vertex by ``α_P`` changes the transports to ``τ e^{i(β_f − α_P)}`` and the features to
``x e^{-iβ_f}`` / ``x e^{-iα_P}``, and the outputs rotate with their own vertex's frame.
"""

from __future__ import annotations

import jax.numpy as jnp

from .._errors import InputError
from .._neighborhoods import PoolingMap
from .._types import Array, ArrayLike, Complex
from ._numerics import check_complex, real_dtype


def tangent_pool(x: Complex[ArrayLike, "Vf C"], pm: PoolingMap) -> Complex[Array, "Vc C"]:
    """Area-weighted mean of the children's features, transported into the parent's frame.

    .. math:: y_P = \\frac{\\sum_{f \\in \\mathrm{ch}(P)} w_f\\, \\tau_{f\\to P}\\, x_f}
       {\\sum_{f \\in \\mathrm{ch}(P)} w_f}

    with ``w_f`` the child's area weight (``children_weight``, mask folded in) and ``τ`` the unit
    complex transport ``children_transport``. A coarse vertex without children (padding) gets 0.

    Args:
      x: ``[Vf, C]`` complex features at the fine level, each in its fine vertex's frame.
      pm: the :class:`~jmeshtex.PoolingMap` between the two levels (possibly padded).

    Returns:
      ``[Vc, C]`` complex features, each in its coarse vertex's frame; dtype of ``x``.

    Example:
      >>> import numpy as np
      >>> pm = PoolingMap(parent=np.array([0, 0]), to_parent=np.array([1, 1j]),
      ...     children=np.array([[0, 1]]), children_mask=np.array([[True, True]]),
      ...     children_weight=np.array([[1.0, 3.0]]), children_transport=np.array([[1, 1j]]))
      >>> tangent_pool(jnp.array([[2 + 0j], [-1j]]), pm).tolist()  # (1·2 + 3·(1j·-1j)) / 4
      [[(1.25+0j)]]
    """
    check_complex(x, "tangent_pool", ndim_min=2)
    _check_map(x, pm, "tangent_pool", fine=True)
    rdt = real_dtype(x.dtype)
    mask = jnp.asarray(pm.children_mask).astype(bool)
    # padded slots may hold anything (NaN included): select before multiplying
    w = jnp.where(mask, jnp.asarray(pm.children_weight).astype(rdt), 0)
    w = w / jnp.maximum(jnp.sum(w, axis=1, keepdims=True), jnp.finfo(rdt).tiny)
    t = jnp.where(mask, jnp.asarray(pm.children_transport).astype(x.dtype), 0)
    coef = t * w.astype(x.dtype)  # [Vc, M]: weight and transport folded into one complex factor
    xc = jnp.take(x, jnp.asarray(pm.children), axis=0, mode="clip")  # [Vc, M, C]
    xc = jnp.where(mask[..., None], xc, 0)  # a padded vertex row of x may be non-finite too
    return jnp.einsum("pm,pmc->pc", coef, xc)


def tangent_unpool(x: Complex[ArrayLike, "Vc C"], pm: PoolingMap) -> Complex[Array, "Vf C"]:
    """Nearest-parent upsampling: each fine vertex copies its parent's feature into its own frame.

    .. math:: y_f = \\overline{\\tau_{f\\to P(f)}}\\; x_{P(f)}

    ``τ_{f→P}`` (``to_parent``) has unit modulus, so its conjugate is the inverse transport from the
    parent's frame to the child's.

    Args:
      x: ``[Vc, C]`` complex features at the coarse level, each in its coarse vertex's frame.
      pm: the :class:`~jmeshtex.PoolingMap` between the two levels.

    Returns:
      ``[Vf, C]`` complex features in the fine vertices' frames; dtype of ``x``.

    Example:
      >>> import numpy as np
      >>> pm = PoolingMap(parent=np.array([0, 0]), to_parent=np.array([1, 1j]),
      ...     children=np.array([[0, 1]]), children_mask=np.array([[True, True]]),
      ...     children_weight=np.array([[1.0, 3.0]]), children_transport=np.array([[1, 1j]]))
      >>> tangent_unpool(jnp.array([[1 + 0j]]), pm).tolist()
      [[(1+0j)], [-1j]]
    """
    check_complex(x, "tangent_unpool", ndim_min=2)
    _check_map(x, pm, "tangent_unpool", fine=False)
    xp = jnp.take(x, jnp.asarray(pm.parent), axis=0, mode="clip")  # [Vf, C]
    back = jnp.conj(jnp.asarray(pm.to_parent).astype(x.dtype))
    return back[:, None] * xp


def _check_map(x, pm: PoolingMap, name: str, *, fine: bool) -> None:
    if x.ndim != 2:
        raise InputError(f"{name}: x must be [V, C] (vmap for batches), got shape {x.shape}")
    vf, vc = jnp.shape(pm.parent)[0], jnp.shape(pm.children)[0]
    n, level = (vf, "fine (len(pm.parent))") if fine else (vc, "coarse (pm.children.shape[0])")
    if x.shape[0] != n:
        raise InputError(
            f"{name}: x has {x.shape[0]} vertices but the PoolingMap's {level} level has {n}; "
            "pass features of that level (pad them with zeros if the map was padded with pad_to)"
        )
    m_shape = jnp.shape(pm.children)
    for field in ("children_mask", "children_weight", "children_transport"):
        if jnp.shape(getattr(pm, field)) != m_shape:
            raise InputError(
                f"{name}: pm.{field} has shape {jnp.shape(getattr(pm, field))}, expected {m_shape}"
            )
    if jnp.shape(pm.to_parent) != (vf,):
        raise InputError(
            f"{name}: pm.to_parent has shape {jnp.shape(pm.to_parent)}, expected ({vf},)"
        )

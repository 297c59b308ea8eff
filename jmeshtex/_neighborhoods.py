"""Padded neighbourhood pytrees: the contract between host-side geometry and pure JAX ops.

Every builder in :mod:`jmeshtex.geometry` (and the texel builders of :mod:`jmeshtex.surfacecnn`) returns one of these NamedTuples of arrays with static
shapes. They are pytrees, so they pass through ``jax.jit`` / ``vmap`` as arguments, and can be padded
to common sizes with :func:`pad_to` and stacked for batches.

Padding contract (the docs' Concepts page): a padded slot holds index 0, ``mask`` False and zero weight; no op may
let a padded slot change its output. Padded vertices / faces have ``vertex_mask`` / ``face_mask``
False.

Frames: tangent vectors are complex numbers in a per-vertex frame; ``log[p, j]`` is the position of
neighbour ``index[p, j]`` in p's frame; ``transport[p, j]`` (unit modulus) maps coordinates in the
neighbour's frame to p's frame: ``x_in_p = transport[p, j] * x_in_q``.

Host builders return NumPy float64 / complex128 / int32 / bool arrays; :func:`to_jax` converts a
whole pytree to JAX arrays of a chosen precision.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple, TypeVar

import jax
import jax.numpy as jnp
import numpy as np

from ._errors import InputError, LogScaleWarning
from ._types import Array, ArrayLike, Bool, Complex, Float, Int


class FaceNeighborhood(NamedTuple):
    """Face-to-face connectivity for DGTS face convolutions (Hertz et al. 2020, §3.1).

    Edge ``k`` of face ``f`` is ``(faces[f, k], faces[f, (k + 1) % 3])``.

    Attributes:
      faces: ``[F, 3]`` vertex indices.
      neighbors: ``[F, 3]`` face across edge k; 0 where ``mask`` is False (boundary / padding).
      opposite: ``[F, 3]`` vertex of the neighbour face opposite edge k; on a boundary edge the
        face's own opposite vertex ``faces[f, (k + 2) % 3]`` (a consistent substitute).
      mask: ``[F, 3]`` True where edge k has a neighbour face.
      face_mask: ``[F]`` True for real faces, False for padding.
      vertex_faces: ``[V, M]`` faces incident to each vertex, padded with 0.
      vertex_corners: ``[V, M]`` which corner (0, 1, 2) of that face the vertex is.
      vertex_faces_mask: ``[V, M]`` True for real incidences.
      vertex_mask: ``[V]`` True for real vertices.
    """

    faces: Int[Array, "F 3"]
    neighbors: Int[Array, "F 3"]
    opposite: Int[Array, "F 3"]
    mask: Bool[Array, "F 3"]
    face_mask: Bool[Array, " F"]
    vertex_faces: Int[Array, "V M"]
    vertex_corners: Int[Array, "V M"]
    vertex_faces_mask: Bool[Array, "V M"]
    vertex_mask: Bool[Array, " V"]


class VertexNeighborhood(NamedTuple):
    """Padded vertex neighbourhoods with intrinsic log maps and transport.

    Used both for one-rings (no self slot, counter-clockwise order, slot 0 is the gauge's reference
    edge) and for k-nearest geodesic neighbourhoods (slot 0 is the vertex itself with ``log`` 0 and
    ``transport`` 1).

    Attributes:
      index: ``[V, K]`` neighbour vertex q of each slot; 0 on padding.
      mask: ``[V, K]`` True for real slots.
      log: ``[V, K]`` complex ``log_p(q)`` in p's tangent frame (0 on padding).
      transport: ``[V, K]`` unit complex ``rho_{q->p}``, q's frame to p's frame (1 on padding).
      weight: ``[V, K]`` integration weight of the slot: the vertex area of q (0 on padding).
      area: ``[V]`` vertex area of p (barycentric, a third of incident face areas); 0 on padding.
      vertex_mask: ``[V]`` True for real vertices.
      log_unit: the length, in mesh units, of one unit of ``log`` (a 0-d array), set by
        :func:`scale_log_maps` and by the builders' ``scale=`` (by default the mean edge length,
        so that ``|log|`` is about 1 for a neighbour one edge away, the scale a filter's weights
        start at); ``None``: unrecorded (``scale=None``, hand-built or hierarchy
        neighbourhoods: ``log`` in mesh units). A leaf of the pytree when set (``vmap`` a stacked
        batch with ``[B]`` units).
    """

    index: Int[Array, "V K"]
    mask: Bool[Array, "V K"]
    log: Complex[Array, "V K"]
    transport: Complex[Array, "V K"]
    weight: Float[Array, "V K"]
    area: Float[Array, " V"]
    vertex_mask: Bool[Array, " V"]
    log_unit: Float[ArrayLike, ""] | None = None


#: an unrecorded neighbourhood whose typical edge in log units (``typical_edge``) lies outside
#: this range warns: the issue's first user mesh had edges of 11.7, a unit sphere at 40K vertices 0.02
LOG_SCALE_RANGE = (0.2, 5.0)

_WARNED: set[str] = set()  # callers that warned once (``check_log_scale(once=True)``)


def typical_edge(nbhd: VertexNeighborhood) -> float | None:
    """The mean over vertices of the shortest positive ``|log|`` in each row: about one edge length.

    In a one-ring or a k-NN neighbourhood the nearest neighbour is an edge neighbour, so this is
    the mean shortest edge at a vertex in the units of ``log`` (≈ 0.6–0.9 at unit scale). None when
    no real slot has a positive ``|log|``.

    Example:
      >>> import numpy as np
      >>> nb = VertexNeighborhood(np.zeros((2, 3), np.int32), np.ones((2, 3), bool),
      ...     np.array([[0, 2, 3j], [0, 0.5, -4]]), np.ones((2, 3), complex), np.ones((2, 3)),
      ...     np.ones(2), np.ones(2, bool))
      >>> typical_edge(nb)  # (2 + 0.5) / 2
      1.25
    """
    r = np.where(np.asarray(nbhd.mask, bool), np.abs(np.asarray(nbhd.log)), 0.0)
    r = np.where(r > 0, r, np.inf).min(axis=1)
    r = r[np.isfinite(r)]
    return float(r.mean()) if r.size else None


def check_log_scale(
    nbhd: VertexNeighborhood, caller: str = "check_log_scale", *, once: bool = False
) -> None:
    """Warn (:class:`LogScaleWarning`) when ``nbhd``'s log maps have no recorded unit and are far from one.

    Checks only what can be read without tracing: a neighbourhood with a recorded ``log_unit`` is
    at the scale its builder chose (the unit must be positive and finite, else
    :class:`~jmeshtex.InputError`); one without is checked when its arrays are concrete (not under
    ``jax.jit`` / ``vmap`` / ``grad``), by its typical edge (the mean over vertices of the nearest
    neighbour's ``|log|``, about one edge length) against ``LOG_SCALE_RANGE``
    (0.2 to 5).

    Args:
      nbhd: a :class:`VertexNeighborhood`.
      caller: the calling function's name, for the messages.
      once: warn at most once per process for this ``caller`` (:func:`jmeshtex.ops.field_conv`
        passes True: a network calls it once per layer and step).

    Example:
      >>> import numpy as np, warnings
      >>> nb = VertexNeighborhood(np.zeros((1, 2), np.int32), np.ones((1, 2), bool),
      ...     np.array([[0, 0.001j]]), np.ones((1, 2), complex), np.ones((1, 2)), np.ones(1),
      ...     np.ones(1, bool))
      >>> with warnings.catch_warnings(record=True) as caught:
      ...     warnings.simplefilter("always")
      ...     check_log_scale(nb, "field_conv")
      >>> caught[0].category.__name__
      'LogScaleWarning'
      >>> check_log_scale(scale_log_maps(nb, 0.001), "field_conv")  # unit recorded: silent
    """
    unit, log, mask = nbhd.log_unit, nbhd.log, nbhd.mask
    if unit is not None:
        if isinstance(unit, jax.core.Tracer):
            return
        u = np.asarray(unit)
        if not (np.all(np.isfinite(u)) and np.all(u > 0)):
            raise InputError(f"{caller}: nbhd.log_unit must be positive and finite, got {u!r}")
        return
    if once and caller in _WARNED:
        return
    if isinstance(log, jax.core.Tracer) or isinstance(mask, jax.core.Tracer):
        return
    edge = typical_edge(nbhd)
    lo, hi = LOG_SCALE_RANGE
    if edge is None or lo <= edge <= hi:
        return
    if once:
        _WARNED.add(caller)
    warnings.warn(
        f"{caller}: the neighbourhood has no recorded unit (log_unit None) and its log maps put "
        f"a typical edge at |log| = {edge:.3g}, outside [{lo}, {hi}], far from the unit scale the "
        "filters see (the output then hardly depends on the geometry, or saturates); build it "
        'with scale="mean_edge" (the builders\' default) or call jmeshtex.scale_log_maps(nbhd, '
        "mean_edge_length(v, f))" + (" (said once)" if once else ""),
        LogScaleWarning,
        stacklevel=3,
    )


def scale_log_maps(nbhd: VertexNeighborhood, unit: float) -> VertexNeighborhood:
    """Express a neighbourhood's log maps in units of ``unit`` and record the unit.

    .. math:: \\log_p(q) \\leftarrow \\log_p(q) / u, \\qquad u_{\\log} \\leftarrow u \\cdot u_{\\log}

    (``log_unit`` is ``u_log``; 1 when it was None).

    Field-convolution filters see ``log`` directly, so their weights (drawn for arguments of
    order 1) only see the geometry when ``|log|`` is of order 1: on a mesh with a mean edge of 0.01
    in mesh units every log map is about 0 to the filter. Dividing by the mean edge length
    (:func:`jmeshtex.geometry.mean_edge_length`) puts one edge at about 1 on any mesh.

    Args:
      nbhd: a :class:`VertexNeighborhood` (NumPy or JAX arrays).
      unit: a positive, finite length in the current units of ``nbhd.log``.

    Returns:
      The same neighbourhood with ``log / unit`` and ``log_unit`` the length of one new unit in
      mesh units (a float64 0-d NumPy array, or of ``log``'s real dtype for JAX arrays).

    Example:
      >>> import numpy as np
      >>> nb = VertexNeighborhood(np.zeros((1, 2), np.int32), np.ones((1, 2), bool),
      ...     np.array([[0, 0.02j]]), np.ones((1, 2), complex), np.ones((1, 2)), np.ones(1),
      ...     np.ones(1, bool))
      >>> s = scale_log_maps(nb, 0.01)
      >>> s.log.tolist(), float(s.log_unit), float(scale_log_maps(s, 2.0).log_unit)
      ([[0j, 2j]], 0.01, 0.02)
    """
    unit_f = float(unit)
    if not (np.isfinite(unit_f) and unit_f > 0):
        raise InputError(f"scale_log_maps: unit must be a positive, finite length, got {unit!r}")
    xp = jnp if isinstance(nbhd.log, jax.Array) else np
    real = xp.real(nbhd.log).dtype
    old = 1.0 if nbhd.log_unit is None else nbhd.log_unit
    return nbhd._replace(
        log=nbhd.log / xp.asarray(unit_f, nbhd.log.dtype),
        log_unit=xp.asarray(old, real) * xp.asarray(unit_f, real),
    )


class TangentFrames(NamedTuple):
    """Extrinsic orthonormal frames per vertex, used only to convert tangent vectors to/from 3D.

    ``x`` is the reference one-ring edge projected onto the tangent plane, so the complex angle of a
    tangent vector measured from ``x`` agrees with the intrinsic gauge of :class:`~jmeshtex.VertexNeighborhood`.

    Attributes:
      normal: ``[V, 3]`` unit angle-weighted vertex normals.
      x: ``[V, 3]`` unit tangent x-axes.
      y: ``[V, 3]`` ``normal × x``.
    """

    normal: Float[Array, "V 3"]
    x: Float[Array, "V 3"]
    y: Float[Array, "V 3"]


class PoolingMap(NamedTuple):
    """Maps between two hierarchy levels, fine (``Vf`` vertices) and coarse (``Vc``).

    Attributes:
      parent: ``[Vf]`` coarse vertex each fine vertex belongs to.
      to_parent: ``[Vf]`` unit complex transport from the fine vertex's frame to its parent's frame.
      children: ``[Vc, M]`` fine vertices of each coarse vertex, padded with 0.
      children_mask: ``[Vc, M]`` True for real children.
      children_weight: ``[Vc, M]`` area weight of each child (0 on padding).
      children_transport: ``[Vc, M]`` transport child frame → parent frame (1 on padding).
    """

    parent: Int[Array, " Vf"]
    to_parent: Complex[Array, " Vf"]
    children: Int[Array, "Vc M"]
    children_mask: Bool[Array, "Vc M"]
    children_weight: Float[Array, "Vc M"]
    children_transport: Complex[Array, "Vc M"]


class TexelNeighborhood(NamedTuple):
    """Nine sampling taps per texel, each a weighted sum of ``J`` texels.

    Padding contract: a padded slot has index 0 and weight 0; a padded texel has ``texel_mask``
    False (its output is 0). A tap that falls off the surface (or off the image) has all-zero
    weights, i.e. zero padding.

    Attributes:
      index: ``[N, 9, J]`` int32 texels each tap interpolates (``J = 4`` bilinear, 1 nearest).
      weight: ``[N, 9, J]`` interpolation weights (summing to 1 for a tap on the surface, 0 off it).
      texel_mask: ``[N]`` True for real texels.
    """

    index: Int[Array, "N 9 J"]
    weight: Float[Array, "N 9 J"]
    texel_mask: Bool[Array, " N"]


class PoolGroups(NamedTuple):
    """Groups of texels pooled into one coarser texel.

    Attributes:
      index: ``[G, S]`` int32 fine texels of each group, 0 on padding.
      mask: ``[G, S]`` True for real members.
    """

    index: Int[Array, "G S"]
    mask: Bool[Array, "G S"]


T = TypeVar("T")


def to_jax(tree: T, dtype=jnp.float32) -> T:
    """Convert a host pytree to JAX arrays: floats to ``dtype``, complex to the matching complex.

    Integer and boolean leaves keep their kind (integers become int32).

    Args:
      tree: any pytree of NumPy/JAX arrays, e.g. a :class:`~jmeshtex.VertexNeighborhood`.
      dtype: ``jnp.float32`` (default) or ``jnp.float64`` (needs ``jax_enable_x64``).

    Example:
      >>> import numpy as np
      >>> t = to_jax({"a": np.ones(2), "z": np.ones(2, complex), "i": np.arange(2)})
      >>> t["a"].dtype, t["z"].dtype, t["i"].dtype
      (dtype('float32'), dtype('complex64'), dtype('int32'))
    """
    real = jnp.dtype(dtype)
    if real not in (
        jnp.dtype(jnp.float16),
        jnp.dtype(jnp.bfloat16),
        jnp.dtype(jnp.float32),
        jnp.dtype(jnp.float64),
    ):
        raise InputError(
            f"to_jax: dtype must be a real floating dtype (float32 or float64: the dtype weights, "
            f"log maps and positions become), got {real}; integer leaves are int32 anyway"
        )
    cplx = jnp.dtype(jnp.complex128) if real == jnp.float64 else jnp.dtype(jnp.complex64)

    def convert(leaf):
        leaf_dtype = np.asarray(leaf).dtype if not isinstance(leaf, jax.Array) else leaf.dtype
        if jnp.issubdtype(leaf_dtype, jnp.complexfloating):
            target = cplx
        elif jnp.issubdtype(leaf_dtype, jnp.floating):
            target = real
        elif jnp.issubdtype(leaf_dtype, jnp.integer):
            target = jnp.dtype(jnp.int32)
        else:  # booleans (masks) keep their dtype
            target = leaf_dtype
        if isinstance(leaf, jax.Array):
            return jnp.asarray(leaf, dtype=target)
        # host arrays convert on the host and are put on the device as they are: jnp.asarray would
        # compile a conversion (or a staging copy) per shape under jax.ensure_compile_time_eval
        return jax.device_put(np.asarray(leaf, dtype=target))

    return jax.tree.map(convert, tree)


_PAD_VALUES = {"transport": 1, "to_parent": 1, "children_transport": 1}


def pad_to(tree: T, sizes: dict[str, int]) -> T:
    """Pad a neighbourhood pytree's leading / slot axes to larger static sizes.

    ``sizes`` maps axis names to target sizes: ``"V"`` (vertices), ``"F"`` (faces), ``"K"``
    (slots of ``[V, K]`` fields), ``"M"`` (incident faces / children); for the texel pytrees: ``"N"`` (texels), ``"J"`` (texels per tap), ``"G"`` (groups), ``"S"`` (group
    size). Index fields are padded with 0,
    masks with False, weights and logs with 0, transports with 1 — the padding contract.

    Args:
      tree: a :class:`~jmeshtex.VertexNeighborhood` or :class:`~jmeshtex.FaceNeighborhood`.
      sizes: target sizes; each must be at least the current size.

    Returns:
      The same type with padded arrays (NumPy or JAX following the input).

    Example:
      >>> import numpy as np
      >>> nb = VertexNeighborhood(np.zeros((2, 3), np.int32), np.ones((2, 3), bool),
      ...     np.zeros((2, 3), complex), np.ones((2, 3), complex), np.ones((2, 3)), np.ones(2),
      ...     np.ones(2, bool))
      >>> pad_to(nb, {"V": 4, "K": 5}).index.shape
      (4, 5)
    """
    axes = _AXES[type(tree).__name__]
    out = {}
    for name, leaf in tree._asdict().items():
        names = axes[name]
        if leaf is None or names == ():  # optional fields, scalars (log_unit): nothing to pad
            out[name] = leaf
            continue
        xp = jnp if isinstance(leaf, jax.Array) else np
        widths = []
        for axis_name, current in zip(names, leaf.shape, strict=False):
            target = sizes.get(axis_name, current)
            if target < current:
                raise InputError(
                    f"pad_to: cannot shrink axis {axis_name} of {name} from {current} to {target}"
                )
            widths.append((0, target - current))
        widths += [(0, 0)] * (leaf.ndim - len(names))
        out[name] = xp.pad(leaf, widths, constant_values=_PAD_VALUES.get(name, 0))
    return type(tree)(**out)


_AXES = {
    "FaceNeighborhood": {
        "faces": ("F",),
        "neighbors": ("F",),
        "opposite": ("F",),
        "mask": ("F",),
        "face_mask": ("F",),
        "vertex_faces": ("V", "M"),
        "vertex_corners": ("V", "M"),
        "vertex_faces_mask": ("V", "M"),
        "vertex_mask": ("V",),
    },
    "VertexNeighborhood": {
        "index": ("V", "K"),
        "mask": ("V", "K"),
        "log": ("V", "K"),
        "transport": ("V", "K"),
        "weight": ("V", "K"),
        "area": ("V",),
        "vertex_mask": ("V",),
        "log_unit": (),
    },
    "TangentFrames": {"normal": ("V",), "x": ("V",), "y": ("V",)},
    # texel neighbourhoods: N texels, 9 taps of J texels each; G pooling groups of S texels
    "TexelNeighborhood": {
        "index": ("N", "T", "J"),
        "weight": ("N", "T", "J"),
        "texel_mask": ("N",),
    },
    "PoolGroups": {"index": ("G", "S"), "mask": ("G", "S")},
    "PoolingMap": {
        "parent": ("Vf",),
        "to_parent": ("Vf",),
        "children": ("Vc", "M"),
        "children_mask": ("Vc", "M"),
        "children_weight": ("Vc", "M"),
        "children_transport": ("Vc", "M"),
    },
}

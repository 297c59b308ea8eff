"""Transfer a learned DGTS texture to any mesh, and interpolate between noises (Hertz et al. 2020, §3.4, §4).

Inference modes (all through one jit-compiled pass that also returns every level's output, the
growing mesh of the paper's Fig. 6, ``per_level=True``):

- :func:`transfer`: the generators ``start_level … stop_level`` (default: the last) on the target,
  fresh noise on the first two levels run and none above (the official ``growing`` / ``animate``,
  ``zero_places = (0, 0, 1, 1, 1)``); ``zero_noise_from=k`` sets the noise of levels ``≥ k`` to
  zero instead (deterministic from the start level on when ``k ≤ start_level``; ``k = L``: noise
  everywhere);
- :func:`reconstruct`: the template through all levels with the reconstruction noise
  (:meth:`Model.reconstruction_noise`: ``z*`` at level 0, zero above by default): the training
  meshes' reconstruction;
- :func:`conditional`: generation from the template at scale ``k`` (Fig. 5): the reconstruction's
  noise below level ``k``, fresh noise from ``k`` on, so levels ``< k`` reproduce the reconstruction;
- :func:`interpolate`: frames between two noise draws.

Start and stop levels. The official code runs the generators ``--gen-levels start stop`` (default
``[1, 4]``, clipped to the model: :func:`~jmeshtex.dgts.official_gen_levels`) on the raw target scaled to unit
edge; ``transfer(..., start_level=1, stop_level=min(4, L − 1))`` does exactly that
(:data:`OFFICIAL_GEN_LEVELS`). jmeshtex's own default (``start_level=None``, not the official one)
starts at the level whose training mesh has the target's resolution, never the coarsest of a deeper
model, raised until the output (``F_out = F_target · 4^{stop − start}``) fits ``max_faces``
(:func:`choose_start_level`; default 500 000; :class:`FaceBudgetError` when none does), and stops at
the last level (``stop_level=None``).

The target is scaled about its centroid so its mean edge is 1 (the frame the generators were trained
in, the official ``to_unit_edge``), the generators ``start_level … stop_level`` run on it with fresh
Gaussian vertex noise, subdividing 1 → 4 and rescaling ×2 between levels (not after the last), and
the result is mapped back to the target's coordinates (the official code exports it in the
unit-edge frame). No re-meshing: the target's own triangles are subdivided, so open meshes, several
components and any genus work (boundary edges are handled by the face neighbourhood's substitute
opposite vertex).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._config import is_int
from .._errors import FaceBudgetError, InputError
from .._mesh import Mesh, as_mesh
from .._types import Array, Float, Int, PRNGKey
from ..geometry import (
    mean_edge_length,
    taubin_smooth,
    unique_edges,
    validate_mesh,
    vertex_normals,
)
from ._model import Model
from ._networks import LevelGeometry, generate, hierarchy_geometry, upsample


class Transfer(NamedTuple):
    """Meshes produced by :func:`transfer` and :func:`interpolate` (all in the target's coordinates).

    Attributes:
      vertices: ``[S, V_n, 3]`` float64, one textured mesh per sample (or frame).
      faces: ``[F_n, 3]`` int64, their triangles (the target subdivided ``n − 1`` times).
      base: ``[V_n, 3]`` float64, the subdivided target without displacement (the reference for heights).
      heights: ``[S, V_n]`` float64, displacement along the base's vertex normals, in mean edges of
        the output's level frame (for colouring).
      noise: per sample, the list of per-level noises used (``[V_l, 3]`` float32 arrays; replay or
        interpolate with them through :func:`~jmeshtex.dgts.core.run_plan`).
      start_level: the first generator level run (chosen by the face budget when not given).
      level_vertices: with ``per_level=True``, one ``[S, V_l, 3]`` float64 array per level run:
        that level's output (target coordinates, before subdivision); else empty.
      level_faces: the matching ``[F_l, 3]`` triangles; else empty.
      stop_level: the last generator level run.
    """

    vertices: np.ndarray
    faces: np.ndarray
    base: np.ndarray
    heights: np.ndarray
    noise: list
    start_level: int = 0
    level_vertices: tuple = ()
    level_faces: tuple = ()
    stop_level: int = -1

    def mesh(self, sample: int = 0) -> Mesh:
        """Sample (or frame) ``sample`` as a :class:`~jmeshtex.Mesh`."""
        return Mesh(self.vertices[sample], self.faces)


class TransferPlan(NamedTuple):
    """A target prepared for the generators (:func:`plan_transfer`): frames and connectivity.

    Attributes:
      vertices: ``[V, 3]`` float32, the target in the model's frame (centred on its centroid, mean
        edge 1).
      geometry: one :class:`~jmeshtex.dgts.core.LevelGeometry` per level run.
      faces: ``[F_l, 3]`` int64 triangles per level run (the target's, then its subdivisions).
      sizes: vertices per level run (the shapes of the noise, ``[V_l, 3]``).
      center: ``[3]`` the target's centroid (input coordinates).
      factor: input-to-output scale: the output's frame is ``(x − center) · factor``.
      start_level: the first generator run (the last is ``start_level + len(sizes) − 1``).
      scale_factor: the rescaling between levels (``Config.scale_factor``).
    """

    vertices: Float[Array, "V 3"]
    geometry: tuple[LevelGeometry, ...]
    faces: tuple[np.ndarray, ...]
    sizes: tuple[int, ...]
    center: Float[np.ndarray, " 3"]
    factor: float
    start_level: int
    scale_factor: float = 2.0

    @property
    def stop_level(self) -> int:
        """The last generator level run."""
        return self.start_level + len(self.sizes) - 1

    def to_target(
        self, vertices: Float[Array, "Vn 3"], level: int | None = None
    ) -> Float[np.ndarray, "Vn 3"]:
        """Output positions of :func:`run_plan` back in the target's coordinates (float64).

        ``level``: the index (into ``sizes``) of the level run the positions come from; default the
        last (the frames grow by ``scale_factor`` per level).
        """
        factor = self.factor
        if level is not None:
            factor = self.factor / self.scale_factor ** (len(self.sizes) - 1 - int(level))
        return np.asarray(vertices, np.float64) / factor + self.center


def plan_transfer(
    model: Model, target: Mesh | tuple, *, start_level: int = 0, stop_level: int | None = None
) -> TransferPlan:
    """Prepare a target mesh for the generators ``start_level … stop_level`` (host side, once per target).

    The target is scaled about its centroid so its mean edge is 1 (the frame the generators were
    trained in), and the connectivity of ``stop_level − start_level + 1`` levels of midpoint
    subdivision is built.

    Args:
      model: a trained :class:`~jmeshtex.dgts.Model`.
      target: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])`` (open or closed, any
        genus, any scale and placement).
      start_level: first generator to run (0: coarsest).
      stop_level: last generator to run, in ``[start_level, L − 1]``; None: the last (``L − 1``).

    Returns:
      :class:`TransferPlan`, the input of :func:`run_plan`.

    Raises:
      InputError: a bad ``start_level`` or ``stop_level``, an untrained model, or a target that is
        not a mesh;
      MeshError: (a subclass) an invalid target.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.dgts import Config
      >>> from jmeshtex.dgts.core import init_level
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(2))
      >>> model = Model(c, gs, gs, np.zeros((12, 3), np.float32))
      >>> plan = plan_transfer(model, icosahedron())
      >>> plan.sizes, plan.faces[-1].shape
      ((12, 42), (80, 3))
    """
    v, f = as_mesh(target, what="target")
    validate_mesh(v, f)
    L = model.num_levels
    if L == 0:
        raise InputError("the model has no trained level: train it first")
    if not is_int(start_level, 0) or start_level >= L:
        raise InputError(
            f"start_level must be an int in [0, {L - 1}] (the model has {L} levels), got {start_level!r}"
        )
    stop = _stop(model, start_level, stop_level)
    v = np.asarray(v, np.float64)
    f = np.asarray(f, np.int64)
    center = v.mean(axis=0)
    scale = 1.0 / mean_edge_length(v, f)
    n = stop - int(start_level) + 1
    geos, faces_all = hierarchy_geometry(f, len(v), n)
    sizes = [len(v)]
    for g in geos[:-1]:
        sizes.append(sizes[-1] + int(g.edge_vertices.shape[0]))
    factor = scale * model.config.scale_factor ** (n - 1)
    return TransferPlan(
        jnp.asarray((v - center) * scale, jnp.float32),
        geos,
        faces_all,
        tuple(sizes),
        center,
        float(factor),
        int(start_level),
        float(model.config.scale_factor),
    )


def _stop(model: Model, start_level: int, stop_level: int | None) -> int:
    """``stop_level`` checked against the model and the start level (None: the last level)."""
    L = model.num_levels
    if stop_level is None:
        return L - 1
    if not is_int(stop_level, 0) or not int(start_level) <= stop_level <= L - 1:
        raise InputError(
            f"stop_level must be an int in [start_level, {L - 1}] = [{start_level}, {L - 1}] "
            f"(the model has {L} levels), got {stop_level!r}"
        )
    return int(stop_level)


#: the official inference levels, ``--gen-levels`` (``options.py``, default ``[1, 4]``): the
#: generators 1 … 4, clipped to the model by :func:`~jmeshtex.dgts.official_gen_levels`
OFFICIAL_GEN_LEVELS = (1, 4)


def official_gen_levels(
    model: Model, gen_levels: Sequence[int] = OFFICIAL_GEN_LEVELS
) -> tuple[int, int]:
    """``(start_level, stop_level)`` as the official inference takes them from ``--gen-levels``.

    The official ``Mesh2Mesh.trim``: a stop level below 0 or past the model's last level becomes the
    last level, and a start level past the stop level becomes the stop level. With the default
    ``[1, 4]`` a 5-level model runs its generators 1 … 4, a 3-level model 1 … 2.

    Args:
      model: a trained model (``L`` levels).
      gen_levels: ``(start, stop)``, the official ``--gen-levels`` (default ``[1, 4]``).

    Returns:
      ``(start_level, stop_level)`` for :func:`transfer` / :func:`interpolate`.

    Raises:
      InputError: not two ints, or a negative start level.

    Example:
      >>> from jmeshtex.dgts import Config
      >>> from jmeshtex.dgts.core import init_level
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(3))
      >>> model = Model(c, gs, gs, np.zeros((12, 3), np.float32))
      >>> official_gen_levels(model), official_gen_levels(model, (4, 7))
      ((1, 2), (2, 2))
    """
    if len(gen_levels) != 2 or not all(is_int(x) for x in gen_levels) or int(gen_levels[0]) < 0:
        raise InputError(f"gen_levels must be two ints (start >= 0, stop), got {gen_levels!r}")
    L = model.num_levels
    if L == 0:
        raise InputError("the model has no trained level: train it first")
    start, stop = int(gen_levels[0]), int(gen_levels[1])
    if stop < 0 or stop > L - 1:
        stop = L - 1
    return min(start, stop), stop


@jax.jit(static_argnums=(0, 1, 2, 3, 4))
def _generate_jit(scale, negative_slope, eps, y_sign, per_level, v0, geos, params, zs):
    return generate(
        params,
        v0,
        geos,
        zs,
        scale=scale,
        negative_slope=negative_slope,
        eps=eps,
        y_sign=y_sign,
        per_level=per_level,
    )


def run_plan(
    model: Model, plan: TransferPlan, noise: Sequence[Float[Array, "Vl 3"] | float]
) -> Float[Array, "Vn 3"]:
    """Run the generators on a prepared target with the given noise (jit-compiled, pure JAX).

    .. math:: v_{l+1} = s\\,U_l\\big(v_l + G_l(v_l, z_l)\\big),\\quad l = \\text{start} \\ldots \\text{stop}

    Args:
      model: the :class:`~jmeshtex.dgts.Model` the plan was made for.
      plan: from :func:`plan_transfer`.
      noise: one ``[V_l, 3]`` array (``plan.sizes[l]``) or scalar 0 per level run.

    Returns:
      ``[V_n, 3]`` float32 output in the last level's frame (:meth:`TransferPlan.to_target` maps it
      back); a second call with the same shapes does not recompile.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.dgts import Config
      >>> from jmeshtex.dgts.core import init_level
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(2))
      >>> model = Model(c, gs, gs, np.zeros((12, 3), np.float32))
      >>> plan = plan_transfer(model, icosahedron())
      >>> plan.to_target(run_plan(model, plan, [0.0, 0.0])).shape
      (42, 3)
    """
    if len(noise) != len(plan.sizes):
        raise InputError(f"run_plan: got {len(noise)} noises for {len(plan.sizes)} levels")
    c = model.config
    params = tuple(model.generators[plan.start_level : plan.stop_level + 1])
    return _generate_jit(
        c.scale_factor,
        c.negative_slope,
        c.eps,
        c.y_sign,
        False,
        plan.vertices,
        plan.geometry,
        params,
        tuple(noise),
    )


def output_faces(
    model: Model, num_faces: int, start_level: int, stop_level: int | None = None
) -> int:
    """Faces of a transfer's output: ``F · 4^{stop − start}`` (midpoint subdivision 1 → 4 per level;
    ``stop_level`` None: the last level, ``L − 1``).

    Example:
      >>> from jmeshtex.dgts import Config
      >>> from jmeshtex.dgts.core import init_level
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(3))
      >>> output_faces(Model(c, gs, gs, np.zeros((12, 3), np.float32)), 100, 0)
      1600
    """
    stop = model.num_levels - 1 if stop_level is None else int(stop_level)
    return int(num_faces) * 4 ** (stop - int(start_level))


def matching_level(model: Model, num_faces: int) -> int:
    """The level whose training mesh has about the target's face count, never level 0 of a deeper model.

    .. math:: s = \\operatorname{clip}\\big(\\operatorname{round}\\big(\\log_4 (F / F_0)\\big),\\;
       \\min(1, L - 1),\\; L - 1\\big),\\qquad F_0 = 2 V_0

    (``V_0`` the template's vertices, the rows of ``z*``; a closed template has ``F_0 ≈ 2 V_0``.)
    Equal face counts mean equal mean edges relative to the surface's size, so the generator that
    starts sees a shape as coarse, in its own edges, as the one it was trained on. This choice is
    jmeshtex's own (the official code starts where ``--gen-levels`` says, level 1 by default,
    whatever the target: :func:`~jmeshtex.dgts.official_gen_levels`). Level 0 is skipped, as the official default
    does (the paper starts at 2–3): its generator lays out the training shape itself and, with
    ``Config.reconstruction_start`` = 1, never learns to leave a given shape alone.

    Example:
      >>> from jmeshtex.dgts import Config
      >>> from jmeshtex.dgts.core import init_level
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(5))
      >>> model = Model(c, gs, gs, np.zeros((42, 3), np.float32))  # template of 80 faces
      >>> [matching_level(model, f) for f in (20, 320, 1000, 5120, 10**6)]
      [1, 1, 2, 3, 4]
    """
    L = model.num_levels
    f0 = 2.0 * max(int(np.shape(model.z_star)[0]), 1)
    s = int(np.floor(np.log(max(int(num_faces), 1) / f0) / np.log(4.0) + 0.5))
    return int(min(max(s, min(1, L - 1)), L - 1))


def choose_start_level(
    model: Model, num_faces: int, *, max_faces: int = 500_000, stop_level: int | None = None
) -> int:
    """jmeshtex's default start level (not the official one, which is 1: :func:`~jmeshtex.dgts.official_gen_levels`):
    :func:`matching_level`, raised until the output fits ``max_faces``.

    .. math:: s = \\min\\{\\,s \\in [\\min(s_m, t), t] : F \\cdot 4^{t-s} \\le F_{\\max}\\,\\}

    Args:
      model: the trained model (``L`` levels).
      num_faces: faces of the target.
      max_faces: the face budget of the output.
      stop_level: the last level to run, ``t`` (None: ``L − 1``).

    Returns:
      The start level.

    Raises:
      FaceBudgetError: even the last level alone (no subdivision, ``F`` faces) exceeds the budget.
      InputError: an untrained model or a budget below 1.

    Example:
      >>> from jmeshtex.dgts import Config
      >>> from jmeshtex.dgts.core import init_level
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(5))
      >>> model = Model(c, gs, gs, np.zeros((12, 3), np.float32))  # template of 20 faces
      >>> choose_start_level(model, 1_000), choose_start_level(model, 1_000, max_faces=3_000)
      (3, 4)
    """
    L = model.num_levels
    if L == 0:
        raise InputError("the model has no trained level: train it first")
    if not is_int(max_faces, 1):
        raise InputError(f"max_faces must be a positive int, got {max_faces!r}")
    stop = _stop(model, 0, stop_level)
    for start in range(min(matching_level(model, num_faces), stop), stop + 1):
        if output_faces(model, num_faces, start, stop) <= max_faces:
            return start
    raise FaceBudgetError(
        f"the target has {num_faces} faces: even from the last level (no subdivision) the output "
        f"exceeds max_faces={max_faces}; decimate the target or raise max_faces"
    )


def _resolve_start(
    model: Model,
    target,
    start_level: int | None,
    max_faces: int | None,
    stop_level: int | None = None,
) -> int:
    _, f = as_mesh(target, what="target")
    F = int(np.shape(f)[0])
    if start_level is None:
        return choose_start_level(
            model,
            F,
            max_faces=500_000 if max_faces is None else max_faces,
            stop_level=stop_level,
        )
    if max_faces is not None and is_int(start_level, 0) and start_level < model.num_levels:
        stop = _stop(model, start_level, stop_level)
        if output_faces(model, F, start_level, stop) > max_faces:
            raise FaceBudgetError(
                f"start_level={start_level} on {F} faces gives "
                f"{output_faces(model, F, start_level, stop)} faces, over max_faces={max_faces}; "
                "use start_level=None to choose one that fits"
            )
    return start_level


def _noises(key: PRNGKey, sizes: Sequence[int], amplitude: float) -> list[jax.Array]:
    keys = jax.random.split(key, len(sizes))
    return [
        amplitude * jax.random.normal(k, (s, 3), jnp.float32)
        for k, s in zip(keys, sizes, strict=True)
    ]


def _synthesise(
    model: Model, plan: TransferPlan, draws: Sequence[Sequence], *, per_level: bool
) -> Transfer:
    """Run the generators of ``plan`` once per noise list in ``draws`` (one ``[V_l, 3]`` array per level
    run) and map the results back to the target's frame."""
    c = model.config
    params = tuple(model.generators[plan.start_level : plan.stop_level + 1])
    for level, p in enumerate(params, start=plan.start_level):
        if not all(np.isfinite(np.asarray(x)).all() for x in jax.tree.leaves(p)):
            raise InputError(
                f"the model's generator at level {level} has non-finite parameters (a diverged or "
                "damaged model): retrain it, or load another model"
            )
    outs = [
        _generate_jit(
            c.scale_factor,
            c.negative_slope,
            c.eps,
            c.y_sign,
            True,
            plan.vertices,
            plan.geometry,
            params,
            tuple(jnp.asarray(z, jnp.float32) for z in zs),
        )
        for zs in draws
    ]
    for o in outs:
        bad = [i for i, level in enumerate(o) if not np.isfinite(np.asarray(level)).all()]
        if bad:
            raise InputError(
                f"level {plan.start_level + bad[0]} of the transfer is not finite although the "
                "model's parameters are: the target's geometry breaks the face features there "
                "(degenerate or coincident faces? `jmeshtex info` on the target says)"
            )
    base = plan.vertices
    for g in plan.geometry[:-1]:
        base = upsample(base, g.edge_vertices, scale=c.scale_factor)
    base = np.asarray(base, np.float64)
    nrm = vertex_normals(base, plan.faces[-1])
    last = [np.asarray(o[-1], np.float64) for o in outs]
    heights = np.stack([np.einsum("vd,vd->v", o - base, nrm) for o in last])
    vertices = np.stack([plan.to_target(o) for o in last])
    levels: tuple = ()
    if per_level:
        levels = tuple(
            np.stack([plan.to_target(o[i], level=i) for o in outs]) for i in range(len(plan.sizes))
        )
    return Transfer(
        vertices,
        plan.faces[-1],
        plan.to_target(base),
        heights,
        [[np.asarray(z, np.float32) for z in zs] for zs in draws],
        plan.start_level,
        levels,
        tuple(plan.faces) if per_level else (),
        plan.stop_level,
    )


#: levels run with fresh noise by default, from the start level on (the official ``growing`` and
#: ``animate``: ``zero_places = (0, 0, 1, 1, 1)``, amirhertz/geometric-textures ``dgts_base.py``).
#: That tuple has 5 entries, so an official run of more than 5 levels gets fresh noise again from
#: its 6th level on; jmeshtex keeps zero noise there (a default model has 5 levels)
OFFICIAL_NOISY_LEVELS = 2


def _zero_above(draws: list, plan: TransferPlan, zero_noise_from: int | None) -> list:
    if zero_noise_from is None:
        return draws
    k = int(zero_noise_from)
    return [
        [np.zeros_like(np.asarray(z)) if plan.start_level + i >= k else z for i, z in enumerate(zs)]
        for zs in draws
    ]


def _noise_plan(
    model: Model, target, start_level, stop_level, max_faces, zero_noise_from
) -> tuple[TransferPlan, int]:
    """The plan of a noisy run (:func:`transfer`, :func:`interpolate`) and the level from which its
    noise is zero (default: the start level plus ``OFFICIAL_NOISY_LEVELS``)."""
    if zero_noise_from is not None:
        _check_level("zero_noise_from", zero_noise_from, 0, model.num_levels)
    start = _resolve_start(model, target, start_level, max_faces, stop_level)
    plan = plan_transfer(model, target, start_level=start, stop_level=stop_level)
    if zero_noise_from is None:
        zero_noise_from = start + OFFICIAL_NOISY_LEVELS
    return plan, zero_noise_from


def _check_level(name: str, value, low: int, high: int) -> int:
    if not is_int(value, low) or value > high:
        raise InputError(f"{name} must be an int in [{low}, {high}], got {value!r}")
    return int(value)


def transfer(
    model: Model,
    target: Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]],
    *,
    key: PRNGKey,
    start_level: int | None = None,
    stop_level: int | None = None,
    num_samples: int = 1,
    max_faces: int | None = 500_000,
    zero_noise_from: int | None = None,
    per_level: bool = False,
) -> Transfer:
    """Synthesise the learned texture on a target mesh, ``num_samples`` times with different noise.

    Noise on the first two levels run only, as the official code (``zero_places = (0, 0, 1, 1,
    1)``), since the coarse generators were trained on one shape each and the finer ones shape the
    texture. The start level by default is jmeshtex's own choice, the level whose training mesh has
    the target's resolution (:func:`~jmeshtex.dgts.core.choose_start_level`); the official code
    runs ``--gen-levels``, default ``[1, 4]``, whatever the target:
    ``start, stop = official_gen_levels(model)`` then ``transfer(model, target,
    start_level=start, stop_level=stop, key=key)`` (``1`` and ``min(4, L − 1)``).

    The texture's period is fixed in mean edges of each level, so the target's resolution sets its
    size on the surface. Choose it so the target is no more curved per edge than the training mesh:
    the generators see curvature through their edge features, and on a more curved target they
    leave their training distribution. Measured (``docs/results.md``, the curvature study; a knobs model
    trained on a sphere, from level 2): a torus whose tube circumference is 12 / 24 / 48 edges at
    the start level gets 4.4× / 2.1× / 1.6× the density of an oracle carrying the same knobs,
    spheres 1.3–1.6× at any resolution. A lower ``start_level`` subdivides the target more, so the
    texture is smaller relative to the shape and the level that lays it out sees a subdivided
    input, as in training: the 24-edge torus from level 1 gets 0.99× the oracle's density.

    .. math:: v_{l+1} = 2\\,U_l\\big(v_l + G_l(v_l, z_l)\\big),\\quad l = \\text{start\\_level} \\ldots
       \\text{stop\\_level},\\quad v_{\\text{start}} = (\\text{target} - \\bar v) / \\bar\\ell

    Args:
      model: a trained :class:`~jmeshtex.dgts.Model`.
      target: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])`` (any scale and
        placement; open or closed, any genus).
      key: PRNG key of the noise.
      start_level: first generator to run (0: coarsest); the target is treated as a level-``start``
        mesh, so ``stop_level − start_level`` subdivisions follow. None: jmeshtex's default,
        :func:`~jmeshtex.dgts.core.choose_start_level` (the level matching the target's
        resolution, at least 1, within ``max_faces``; the result's ``start_level`` says which);
        the official default is 1.
      stop_level: last generator to run, in ``[start_level, L − 1]`` (the official
        ``--gen-levels`` stop, default 4 clipped to ``L − 1``); None: the last level.
      num_samples: independent noise draws.
      max_faces: face budget of the output (checked for an explicit ``start_level`` too); None: no
        budget (with ``start_level=None`` then 500 000).
      zero_noise_from: zero noise at levels ``≥`` this; None: ``start_level + 2`` (the official
        ``growing``: noise on the first two levels run); ``model.num_levels``: noise everywhere;
        with ``zero_noise_from ≤ start_level`` the output does not depend on ``key``.
      per_level: also return every level's output (``level_vertices``, ``level_faces``: Fig. 6).

    Returns:
      :class:`Transfer` in the target's coordinates.

    Raises:
      FaceBudgetError: the output would exceed ``max_faces`` (an :class:`~jmeshtex.InputError`).
      InputError: a bad ``start_level``, ``num_samples`` or ``zero_noise_from``, an untrained model,
        a target that is not a mesh.
      MeshError: (a subclass) an invalid target.

    Example:
      >>> from jmeshtex.data import icosahedron, torus
      >>> from jmeshtex.dgts import Config
      >>> from jmeshtex.dgts.core import init_level
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(2))
      >>> model = Model(c, gs, gs, np.zeros((12, 3), np.float32))  # untrained, two levels
      >>> res = transfer(model, torus(8, 6), num_samples=2, key=jax.random.key(0))
      >>> res.vertices.shape, res.faces.shape, res.start_level  # a two-level model starts at 1
      ((2, 48, 3), (96, 3), 1)
      >>> transfer(model, torus(8, 6), start_level=0, key=jax.random.key(0)).faces.shape
      (384, 3)
    """
    if not is_int(num_samples, 1):
        raise InputError(f"num_samples must be a positive int, got {num_samples!r}")
    plan, zero_from = _noise_plan(
        model, target, start_level, stop_level, max_faces, zero_noise_from
    )
    draws = [
        _noises(jax.random.fold_in(key, s), plan.sizes, model.config.noise_amplitude)
        for s in range(int(num_samples))
    ]
    return _synthesise(model, plan, _zero_above(draws, plan, zero_from), per_level=per_level)


def conditional(
    model: Model,
    template: Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]],
    *,
    level: int,
    key: PRNGKey,
    num_samples: int = 1,
    per_level: bool = False,
) -> Transfer:
    """Generation conditioned on the training shape at scale ``level`` (the paper's Fig. 5).

    The template runs through every level; levels ``< level`` get the reconstruction noise
    (:meth:`Model.reconstruction_noise`), levels ``≥ level`` fresh noise. The coarse shape up to ``level − 1`` is
    therefore the reconstruction's and only finer detail varies between samples.

    Args:
      model: a trained model.
      template: the training template (``Mesh(meshes.template, meshes.faces[0])``): its vertex
        count must match ``model.z_star``.
      level: first level with fresh noise, in ``[0, L]`` (``L``: no fresh noise, the
        reconstruction itself; 0: an unconditional sample).
      key: PRNG key of the fresh noise.
      num_samples: independent draws.
      per_level: also return every level's output.

    Returns:
      :class:`Transfer` in the template's coordinates.

    Raises:
      InputError: a bad ``level`` or a template that does not match ``z*``.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.dgts import Config
      >>> from jmeshtex.dgts.core import init_level
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(2))
      >>> model = Model(c, gs, gs, np.zeros((12, 3), np.float32))  # untrained, two levels
      >>> out = conditional(model, icosahedron(), level=1, num_samples=2, per_level=True,
      ...                   key=jax.random.key(0))
      >>> bool(np.array_equal(out.level_vertices[0][0], out.level_vertices[0][1]))  # level 0: reconstruction
      True
    """
    L = model.num_levels
    k = _check_level("level", level, 0, L)
    if not is_int(num_samples, 1):
        raise InputError(f"num_samples must be a positive int, got {num_samples!r}")
    plan = plan_transfer(model, template, start_level=0)
    rec = model.reconstruction_noise(plan.sizes)
    draws = []
    for s in range(int(num_samples)):
        fresh = _noises(jax.random.fold_in(key, s), plan.sizes, model.config.noise_amplitude)
        draws.append([rec[i] if i < k else fresh[i] for i in range(L)])
    return _synthesise(model, plan, draws, per_level=per_level)


def reconstruct(
    model: Model,
    template: Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]],
    *,
    per_level: bool = True,
) -> Transfer:
    """The training reconstruction: the template through every level with the reconstruction noise.

    Deterministic (no key). Level ``l``'s output times ``scale_factor**l`` is the reconstruction
    the generator ``l`` was trained to match against ``meshes.vertices[l]`` (template coordinates
    are the level-0 frame).

    Args:
      model: a trained model.
      template: the training template (vertex count of ``model.z_star``).
      per_level: return every level's output (default True).

    Returns:
      :class:`Transfer` with one sample.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.dgts import Config
      >>> from jmeshtex.dgts.core import init_level
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(2))
      >>> model = Model(c, gs, gs, np.zeros((12, 3), np.float32))  # untrained, two levels
      >>> [v.shape for v in reconstruct(model, icosahedron()).level_vertices]
      [(1, 12, 3), (1, 42, 3)]
    """
    return conditional(
        model, template, level=model.num_levels, key=jax.random.key(0), per_level=per_level
    )


def interpolate(
    model: Model,
    target: Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]],
    *,
    key: PRNGKey,
    start_level: int | None = None,
    stop_level: int | None = None,
    num_frames: int = 8,
    max_faces: int | None = 500_000,
    zero_noise_from: int | None = None,
) -> Transfer:
    """Frames of a latent interpolation between two noise draws (the reference code's animation).

    .. math:: z(t) = (1 - t)\\, z_a + t\\, z_b,\\qquad t = 0, \\tfrac{1}{N-1}, \\ldots, 1

    Args:
      model, target, start_level, stop_level, max_faces, zero_noise_from: as :func:`transfer`
        (both draws).
      key: PRNG key of ``z_a`` and ``z_b``.
      num_frames: frames including both ends (≥ 2).

    Returns:
      :class:`Transfer` with one "sample" per frame; ``noise[0]`` is ``z_a`` and
      ``noise[-1]`` is ``z_b``.

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.dgts import Config
      >>> from jmeshtex.dgts.core import init_level
      >>> c = Config(num_layers=3, start_features=4, min_features=4, max_features=4)
      >>> gs = tuple(init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(2))
      >>> model = Model(c, gs, gs, np.zeros((12, 3), np.float32))  # untrained, two levels
      >>> interpolate(model, icosahedron(), start_level=1, num_frames=3, key=jax.random.key(0)).vertices.shape
      (3, 12, 3)
    """
    if not is_int(num_frames, 2):
        raise InputError(f"num_frames must be an int >= 2, got {num_frames!r}")
    plan, zero_from = _noise_plan(
        model, target, start_level, stop_level, max_faces, zero_noise_from
    )
    ka, kb = jax.random.split(key)
    za, zb = _zero_above(
        [
            _noises(ka, plan.sizes, model.config.noise_amplitude),
            _noises(kb, plan.sizes, model.config.noise_amplitude),
        ],
        plan,
        zero_from,
    )
    weights = [np.float32(t) for t in np.linspace(0.0, 1.0, int(num_frames))]
    draws = [[(1 - w) * a + w * b for a, b in zip(za, zb, strict=True)] for w in weights]
    return _synthesise(model, plan, draws, per_level=False)


def normal_heights(
    mesh: Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]],
    *,
    smoothing: int = 10,
    lam: float = 0.5,
    mu: float = -0.53,
) -> Float[np.ndarray, " V"]:
    """Per-vertex height along the normal of a smoothed copy of the mesh, in mean edges.

    .. math:: h_i = \\frac{(v_i - \\bar v_i)\\cdot \\bar n_i}{\\bar\\ell},\\qquad
       \\bar v = \\big((I + \\mu \\Delta)(I + \\lambda \\Delta)\\big)^{k} v

    Taubin's shrink-free smoothing with the uniform graph Laplacian ``Δ = D^{-1}A − I``
    (:func:`jmeshtex.geometry.taubin_smooth`, ``k = smoothing`` pairs of steps), ``n̄`` the smoothed mesh's vertex normals and ``ℓ̄`` the mean
    edge length. Bumps point outwards as positive heights; the distribution of ``h`` summarises a
    geometric texture.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or a ``(vertices [V, 3], faces [F, 3])`` pair.
      smoothing: pairs of Taubin steps.
      lam, mu: the shrink and inflate factors of a pair.

    Returns:
      ``[V]`` float64 heights in mean edges.

    Example:
      >>> from jmeshtex.data import grid
      >>> float(np.abs(normal_heights(grid(6))).max())  # a flat sheet has no texture
      0.0
    """
    v, f = as_mesh(mesh, what="normal_heights: mesh")
    v = np.asarray(v, np.float64)
    f = np.asarray(f, np.int64)
    pairs = unique_edges(f, len(v))
    smooth = taubin_smooth((v, f), steps=smoothing, lam=lam, mu=mu)
    n = vertex_normals(smooth, f)
    ell = np.linalg.norm(v[pairs[:, 0]] - v[pairs[:, 1]], axis=1).mean()
    return np.einsum("vd,vd->v", v - smooth, n) / ell

"""Hyper-parameters of MeshMatch (Chen et al. 2012): fans, features, PatchMatch schedule."""

from __future__ import annotations

import dataclasses

from .._config import ConfigBase, cross_rule, display_name, integers, is_finite_number, is_int, rule
from .._errors import InputError
from ..geometry import up_vector


def _as_tuple(weight: float | tuple[float, ...]) -> tuple[float, ...]:
    return weight if isinstance(weight, tuple) else (weight,)


def _weights_ok(values: tuple[float, ...]) -> bool:
    return bool(values) and all(is_finite_number(v) and v >= 0 for v in values)


def _up_ok(up) -> bool:
    if up is None:
        return True
    try:
        up_vector(up)
    except InputError:
        return False
    return True


def _unit_axis(axis) -> tuple[float, float, float] | None:
    return None if axis is None else tuple(float(x) for x in up_vector(axis))


#: a weight's message shows the value as the 1-tuple the tuple-valued shape_weight is checked as
MAX_FAN_RADIUS = 64.0
"""The largest ``Config.fan_radius`` (mean edge lengths): tracing cost grows with the radius and a
larger fan no longer describes a local patch."""

_WEIGHT_MESSAGE = "{cls}.{name} must be finite and >= 0, got ({value!r},)"


@dataclasses.dataclass(frozen=True)
class Experimental(ConfigBase):
    """MeshMatch's search budget and the paper's variants of it: ``Config.experimental``.

    The defaults are the measured ones (``docs/design_notes.md``, MeshMatch); the benchmark's and
    the studies' option rows set them. Their names are unique across :class:`~jmeshtex.meshmatch.Config`, so
    ``Config().replace(star_candidates=True)`` and ``Config.intrinsic(exact_candidates=64)``
    reach them, and a saved transfer stores them among the config's own fields.

    Attributes:
      hks_max_vertices: the HKS is computed on the finest hierarchy level with at most this many
        vertices and copied down to the finer levels through the parent maps (it is smooth).
      random_search_levels: how many hierarchy levels the random search hops up (then down again
        at random); 0 turns the hierarchical search off.
      global_candidates: uniformly random source vertices tried per target vertex and iteration.
      exact_candidates: per candidate set (random search + first sweep, then each further sweep)
        only this many candidates, those with the smallest rotation-invariant lower bound of the
        patch distance, get the exact rotation search (a number at least the candidate count,
        about ``3 + global_candidates + K``, searches every candidate exactly, as the paper does).
      star_candidates: propagation proposes the whole star (the vertex and its one-ring) of each
        neighbour's match, as the paper does, instead of the one star vertex nearest the
        propagated offset (about 7× the candidates, all pre-scored by the bound).
      bucket_vertices: hierarchy levels with at most this many target vertices are padded to one
        common shape and share one compiled PatchMatch step; larger levels share theirs in pairs
        (see :func:`~jmeshtex.meshmatch.core.level_groups`); 0 pads nothing (every level
        compiles its own step).
      interp_sigma: standard deviation of the Gaussian that reads a source colour at an offset
        inside the matched vertex's star (the vote's resampling), in the source level's mean edge
        lengths. At 0.5 a vertex read at its own position keeps only about 55 % of its own colour
        (six neighbours one edge away weigh ``e⁻²`` each): the vote blurs by about an edge
        (0.5: smaller values did not help consistently, ``docs/design_notes.md``).

    Example:
      >>> Config().replace(star_candidates=True).experimental.star_candidates
      True
    """

    hks_max_vertices: int = 4096
    random_search_levels: int = 3
    global_candidates: int = 4
    exact_candidates: int = 2
    star_candidates: bool = False
    bucket_vertices: int = 4096
    interp_sigma: float = 0.5

    _RULES = (
        integers("hks_max_vertices", 16),
        integers("exact_candidates", 1),
        integers("random_search_levels global_candidates bucket_vertices", 0),
        rule("interp_sigma", lambda x: is_finite_number(x) and x > 0, "a positive number"),
    )


@dataclasses.dataclass(frozen=True)
class Config(ConfigBase):
    """Settings of a MeshMatch transfer. All lengths are in units of the level's mean edge length.

    The default assumes source and target in a common pose (the same orientation and up axis, up to
    a per-axis scale and offset: positions are compared after per-axis moment standardisation, see
    ``aligned``); :meth:`Config.intrinsic` gives the pose-free features (HKS and ``n · up``). The
    measurements behind each default are in ``docs/results.md`` (MeshMatch); the reasoning in
    ``docs/design_notes.md`` (MeshMatch).

    Attributes:
      num_radii: ``R``, rings per geodesic fan (paper default 3).
      num_angles: ``A``, samples per ring (paper default 18); rotations are searched in steps of
        ``2π / A``.
      fan_radius: radius of the outermost ring, in mean edge lengths of the target's level (or of
        the paired source level where that is coarser: a target finer than the source gets fans
        at the source's scale); ring ``i`` (0-based) has radius ``fan_radius · (i + 1) / R``; at most
        ``MAX_FAN_RADIUS`` (64).
      color_weight: weight of the colour term of the patch distance (normalised per dimension and
        by the source colour variance).
      shape_weight: weight of the shape term (HKS, the whole normal and the standardised positions;
        HKS and ``n · up`` with :meth:`Config.intrinsic`; each feature standardised), one value for
        every level or a tuple from the finest level to the coarsest (the last entry repeats for
        further levels). Default (0.3, 3, 30): the shape places patches at the coarse levels, the
        colours refine them at the finest (``docs/design_notes.md``, ``shape_weight``).
      affinity_weight: weight of the correspondence affinities (only with correspondences).
      hks_times: number of log-spaced heat kernel signature times.
      hks_eigenpairs: Laplacian eigenpairs used for the HKS (32: more cost time and did not help
        across shapes, ``docs/design_notes.md``, ``hks_eigenpairs``).
      up: the "up" direction of the ``n · up`` shape feature: a 3-vector or an axis name
        ``"x"|"y"|"z"|"-x"|"-y"|"-z"`` (``"y"`` for Y-up models, as OBJ files are usually
        authored), or None to leave the feature out. Source and target must share it. Used only
        by :meth:`Config.intrinsic` (``aligned=False``); the aligned default uses the whole normal,
        which needs no up axis (only that both meshes share their pose).
      side: a second direction, as ``up``, for one more feature ``n · side`` (None, the default:
        none). HKS and ``n · up`` are unchanged by a mirror across a plane that contains ``up``,
        so a bilaterally symmetric model can match its left half to its right; ``n · side`` along
        the left/right axis changes sign under that mirror. Only with :meth:`Config.intrinsic`
        (``aligned=False``): the aligned default tells left from right by position.
      aligned: source and target share a pose (the same orientation in world space and the same up
        axis) -- the default. The whole normal ``(n · x, n · y, n · z)`` and the vertex positions
        standardised per axis (mean 0, standard deviation 1 on each mesh, which also undoes a
        non-uniform stretch) join the HKS as shape features, instead of ``n · up`` / ``n · side``
        (``up`` is then ignored; ``side`` must stay None). False (:meth:`Config.intrinsic`): the
        pose-free features, HKS and ``n · up`` only, for meshes in different poses or
        correspondences that contradict the pose (``docs/design_notes.md``, ``aligned``).
      normal_weight: the weight of each ``n · axis`` feature block relative to the HKS block;
        None (default): 2 with ``aligned``, 1 without.
      position_weight: with ``aligned``, the weight of the per-axis standardised positions as
        one more feature block (a pose prior); None (default): 8 with ``aligned``
        (``docs/design_notes.md``, ``position_weight``); 0 leaves it out. Without ``aligned`` it must
        be None or 0.
      steps: most PatchMatch iterations (E-step + M-step) per level.
      coarse_steps: most iterations at the coarsest level, which starts from a random field
        (propagation moves good matches ``sweeps`` rings per iteration there; the level is tiny).
      tolerance: a level stops early when fewer than this fraction of target vertices changed
        their match in an iteration.
      sweeps: propagation sweeps per iteration; each sweep propagates from the matches the previous
        one found, so an iteration moves good matches ``sweeps`` rings (1 = Jacobi-style).
      propagation: ``"parallel"`` (default: every target vertex of a sweep proposes from the
        matches the previous sweep left, Jacobi-style, ``sweeps`` rings per iteration) or
        ``"sequential"`` (the paper's scan, Gauss–Seidel: each sweep runs through the target's
        breadth-first wavefronts from vertex 0 one after the other, every wavefront proposing from
        the matches the earlier ones just found; odd sweeps run backwards from the far end). The
        default is parallel: as accurate, several times faster
        (``docs/design_notes.md``, ``propagation``).
      vote: the M-step (how the target's colours are voted from the matches), ``"ring"`` (default)
        or ``"fan"``. ``"ring"``: a vertex averages the source colours its own match and its
        one-ring neighbours' matches put at its position (read in the matched star, see
        ``interp_sigma``), Gaussian weights of the neighbour's distance (``vote_sigma`` target
        edges). ``"fan"`` (the paper's footprint vote): every target vertex q votes at every point
        its geodesic fan covers: fan sample ``(r, a)`` of q carries the source colour at fan sample
        ``(r, a + k_q)`` of its match onto the corners of the target face it lies in with their
        barycentric weights, times a Gaussian of the ring radius (``vote_sigma`` in the fans' edge
        lengths), plus q's centre with weight 1. The default is ``"ring"``: cheaper, sharper, the
        same final colours (``docs/design_notes.md``, ``vote``).
      upsample: how a finer level starts from the coarser one, ``"copy"`` (default: each vertex
        takes its coarse parent's match and rotation and colour) or ``"offset"`` (the paper's): the
        parent's match moved by the vertex's geodesic offset from its parent (the tangent-plane
        offset in the parent's frame, rotated into the match's frame by the parent's rotation),
        landing on the source vertex of the finer source level nearest that point, with the
        rotation carried the same way, then a re-vote of the level's colours before its
        iterations. The default is ``"copy"``: the level's iterations erase the offset start's
        head start (``docs/design_notes.md``, ``upsample``).
      vote_sigma: standard deviation of the Gaussian vote weights (M-step), in mean edge lengths
        (of the target level with ``vote="ring"``; of the fans, as ``fan_radius``, with
        ``vote="fan"``; ``docs/design_notes.md``, ``vote_sigma``).
      min_vertices: coarsest hierarchy level size (decimation stops below it).
      levels: number of hierarchy levels, or None for "down to ``min_vertices``".
      max_scale_ratio: the largest ratio of the source's and the target's bounding-box diagonals
        :func:`~jmeshtex.meshmatch.meshmatch` accepts (either way) before it raises an
        :class:`~jmeshtex.InputError`: fans and levels are paired in world units, so meshes in
        different units (a ×100 mismatch) otherwise pair the wrong levels silently. None turns
        the check off (a small exemplar patch on a large mesh, on purpose).
      dtype: ``"float32"`` (default, the fast path) or ``"float64"`` for the jitted steps.
      experimental: the search budget and the paper's variants of it
        (:class:`~jmeshtex.meshmatch.core.Experimental`: HKS level size, random and global
        candidates, exact and whole-star candidates, level buckets, the vote's resampling width);
        each may also be given by its own name to ``replace``, ``from_dict`` and
        :meth:`intrinsic`.

    Example:
      >>> c = Config(num_angles=12)
      >>> c.num_angles, c.shape_weight_at(5)
      (12, 30.0)
    """

    num_radii: int = 3
    num_angles: int = 18
    fan_radius: float = 4.0
    color_weight: float = 1.0
    shape_weight: float | tuple[float, ...] = (0.3, 3.0, 30.0)
    affinity_weight: float = 1.0
    hks_times: int = 8
    hks_eigenpairs: int = 32
    up: tuple[float, float, float] | str | None = (0.0, 0.0, 1.0)
    side: tuple[float, float, float] | str | None = None
    aligned: bool = True
    normal_weight: float | None = None
    position_weight: float | None = None
    steps: int = 6
    coarse_steps: int = 30
    tolerance: float = 0.002
    sweeps: int = 2
    propagation: str = "parallel"
    vote: str = "ring"
    upsample: str = "copy"
    vote_sigma: float = 1.0
    min_vertices: int = 128
    levels: int | None = None
    max_scale_ratio: float | None = 2.0
    dtype: str = "float32"
    experimental: Experimental = Experimental()

    _RULES = (
        integers("num_radii", 1),
        integers("num_angles", 2),
        integers("hks_times", 1),
        integers("hks_eigenpairs", 2),
        integers("steps coarse_steps", 1),
        integers("min_vertices", 8),
        integers("sweeps", 1),
        rule(
            "vote_sigma",
            lambda x: is_finite_number(x) and x > 0,
            "a positive number",
        ),
        rule(
            "fan_radius",
            lambda x: is_finite_number(x) and 0 < x <= MAX_FAN_RADIUS,
            f"a number in (0, {MAX_FAN_RADIUS:g}] (mean edge lengths: a fan's trace walks about that "
            "many faces, and the default 4 covers a patch of a few rings)",
        ),
        rule(
            "normal_weight position_weight",
            lambda x: x is None or (is_finite_number(x) and x >= 0),
            "None or a number >= 0",
        ),
        rule("aligned", lambda x: isinstance(x, bool), "True or False"),
        rule("color_weight", lambda x: _weights_ok((x,)), message=_WEIGHT_MESSAGE),
        cross_rule(
            lambda c: _weights_ok(_as_tuple(c.shape_weight)),
            lambda c: (
                f"{display_name(type(c))}.shape_weight must be finite and >= 0, got {_as_tuple(c.shape_weight)!r}"
            ),
        ),
        rule("affinity_weight tolerance", lambda x: _weights_ok((x,)), message=_WEIGHT_MESSAGE),
        cross_rule(
            lambda c: c.color_weight != 0 or any(w != 0 for w in _as_tuple(c.shape_weight)),
            "color_weight and shape_weight are all 0: the patch distance would be constant",
        ),
        rule("side", _up_ok, "a non-zero 3-vector, one of x, y, z, -x, -y, -z, or None"),
        rule("up", _up_ok, "a non-zero 3-vector, one of x, y, z, -x, -y, -z, or None"),
        cross_rule(
            lambda c: not (c.aligned and c.side is not None),
            "{cls}.side has no effect with aligned=True (the whole normal and the positions are "
            "features): use {cls}.intrinsic(side=...) for the pose-free n·side feature",
        ),
        cross_rule(
            lambda c: c.aligned or not c.position_weight,
            "{cls}.position_weight needs aligned=True (positions are a pose prior), got "
            "position_weight={c.position_weight!r} with aligned=False",
        ),
        rule(
            "max_scale_ratio",
            lambda x: x is None or (is_finite_number(x) and x >= 1),
            "None or a number >= 1",
        ),
        rule("levels", lambda x: x is None or is_int(x, 1), "None or an integer >= 1"),
        rule("dtype", lambda x: x in ("float32", "float64"), "'float32' or 'float64'"),
        rule(
            "propagation", lambda x: x in ("parallel", "sequential"), "'parallel' or 'sequential'"
        ),
        rule("vote", lambda x: x in ("ring", "fan"), "'ring' or 'fan'"),
        rule("upsample", lambda x: x in ("copy", "offset"), "'copy' or 'offset'"),
    )

    @classmethod
    def intrinsic(cls, **fields) -> Config:
        """The pose-free configuration: HKS and ``n · up`` (and ``n · side`` if given) as shape
        features, no normal components along fixed axes and no positions (``aligned=False``), for
        source and target in different poses (the default assumes a shared pose and up axis).

        Example:
          >>> c = Config.intrinsic(up="y")
          >>> c.aligned, c.normal_axes()["up"], c.normal_axes()["position_weight"]
          (False, (0.0, 1.0, 0.0), 0.0)
        """
        return cls.from_dict({"aligned": False, **fields})

    def up_vector(self) -> tuple[float, float, float] | None:
        """``up`` as a unit 3-vector (axis names resolved), or None.

        Example:
          >>> Config(up="-y").up_vector()
          (0.0, -1.0, 0.0)
        """
        return _unit_axis(self.up)

    def side_vector(self) -> tuple[float, float, float] | None:
        """``side`` as a unit 3-vector (axis names resolved), or None.

        Example:
          >>> Config.intrinsic(side="z").side_vector()
          (0.0, 0.0, 1.0)
        """
        return _unit_axis(self.side)

    def normal_axes(self) -> dict:
        """The ``up`` / ``side`` / ``axes`` / ``normal_weight`` arguments of
        :func:`~jmeshtex.meshmatch.core.shape_features` these settings ask for.

        Example:
          >>> a = Config().normal_axes()
          >>> a["axes"], a["normal_weight"], a["position_weight"]
          (((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)), 2.0, 8.0)
        """
        if self.aligned:
            return {
                "up": None,
                "side": None,
                "axes": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
                "normal_weight": 2.0 if self.normal_weight is None else float(self.normal_weight),
                "position_weight": 8.0
                if self.position_weight is None
                else float(self.position_weight),
            }
        return {
            "up": self.up_vector(),
            "side": self.side_vector(),
            "axes": (),
            "normal_weight": 1.0 if self.normal_weight is None else float(self.normal_weight),
            "position_weight": 0.0,
        }

    def shape_weight_at(self, level: int) -> float:
        """The shape weight of hierarchy level ``level`` (0 = finest)."""
        if isinstance(self.shape_weight, tuple):
            return float(self.shape_weight[min(level, len(self.shape_weight) - 1)])
        return float(self.shape_weight)

    def radii(self, edge: float) -> tuple[float, ...]:
        """Ring radii for a level whose mean edge length is ``edge``."""
        return tuple(
            self.fan_radius * edge * (i + 1) / self.num_radii for i in range(self.num_radii)
        )

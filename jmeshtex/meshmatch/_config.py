"""Hyper-parameters of MeshMatch (Chen et al. 2012): fans, features, PatchMatch schedule."""

from __future__ import annotations

import dataclasses
import math

from .._errors import ConfigError


@dataclasses.dataclass(frozen=True)
class MeshMatchConfig:
    """Settings of a MeshMatch transfer. All lengths are in units of the level's mean edge length.

    Attributes:
      num_radii: ``R``, rings per geodesic fan (paper default 3).
      num_angles: ``A``, samples per ring (paper default 18); rotations are searched in steps of
        ``2π / A``.
      fan_radius: radius of the outermost ring, in mean edge lengths of the target's level; ring
        ``i`` (0-based) has radius ``fan_radius · (i + 1) / R``.
      color_weight: weight of the colour term of the patch distance (normalised per dimension and
        by the source colour variance).
      shape_weight: weight of the shape term (HKS and ``n · up``, each feature standardised), one
        value for every level or a tuple from the finest level to the coarsest (the last entry
        repeats for further levels). The default, 30 at every coarse level and 3 at the finest,
        lets the shape decide where patches go and the colours refine them last: the target's
        colours are synthesised, so with a weak shape term the coarse levels settle on a coherent
        but shifted placement that finer levels cannot undo (benchmark torus, 16K vertices:
        15 dB self-transfer PSNR at weight 3 everywhere, 31 dB at 30 everywhere, 32 dB with the
        default; the small demo sphere: 23 dB with the default, 20 dB at 30 everywhere).
      affinity_weight: weight of the correspondence affinities (only with correspondences).
      hks_times: number of log-spaced heat kernel signature times.
      hks_eigenpairs: Laplacian eigenpairs used for the HKS.
      hks_max_vertices: the HKS is computed on the finest hierarchy level with at most this many
        vertices and copied down to the finer levels through the parent maps (it is smooth).
      up: the "up" direction of the ``n · up`` shape feature, or None to leave the feature out.
      iterations: most PatchMatch iterations (E-step + M-step) per level.
      coarse_iterations: most iterations at the coarsest level, which starts from a random field
        (propagation moves good matches ``sweeps`` rings per iteration there; the level is tiny).
      tolerance: a level stops early when fewer than this fraction of target vertices changed
        their match in an iteration.
      random_search_levels: how many hierarchy levels the random search hops up (then down again
        at random); 0 turns the hierarchical search off.
      global_candidates: uniformly random source vertices tried per target vertex and iteration.
      sweeps: propagation sweeps per iteration; each sweep propagates from the matches the previous
        one found, so an iteration moves good matches ``sweeps`` rings (1 = Jacobi-style).
      exact_candidates: per candidate set (random search + first sweep, then each further sweep)
        only this many candidates, those with the smallest rotation-invariant lower bound of the
        patch distance, get the exact rotation search.
      bucket_vertices: hierarchy levels with at most this many target vertices are padded to one
        common shape and share one compiled PatchMatch step; larger levels share theirs in pairs
        (see :func:`~jmeshtex.meshmatch._patchmatch.level_groups`); 0 pads nothing (every level
        compiles its own step).
      vote_sigma: standard deviation of the Gaussian vote weights (M-step), in mean edge lengths.
      min_vertices: coarsest hierarchy level size (decimation stops below it).
      levels: number of hierarchy levels, or None for "down to ``min_vertices``".
      dtype: ``"float32"`` (default, the fast path) or ``"float64"`` for the jitted steps.

    Example:
      >>> c = MeshMatchConfig(num_angles=12)
      >>> c.num_angles, c.shape_weight_at(5)
      (12, 30.0)
    """

    num_radii: int = 3
    num_angles: int = 18
    fan_radius: float = 4.0
    color_weight: float = 1.0
    shape_weight: float | tuple[float, ...] = (3.0, 30.0)
    affinity_weight: float = 1.0
    hks_times: int = 8
    hks_eigenpairs: int = 32
    hks_max_vertices: int = 4096
    up: tuple[float, float, float] | None = (0.0, 0.0, 1.0)
    iterations: int = 6
    coarse_iterations: int = 30
    tolerance: float = 0.002
    random_search_levels: int = 3
    global_candidates: int = 4
    sweeps: int = 2
    exact_candidates: int = 2
    bucket_vertices: int = 4096
    vote_sigma: float = 1.0
    min_vertices: int = 128
    levels: int | None = None
    dtype: str = "float32"

    def __post_init__(self):
        ints = {
            "num_radii": 1, "num_angles": 2, "hks_times": 1, "hks_eigenpairs": 2,
            "hks_max_vertices": 16, "iterations": 1, "coarse_iterations": 1, "min_vertices": 8,
            "sweeps": 1, "exact_candidates": 1,
        }
        for name, low in ints.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ConfigError(f"MeshMatchConfig.{name} must be an integer >= {low}, got {value!r}")
        for name in ("random_search_levels", "global_candidates", "bucket_vertices"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ConfigError(f"MeshMatchConfig.{name} must be an integer >= 0, got {value!r}")
        for name in ("fan_radius", "vote_sigma"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ConfigError(f"MeshMatchConfig.{name} must be a positive number, got {value!r}")
        weights = self.shape_weight if isinstance(self.shape_weight, tuple) else (self.shape_weight,)
        for name, values in (("color_weight", (self.color_weight,)), ("shape_weight", weights),
                             ("affinity_weight", (self.affinity_weight,)), ("tolerance", (self.tolerance,))):
            if not values or not all(isinstance(v, (int, float)) and math.isfinite(v) and v >= 0 for v in values):
                raise ConfigError(f"MeshMatchConfig.{name} must be finite and >= 0, got {values!r}")
        if self.color_weight == 0 and all(w == 0 for w in weights):
            raise ConfigError("color_weight and shape_weight are all 0: the patch distance would be constant")
        if self.up is not None:
            up = tuple(self.up)
            if len(up) != 3 or not all(math.isfinite(float(x)) for x in up) or all(float(x) == 0 for x in up):
                raise ConfigError(f"MeshMatchConfig.up must be a non-zero 3-vector or None, got {self.up!r}")
        if self.levels is not None and (isinstance(self.levels, bool) or not isinstance(self.levels, int)
                                        or self.levels < 1):
            raise ConfigError(f"MeshMatchConfig.levels must be None or an integer >= 1, got {self.levels!r}")
        if self.dtype not in ("float32", "float64"):
            raise ConfigError(f"MeshMatchConfig.dtype must be 'float32' or 'float64', got {self.dtype!r}")

    def shape_weight_at(self, level: int) -> float:
        """The shape weight of hierarchy level ``level`` (0 = finest)."""
        if isinstance(self.shape_weight, tuple):
            return float(self.shape_weight[min(level, len(self.shape_weight) - 1)])
        return float(self.shape_weight)

    def radii(self, edge: float) -> tuple[float, ...]:
        """Ring radii for a level whose mean edge length is ``edge``."""
        return tuple(self.fan_radius * edge * (i + 1) / self.num_radii for i in range(self.num_radii))

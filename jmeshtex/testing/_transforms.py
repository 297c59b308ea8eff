"""The transform catalogue of the equivariance harness.

A :class:`Transform` draws a concrete :class:`Realisation`: a source mesh state, a target mesh state,
and the map that carries every kind of value (``jmeshtex/testing/_fields.py``) from the source to the
target. An operator ``fn`` is equivariant under the transform when ``fn(target, T·x) = T·fn(source, x)``.

=====================  =====  =============================================================
transform              exact  what it does
=====================  =====  =============================================================
``rigid``              yes    random rotation in SO(3) plus translation
``reflection``         yes    random improper rotation (det −1) plus translation (opt-in)
``gauge``              yes    rotates every vertex's tangent frame by a random angle
``permute_vertices``   yes    random relabelling of the vertices
``permute_faces``      yes    random reordering of the faces
``rotate_corners``     yes    cyclic rotation of each face's vertex order (random shifts)
``fold``               yes    a flat sheet folded along one mesh line (random angle)
``folds``              yes    a flat sheet folded along several mesh lines
``hinge``              yes    a rigid piece turned about a hinge line of the mesh
``cylinder``           no     a flat sheet rolled onto a cylinder (isometric as h → 0)
``cone``               no     a flat annular sector rolled onto a cone
``catenoid``           no     helicoid bent into a catenoid (isometric as h → 0)
``retriangulate``      no     random edge flips of a flat sheet (same surface, new mesh)
=====================  =====  =============================================================

Smooth isometries are families indexed by a resolution ``n``; the harness checks the order of
convergence of the error as ``n`` doubles, not a fixed tolerance. Re-triangulation is reported only.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from .._errors import InputError
from ._fields import (
    EXTRINSIC_KINDS,
    FACE_EDGE,
    FACE_SCALAR,
    FACE_VECTOR,
    INVARIANT,
    POINTS,
    VERTEX_SCALAR,
    VERTEX_TANGENT,
    VERTEX_VECTOR,
    Field,
)
from ._state import MeshState


@dataclasses.dataclass
class Realisation:
    """A drawn transform: source and target states and how values map between them.

    Attributes:
      name: the transform's name.
      source, target: the two :class:`MeshState` s.
      vperm: ``[V]`` target vertex i corresponds to source vertex ``vperm[i]``.
      fperm: ``[F]`` target face j corresponds to source face ``fperm[j]``.
      froll: ``[F]`` target face j's corner k is source face ``fperm[j]``'s corner ``(k + froll[j]) % 3``.
      rotation, translation: the rigid motion (``x → R x + t``), or None when the transform is not
        rigid (extrinsic kinds then have no defined action).
    """

    name: str
    source: MeshState
    target: MeshState
    vperm: np.ndarray
    fperm: np.ndarray
    froll: np.ndarray
    rotation: np.ndarray | None = None
    translation: np.ndarray | None = None
    _theta: np.ndarray | None = dataclasses.field(default=None, repr=False)

    def acts_on(self, kind: str) -> bool:
        """Whether this realisation defines an action on values of ``kind``."""
        return kind not in EXTRINSIC_KINDS or self.rotation is not None

    def frame_rotation(self) -> np.ndarray:
        """``[V_target]`` angle β_p such that a tangent value maps as ``x_t[p] = x_s[vperm[p]] e^{-iβ_p}``.

        β combines the target's and source's gauges with the angle θ_p, measured in the source's
        intrinsic frame at ``vperm[p]``, of the target's intrinsic reference direction (the first
        one-ring neighbour): β = θ + α_target − α_source.
        """
        if self._theta is None:
            self._theta = self._intrinsic_offset()
        return self._theta + self.target.gauge - self.source.gauge[self.vperm]

    def _intrinsic_offset(self) -> np.ndarray:
        same_labels = np.array_equal(self.vperm, np.arange(len(self.vperm)))
        if same_labels and np.array_equal(self.source.faces, self.target.faces):
            return np.zeros(self.target.num_vertices)
        from ..geometry import one_ring_neighborhood

        src = one_ring_neighborhood(self.source.vertices, self.source.faces, scale=None)
        tgt = one_ring_neighborhood(self.target.vertices, self.target.faces, scale=None)
        ref = self.vperm[tgt.index[:, 0]]  # target's reference neighbour, in source labels
        s = self.vperm
        hit = (np.asarray(src.index)[s] == ref[:, None]) & np.asarray(src.mask)[s]
        slot = np.argmax(hit, axis=1)
        theta = np.angle(np.asarray(src.log)[s, slot])
        missing = ~hit.any(axis=1)
        if missing.any():
            # new connectivity (re-triangulation): the target's reference neighbour is not in the
            # source's one-ring; measure the angle extrinsically (exact on flat regions only)
            theta[missing] = self._extrinsic_offset(src, tgt)[missing]
        return theta

    def _extrinsic_offset(self, src, tgt) -> np.ndarray:
        s = self.vperm
        pos = self.source.vertices
        u = pos[np.asarray(src.index)[s, 0]] - pos[s]
        w = pos[self.vperm[np.asarray(tgt.index)[:, 0]]] - pos[s]
        from ..geometry import tangent_frames

        n = np.asarray(tangent_frames(self.source.vertices, self.source.faces).normal)[s]
        return np.arctan2(np.einsum("ij,ij->i", n, np.cross(u, w)), np.einsum("ij,ij->i", u, w))

    def map(self, field: Field) -> Field:
        """Carry a source value to the target (see ``jmeshtex/testing/_fields.py`` for the rules)."""
        kind, x = field
        if not self.acts_on(kind):
            raise InputError(
                f"transform {self.name!r} has no action on {kind!r} values; check acts_on(kind) first"
            )
        x = np.asarray(x)
        if kind == INVARIANT:
            return field
        if kind == VERTEX_SCALAR:
            return Field(kind, x[self.vperm])
        if kind == FACE_SCALAR:
            return Field(kind, x[self.fperm])
        if kind == FACE_EDGE:
            y = x[self.fperm]
            k = (np.arange(3)[None, :] + self.froll[:, None]) % 3
            return Field(
                kind, np.take_along_axis(y, k.reshape(k.shape + (1,) * (y.ndim - 2)), axis=1)
            )
        if kind == VERTEX_TANGENT:
            beta = self.frame_rotation()
            turn = np.exp(-1j * beta).reshape((-1,) + (1,) * (x.ndim - 1))
            return Field(kind, (x[self.vperm] * turn).astype(x.dtype))
        if kind == VERTEX_VECTOR:
            return Field(kind, (x @ self.rotation.T)[self.vperm].astype(x.dtype))
        if kind == FACE_VECTOR:
            return Field(kind, (x @ self.rotation.T)[self.fperm].astype(x.dtype))
        if kind == POINTS:
            return Field(kind, (x @ self.rotation.T + self.translation)[self.vperm].astype(x.dtype))
        raise InputError(
            f"unknown field kind {kind!r}; see jmeshtex/testing/_fields.py for the kinds"
        )


def _identity(state: MeshState, target: MeshState, name: str, **kw) -> Realisation:
    return Realisation(
        name=name,
        source=state,
        target=target,
        vperm=np.arange(state.num_vertices),
        fperm=np.arange(state.num_faces),
        froll=np.zeros(state.num_faces, np.int64),
        **kw,
    )


def random_rotation(rng: np.random.Generator, *, proper: bool = True) -> np.ndarray:
    """A Haar-random 3×3 rotation (``proper=False``: a random improper rotation, det −1).

    Example:
      >>> R = random_rotation(np.random.default_rng(0))
      >>> bool(np.allclose(R @ R.T, np.eye(3))), round(float(np.linalg.det(R)), 6)
      (True, 1.0)
    """
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    if not proper:
        q = q @ np.diag([1.0, 1.0, -1.0])
    return q


@dataclasses.dataclass(frozen=True)
class Transform:
    """A named generator of realisations; :meth:`Transform.draw` draws one.

    Attributes:
      name: catalogue name.
      exact: True when the transform is an exact symmetry (checked against a tolerance); False for
        smooth isometries (checked by convergence order) and re-triangulation (reported).
      build: ``(state, rng) -> Realisation`` for transforms applicable to any mesh, or
        ``(n, rng, dtype) -> Realisation`` for transforms that build their own mesh family
        (``family=True``; ``n`` is the resolution, doubling halves the mesh spacing).
      family: see ``build``.
      doc: one line for reports.
    """

    name: str
    exact: bool
    build: Callable
    family: bool = False
    doc: str = ""

    def draw(
        self,
        rng: np.random.Generator,
        state: MeshState | None = None,
        *,
        resolution: int = 8,
        dtype=np.float64,
    ) -> Realisation:
        """Draw a realisation: of ``state``'s mesh, or of the family's mesh at ``resolution``.

        Args:
          rng: the generator every random choice is drawn from.
          state: the mesh to transform; required by transforms of any mesh, None for a family
            (``family=True``), which builds its own mesh.
          resolution: a family's resolution (cells per side; doubling halves the spacing).
          dtype: a family's dtype (``np.float64`` or ``np.float32``); a state carries its own.

        Returns:
          The :class:`Realisation`.

        Raises:
          InputError: a state given to a family, or none to a transform of any mesh.

        Example:
          >>> from jmeshtex.data import icosahedron
          >>> rng = np.random.default_rng(0)
          >>> CATALOGUE["gauge"].draw(rng, MeshState(*icosahedron())).target.num_vertices
          12
          >>> CATALOGUE["fold"].draw(rng, resolution=4).source.num_vertices
          25
        """

        if self.family:
            if state is not None:
                raise InputError(
                    f"{self.name!r} builds its own mesh: pass resolution=, not a state"
                )
            return self.build(int(resolution), rng, dtype)
        if not isinstance(state, MeshState):
            raise InputError(f"{self.name!r} transforms a given mesh: pass a MeshState as state")
        return self.build(state, rng)


# --- transforms on any mesh ------------------------------------------------------------------


def rigid_motion(state: MeshState, rotation: np.ndarray, translation=None) -> Realisation:
    """The realisation of ``x → R x + t`` applied to ``state`` (R may be improper).

    Example:
      >>> from jmeshtex.data import icosahedron
      >>> r = rigid_motion(MeshState(*icosahedron()), np.diag([1.0, -1.0, -1.0]))
      >>> r.name, r.target.vertices[0].round(3).tolist()
      ('rigid', [-0.526, -0.851, -0.0])
    """
    R = np.asarray(rotation, dtype=np.float64)
    t = np.zeros(3) if translation is None else np.asarray(translation, dtype=np.float64)
    target = state.with_(vertices=state.vertices @ R.T + t)
    name = "rigid" if np.linalg.det(R) > 0 else "reflection"
    return _identity(state, target, name, rotation=R, translation=t)


def gauge_change(state: MeshState, alpha: np.ndarray) -> Realisation:
    """The realisation of turning every vertex frame p by ``alpha[p]`` (radians, counter-clockwise)."""
    target = state.with_(gauge=state.gauge + np.asarray(alpha, dtype=np.float64))
    return _identity(state, target, "gauge", rotation=np.eye(3), translation=np.zeros(3))


def _rigid(state: MeshState, rng: np.random.Generator, *, proper: bool = True) -> Realisation:
    return rigid_motion(state, random_rotation(rng, proper=proper), rng.standard_normal(3))


def _gauge(state: MeshState, rng: np.random.Generator) -> Realisation:
    return gauge_change(state, rng.uniform(-np.pi, np.pi, state.num_vertices))


def _permute_vertices(state: MeshState, rng: np.random.Generator) -> Realisation:
    V = state.num_vertices
    vperm = rng.permutation(V)  # new i <- old vperm[i]
    inv = np.empty(V, np.int64)
    inv[vperm] = np.arange(V)
    target = state.with_(
        vertices=state.vertices[vperm], faces=inv[state.faces], gauge=state.gauge[vperm]
    )
    r = _identity(state, target, "permute_vertices", rotation=np.eye(3), translation=np.zeros(3))
    r.vperm = vperm
    return r


def _permute_faces(state: MeshState, rng: np.random.Generator) -> Realisation:
    fperm = rng.permutation(state.num_faces)
    target = state.with_(faces=state.faces[fperm])
    r = _identity(state, target, "permute_faces", rotation=np.eye(3), translation=np.zeros(3))
    r.fperm = fperm
    return r


def _rotate_corners(state: MeshState, rng: np.random.Generator) -> Realisation:
    roll = rng.integers(0, 3, state.num_faces)
    k = (np.arange(3)[None, :] + roll[:, None]) % 3
    target = state.with_(faces=np.take_along_axis(state.faces, k, axis=1))
    r = _identity(state, target, "rotate_corners", rotation=np.eye(3), translation=np.zeros(3))
    r.froll = roll
    return r


# --- exact isometries of a flat sheet -----------------------------------------------------------


def _sheet(n: int, rng: np.random.Generator, *, jitter: float = 0.25):
    """A flat ``n × n`` grid on [0,1]² with interior vertices jittered *along* the grid lines.

    Jitter keeps every grid row and column a straight mesh line (so folds stay exact) while breaking
    the ties of a perfectly regular grid (equal distances, equal angles).
    """
    from ..data import grid

    v, f = grid(n, n, diagonals="alternate")
    h = 1.0 / n
    ix = np.rint(v[:, 0] / h).astype(int)
    iy = np.rint(v[:, 1] / h).astype(int)
    # per-column x offsets and per-row y offsets keep lines straight
    dx = rng.uniform(-jitter, jitter, n + 1) * h
    dy = rng.uniform(-jitter, jitter, n + 1) * h
    dx[[0, -1]] = 0.0
    dy[[0, -1]] = 0.0
    v = v.copy()
    v[:, 0] += dx[ix]
    v[:, 1] += dy[iy]
    return v, f, ix, iy


def _folds(n_folds: int, name: str):
    def draw(n: int, rng: np.random.Generator, dtype) -> Realisation:
        from ._isometries import fold_sheet

        v, f, ix, iy = _sheet(n, rng)
        # fold along distinct grid columns (parallel lines: nested moving parts)
        cols = rng.choice(np.arange(2, n - 1), size=n_folds, replace=False)
        lines = [("x", float(v[(ix == c) & (iy == 0), 0][0])) for c in cols]
        angles = rng.uniform(0.3, 2.5, n_folds) * rng.choice([-1.0, 1.0], n_folds)
        folded = fold_sheet(v, f, lines=lines, angles=angles)
        source = MeshState(v, f, dtype=dtype)
        return _identity(source, source.with_(vertices=folded), name)

    return draw


def _hinge(n: int, rng: np.random.Generator, dtype) -> Realisation:
    """A sheet whose top rows turn about a hinge row, like a lid on a box."""
    from ._isometries import hinge

    v, f, ix, iy = _sheet(n, rng)
    r = int(rng.integers(2, n - 1))
    y = float(v[(iy == r) & (ix == 0), 1][0])
    moved = hinge(
        v,
        f,
        moving=iy > r,
        axis_point=(0.0, y, 0.0),
        axis_direction=(1.0, 0.0, 0.0),
        angle=float(rng.uniform(0.5, 2.8)),
    )
    source = MeshState(v, f, dtype=dtype)
    return _identity(source, source.with_(vertices=moved), "hinge")


# --- smooth isometries (families) -------------------------------------------------------------


def _parameter_grid(n: int, rng: np.random.Generator, *, jitter: float = 0.2):
    """An ``n × n`` grid on [0,1]² with interior vertices jittered by up to ``jitter·h``.

    The jitter breaks the exact ties of a regular grid (equal path lengths, cocircular quads), at
    which discrete choices such as k-NN selection or Delaunay flips would be decided by round-off.
    """
    from ..data import grid

    g, f = grid(n, n, diagonals="alternate")
    interior = (g[:, 0] > 0) & (g[:, 0] < 1) & (g[:, 1] > 0) & (g[:, 1] < 1)
    g = g.copy()
    g[interior, :2] += rng.uniform(-jitter, jitter, (int(interior.sum()), 2)) / n
    return g, f


def _cylinder(n: int, rng: np.random.Generator, dtype) -> Realisation:
    """A unit square sheet rolled around a cylinder of radius 0.4 (a 2.5 rad arc)."""
    v, f = _parameter_grid(n, rng)
    R = 0.4
    s, y = v[:, 0], v[:, 1]
    rolled = np.stack([R * np.sin(s / R), y, R - R * np.cos(s / R)], axis=1)
    source = MeshState(v, f, dtype=dtype)
    return _identity(source, source.with_(vertices=rolled), "cylinder")


def _cone(n: int, rng: np.random.Generator, dtype) -> Realisation:
    """A flat annular sector (radii 0.5–1.5, angle 2 rad) rolled onto a cone (sin of half-angle 0.51)."""
    g, f = _parameter_grid(n, rng)
    r = 0.5 + g[:, 0]
    phi = 2.0 * g[:, 1]
    flat = np.stack([r * np.cos(phi), r * np.sin(phi), np.zeros_like(r)], axis=1)
    sin_b = 1.6 / np.pi  # any 0 < sin β < 1 gives a cone; the sector then spans 2/sin β < 2π
    cos_b = np.sqrt(1 - sin_b**2)
    psi = phi / sin_b
    cone = np.stack([r * sin_b * np.cos(psi), r * sin_b * np.sin(psi), r * cos_b], axis=1)
    source = MeshState(flat, f, dtype=dtype)
    return _identity(source, source.with_(vertices=cone), "cone")


def _catenoid(n: int, rng: np.random.Generator, dtype) -> Realisation:
    """The helicoid–catenoid family at θ = 0 (helicoid) and θ = π/2 (catenoid), same (u, v) grid."""
    g, f = _parameter_grid(n, rng)
    u = -2.0 + 4.0 * g[:, 0]  # a part of the helicoid that does not wrap around
    w = -0.8 + 1.6 * g[:, 1]

    def member(theta):
        c, s = np.cos(theta), np.sin(theta)
        return np.stack(
            [
                c * np.sinh(w) * np.sin(u / 2) + s * np.cosh(w) * np.cos(u / 2),
                -c * np.sinh(w) * np.cos(u / 2) + s * np.cosh(w) * np.sin(u / 2),
                c * u / 2 + s * w,
            ],
            axis=1,
        )

    source = MeshState(member(0.0), f, dtype=dtype)
    return _identity(source, source.with_(vertices=member(np.pi / 2)), "catenoid")


def _retriangulate(n: int, rng: np.random.Generator, dtype) -> Realisation:
    """The same flat sheet with each cell's diagonal chosen at random: same surface, new mesh."""
    v, f, _, _ = _sheet(n, rng)
    from ..data import grid

    _, f_uniform = grid(n, n, diagonals="uniform")
    cells = n * n
    pick = rng.random(cells) < 0.5
    # per cell: faces (t1, t2) of the alternate pattern vs. those of the uniform pattern
    f_new = f.copy()
    both = np.concatenate([pick, pick])
    f_new[both] = f_uniform[both]
    source = MeshState(v, f, dtype=dtype)
    r = _identity(source, source.with_(faces=f_new), "retriangulate")
    return r


CATALOGUE: dict[str, Transform] = {
    t.name: t
    for t in (
        Transform("rigid", True, _rigid, doc="random rotation in SO(3) + translation"),
        Transform(
            "reflection",
            True,
            lambda s, rng: _rigid(s, rng, proper=False),
            doc="random improper rotation (det −1) + translation; opt-in",
        ),
        Transform("gauge", True, _gauge, doc="random rotation of every vertex's tangent frame"),
        Transform("permute_vertices", True, _permute_vertices, doc="random vertex relabelling"),
        Transform("permute_faces", True, _permute_faces, doc="random face reordering"),
        Transform(
            "rotate_corners", True, _rotate_corners, doc="cyclic shift of each face's corners"
        ),
        Transform(
            "fold",
            True,
            _folds(1, "fold"),
            family=True,
            doc="flat sheet folded along one mesh line",
        ),
        Transform(
            "folds",
            True,
            _folds(3, "folds"),
            family=True,
            doc="flat sheet folded along three mesh lines",
        ),
        Transform("hinge", True, _hinge, family=True, doc="rigid piece turned about a hinge line"),
        Transform(
            "cylinder", False, _cylinder, family=True, doc="flat sheet rolled onto a cylinder"
        ),
        Transform("cone", False, _cone, family=True, doc="flat annular sector rolled onto a cone"),
        Transform("catenoid", False, _catenoid, family=True, doc="helicoid bent into a catenoid"),
        Transform(
            "retriangulate",
            False,
            _retriangulate,
            family=True,
            doc="same flat sheet, new triangulation",
        ),
    )
}

RELABELLINGS = ("permute_vertices", "permute_faces", "rotate_corners")
EXACT_ISOMETRIES = ("fold", "folds", "hinge")
SMOOTH_ISOMETRIES = ("cylinder", "cone", "catenoid")

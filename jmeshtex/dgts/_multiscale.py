"""Multi-scale training meshes for DGTS (Hertz et al. 2020, §3.3, "Multiscale input shapes").

A template (an icosphere, a torus, or any coarse mesh of the reference's topology) is fitted to the
reference mesh level by level: fit (Adam on Chamfer + normals + regularisers), subdivide 1 → 4 at the
edge midpoints, rescale ×2 so the mean edge stays ≈ 1, fit again. Every level therefore shares the
template's connectivity (subdivided), which is what lets the generator's output be compared vertex by
vertex with the level's mesh (the reconstruction loss) and face by face in the discriminator.

Frames: the template is scaled so its mean edge is 1 ("level-0 frame"); level ``l`` lives in the
level-0 frame times ``scale_factor**l``. ``scales[l]`` maps the reference's input coordinates to level
``l``'s frame: ``v_l = (v_input − center) · scales[l]``.
"""

from __future__ import annotations

import functools
import os
import pathlib
from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._config import is_int
from .._errors import ConfigError, InputError, MeshIOError
from .._mesh import Mesh, as_mesh
from .._training import optimizer_update
from .._types import Array, Float, Int, PRNGKey
from ..geometry import mean_edge_length, subdivide_midpoint, unique_edges, validate_mesh
from ..io import atomic_save_npz, load_npz
from ..ops import chamfer_distance, safe_norm, safe_normalize
from ._config import PrepareConfig


class TrainingMeshes(NamedTuple):
    """The multi-scale training meshes of one reference.

    Attributes:
      template: ``[V_0, 3]`` the template before fitting, in the level-0 frame (mean edge 1): the
        generator's input during training.
      vertices: one ``[V_l, 3]`` array per level, the fitted mesh in level ``l``'s frame.
      faces: one ``[F_l, 3]`` int64 array per level (``faces[l + 1]`` subdivides ``faces[l]``).
      edge_vertices: one ``[E_l, 2]`` array per level but the last: the coarse edge whose midpoint
        is fine vertex ``V_l + e`` (:func:`jmeshtex.geometry.subdivide_midpoint`).
      scales: ``[L]`` input-to-level scale factors (see the module docstring).
      center: ``[3]`` the reference's bounding-box centre in input coordinates.
    """

    template: Float[np.ndarray, "V0 3"]
    vertices: tuple[np.ndarray, ...]
    faces: tuple[np.ndarray, ...]
    edge_vertices: tuple[np.ndarray, ...]
    scales: Float[np.ndarray, " L"]
    center: Float[np.ndarray, " 3"]

    @property
    def num_levels(self) -> int:
        """Number of levels L."""
        return len(self.vertices)

    def mesh(self, level: int) -> Mesh:
        """The fitted mesh of ``level`` (negative: from the finest) as a :class:`~jmeshtex.Mesh`, in
        the level's frame."""
        return Mesh(
            np.asarray(self.vertices[level], np.float64), np.asarray(self.faces[level], np.int64)
        )


# ----------------------------------------------------------------------------------------------
# files
# ----------------------------------------------------------------------------------------------


def save_training_meshes(meshes: TrainingMeshes, path: str | os.PathLike) -> pathlib.Path:
    """Write :class:`TrainingMeshes` to one ``.npz`` file, atomically.

    Args:
      meshes: what :func:`training_meshes` built.
      path: the file (``.npz``); its folder is created.

    Returns:
      The path written.

    Example:
      >>> import tempfile, pathlib
      >>> from jmeshtex.data import icosahedron
      >>> tm = training_meshes(icosahedron(), icosahedron(), config=PrepareConfig(levels=2, steps=0),
      ...                      key=jax.random.key(0))
      >>> path = save_training_meshes(tm, pathlib.Path(tempfile.mkdtemp()) / "training.npz")
      >>> [len(f) for f in load_training_meshes(path).faces]
      [20, 80]
    """
    arrays = {"template": meshes.template, "scales": meshes.scales, "center": meshes.center}
    for level, (v, f) in enumerate(zip(meshes.vertices, meshes.faces, strict=True)):
        arrays[f"vertices_{level}"] = v
        arrays[f"faces_{level}"] = f
    for level, e in enumerate(meshes.edge_vertices):
        arrays[f"edges_{level}"] = e
    return atomic_save_npz(path, arrays)


def load_training_meshes(path: str | os.PathLike) -> TrainingMeshes:
    """Read what :func:`save_training_meshes` wrote.

    Raises:
      MeshIOError: no such file, or not a DGTS training-mesh file.
    """
    data = load_npz(path, "training meshes")
    try:
        n = len(data["scales"])
        return TrainingMeshes(
            template=data["template"],
            vertices=tuple(data[f"vertices_{i}"] for i in range(n)),
            faces=tuple(data[f"faces_{i}"] for i in range(n)),
            edge_vertices=tuple(data[f"edges_{i}"] for i in range(n - 1)),
            scales=data["scales"],
            center=data["center"],
        )
    except KeyError as err:
        raise MeshIOError(f"{path} is not a DGTS training-mesh file (missing {err})") from err


# ----------------------------------------------------------------------------------------------
# fitting
# ----------------------------------------------------------------------------------------------


def sample_points(
    vertices: Float[Array, "V 3"], faces: Int[Array, "F 3"], n: int, *, key: PRNGKey
) -> tuple[Float[Array, "n 3"], Float[Array, "n 3"]]:
    """Area-uniform random points on a mesh with their face normals, inside ``jit``.

    Faces are drawn with probability ``A_f / ΣA`` (not differentiated), barycentric coordinates by
    the square-root rule; the points are differentiable in ``vertices``. A pure JAX function of the
    mesh's arrays (``sample_points(*mesh, n, key=key)`` for a :class:`~jmeshtex.Mesh`).

    .. math:: p = (1 - \\sqrt{u})\\, a + \\sqrt{u}(1 - w)\\, b + \\sqrt{u}\\, w\\, c

    Args:
      vertices: ``[V, 3]`` positions (JAX or NumPy).
      faces: ``[F, 3]`` triangles.
      n: number of points (static).
      key: PRNG key of the draw.

    Returns:
      ``(points [n, 3], unit normals [n, 3])``, ``vertices``' dtype.

    Example:
      >>> from jmeshtex.data import single_triangle
      >>> v, f = single_triangle()
      >>> p, nrm = sample_points(jnp.asarray(v), jnp.asarray(f), 5, key=jax.random.key(0))
      >>> p.shape, nrm[0].tolist()
      ((5, 3), [0.0, 0.0, 1.0])
    """
    tri = vertices[faces]
    cross = jnp.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = jax.lax.stop_gradient(safe_norm(cross))
    cdf = jnp.cumsum(area)
    r, u, w = jax.random.uniform(key, (3, n), vertices.dtype)
    # inverse CDF; side="right" never picks a zero-area face
    face = jnp.minimum(
        jnp.searchsorted(cdf, r * cdf[-1], side="right", method="sort"), faces.shape[0] - 1
    )
    s = jnp.sqrt(u)
    bary = jnp.stack([1 - s, s * (1 - w), s * w], axis=1)
    points = jnp.einsum("nk,nkd->nd", bary, tri[face])
    return points, safe_normalize(cross)[face]


class _FitGeometry(NamedTuple):
    faces: Int[Array, "F 3"]
    edges: Int[Array, "E 2"]
    degree: Float[Array, " V"]
    target_vertices: Float[Array, "T 3"]
    target_faces: Int[Array, "G 3"]


def fitting_loss(
    vertices: Float[Array, "V 3"],
    geo: _FitGeometry,
    *,
    key: PRNGKey,
    config: PrepareConfig,
    num_samples: int,
) -> tuple[Float[Array, ""], dict[str, Float[Array, ""]]]:
    """The level-fitting objective of :class:`PrepareConfig` and its terms (see there)."""
    ps, ns, pt, nt = fit_samples(vertices, geo, key, num_samples=num_samples)
    cd = chamfer_distance(
        ps, pt, p_normals=ns, q_normals=nt, squared=config.squared_chamfer, oriented=True
    )
    reg, reg_terms = regularizer_loss(vertices, geo, config=config)
    terms = {
        "s2t": cd.p_to_q,
        "t2s": cd.q_to_p,
        "normal_s2t": cd.normal_p_to_q,
        "normal_t2s": cd.normal_q_to_p,
        **reg_terms,
    }
    return chamfer_objective(terms, config) + reg, terms


def fit_samples(
    vertices: Float[Array, "V 3"], geo: _FitGeometry, key: PRNGKey, *, num_samples: int
):
    """``(points, normals)`` of ``num_samples`` uniform samples on the fitted mesh, then on the
    target (:func:`sample_points`; the two surfaces' keys split from ``key``)."""
    k_s, k_t = jax.random.split(key)
    ps, ns = sample_points(vertices, geo.faces, num_samples, key=k_s)
    pt, nt = sample_points(geo.target_vertices, geo.target_faces, num_samples, key=k_t)
    return ps, ns, pt, nt


def chamfer_objective(
    terms: dict[str, Float[Array, ""]], config: PrepareConfig
) -> Float[Array, ""]:
    """The weighted Chamfer and normal terms of the fitting objective (:class:`PrepareConfig`'s
    ``weight_s2t``, ``weight_t2s``, ``weight_normal_s2t``, ``weight_normal_t2s``)."""
    c = config
    return (
        c.weight_s2t * terms["s2t"]
        + c.weight_t2s * terms["t2s"]
        + c.weight_normal_s2t * terms["normal_s2t"]
        + c.weight_normal_t2s * terms["normal_t2s"]
    )


def regularizer_loss(
    vertices: Float[Array, "V 3"], geo: _FitGeometry, *, config: PrepareConfig
) -> tuple[Float[Array, ""], dict[str, Float[Array, ""]]]:
    """The triangulation regularisers of :class:`PrepareConfig` (edge spread, edge entropy, Laplacian)."""
    e = vertices[geo.edges[:, 1]] - vertices[geo.edges[:, 0]]
    length = safe_norm(e)
    edge_std = jnp.sqrt(jnp.mean((length - jnp.mean(length)) ** 2) + 1e-12)
    tri = vertices[geo.faces]
    fl = safe_norm(jnp.roll(tri, -1, axis=1) - tri)  # [F, 3]
    fl = fl / jnp.maximum(jnp.sum(fl, axis=1, keepdims=True), 1e-12)
    edge_local = jnp.mean(jnp.sum(fl * jnp.log(jnp.maximum(fl, 1e-12)), axis=1))
    V = vertices.shape[0]
    nbr = jax.ops.segment_sum(vertices[geo.edges[:, 1]], geo.edges[:, 0], V) + jax.ops.segment_sum(
        vertices[geo.edges[:, 0]], geo.edges[:, 1], V
    )
    lap = jnp.mean(jnp.sum(jnp.abs(vertices - nbr / jnp.maximum(geo.degree, 1)[:, None]), axis=1))
    c = config
    loss = (
        c.weight_edge_std * edge_std + c.weight_edge_local * edge_local + c.weight_laplacian * lap
    )
    return loss, {"edge_std": edge_std, "edge_local": edge_local, "laplacian": lap}


_CHUNK = 50


@functools.partial(jax.jit, static_argnames=("config", "num_samples"))
def _fit_chunk(v, state, key, geo, n, *, config: PrepareConfig, num_samples: int):
    """Up to ``_CHUNK`` Adam steps (``n`` of them) of :func:`fitting_loss` in one compiled call;
    ``state``: ``optax.adam(config.learning_rate)``'s. Returns ``(v, state, the last terms)``."""
    opt = optax.adam(config.learning_rate)

    def body(i, carry):
        v, state, _ = carry
        (_, terms), g = jax.value_and_grad(
            lambda x: fitting_loss(
                x, geo, key=jax.random.fold_in(key, i), config=config, num_samples=num_samples
            ),
            has_aux=True,
        )(v)
        v, state = optimizer_update(opt, g, state, v)
        return v, state, terms

    terms0 = jax.eval_shape(
        lambda x: fitting_loss(x, geo, key=key, config=config, num_samples=num_samples)[1], v
    )
    zeros = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), terms0)
    return jax.lax.fori_loop(0, n, body, (v, state, zeros))


def fit_level(
    mesh: Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]],
    target: Mesh | tuple[Float[np.ndarray, "T 3"], Int[np.ndarray, "G 3"]],
    *,
    config: PrepareConfig,
    num_samples: int,
    key: PRNGKey,
    progress: Callable[[int], None] | None = None,
) -> tuple[Float[np.ndarray, "V 3"], dict[str, float]]:
    """Fit one level's mesh to the reference with Adam (``config.steps`` jit-compiled steps, float32).

    Args:
      mesh: the level's initial mesh (level frame): :class:`~jmeshtex.Mesh` or ``(vertices [V, 3],
        faces [F, 3])``; only the positions move.
      target: the reference in the same frame (Mesh or pair).
      config: weights, learning rate and number of steps.
      num_samples: surface samples drawn on each mesh per step.
      key: PRNG key of the sampling.
      progress: called with the number of steps done after each chunk of steps.

    Returns:
      ``(vertices [V, 3] float64, final loss terms)``.

    Example:
      >>> from jmeshtex.data import icosahedron, icosphere
      >>> v, terms = fit_level(icosahedron(), icosphere(2), config=PrepareConfig(steps=10), num_samples=100,
      ...                      key=jax.random.key(0))
      >>> v.shape, sorted(terms)[:2]
      ((12, 3), ['edge_local', 'edge_std'])
    """
    vertices, faces = as_mesh(mesh, what="fit_level: mesh")
    target_vertices, target_faces = as_mesh(target, what="fit_level: target")
    edges = unique_edges(faces, len(vertices))
    degree = np.bincount(edges.ravel(), minlength=len(vertices)).astype(np.float32)
    geo = _FitGeometry(
        jnp.asarray(faces, jnp.int32),
        jnp.asarray(edges, jnp.int32),
        jnp.asarray(degree),
        jnp.asarray(target_vertices, jnp.float32),
        jnp.asarray(target_faces, jnp.int32),
    )
    if config.schedule == "official":
        from ._official_fit import fit_official

        v, terms = fit_official(
            jnp.asarray(vertices, jnp.float32),
            geo,
            config=config,
            num_samples=int(num_samples),
            key=key,
            progress=progress,
        )
        return np.asarray(v, np.float64), terms
    chunk = _CHUNK
    v = jnp.asarray(vertices, jnp.float32)
    state = optax.adam(config.learning_rate).init(v)
    terms: dict = {}
    done = 0
    n_chunks = -(-int(config.steps) // chunk)
    for c in range(n_chunks):
        n = min(chunk, int(config.steps) - done)
        v, state, terms = _fit_chunk(
            v,
            state,
            jax.random.fold_in(key, c),
            geo,
            jnp.int32(n),
            config=config,
            num_samples=int(num_samples),
        )
        done += n
        if progress is not None:
            progress(done)
    return np.asarray(v, np.float64), {k: float(x) for k, x in terms.items()}


def normalize_pair(
    reference_vertices: Float[np.ndarray, "R 3"],
    template_vertices: Float[np.ndarray, "V 3"],
    template_faces: Int[np.ndarray, "F 3"],
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Put the reference and the template in the level-0 frame (as the reference code does).

    Each is centred on its bounding box and scaled to a unit longest side; then both are scaled by
    ``s`` so the template's mean edge is 1.

    Returns:
      ``(reference [R, 3], template [V, 3], scale, center)`` with
      ``reference_out = (reference_in − center) · scale``.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> v, f = icosphere(1)
      >>> r, t, s, c = normalize_pair(2 * v + 1, v, f)
      >>> round(mean_edge_length(t, f), 9), bool(np.allclose(r, t))
      (1.0, True)
    """

    def unit(v):
        lo, hi = v.min(0), v.max(0)
        extent = float((hi - lo).max())
        if not extent > 0:
            raise InputError("cannot normalise a mesh whose vertices all coincide")
        return (lo + hi) / 2, extent

    rc, rext = unit(reference_vertices)
    tc, text = unit(template_vertices)
    t = (template_vertices - tc) / text
    s = 1.0 / mean_edge_length(t, template_faces)
    return (reference_vertices - rc) * (s / rext), t * s, s / rext, rc


def training_meshes(
    reference: Mesh | tuple[Float[np.ndarray, "R 3"], Int[np.ndarray, "G 3"]],
    template: Mesh | tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]],
    *,
    key: PRNGKey,
    config: PrepareConfig | None = None,
    progress: bool | Callable[[str, int, int], None] = True,
    coarse_reference: Mesh | tuple[Float[np.ndarray, "C 3"], Int[np.ndarray, "H 3"]] | None = None,
    coarse_levels: int = 0,
    rotation: Float[np.ndarray, "3 3"] | None = None,
    checkpoint_dir: str | os.PathLike | None = None,
) -> TrainingMeshes:
    """Build the multi-scale training meshes of a reference from a template (DGTS §3.3).

    For level ``l = 0 … L−1``: (``l > 0``) subdivide the previous level 1 → 4 at edge midpoints and
    scale it and the reference by ``scale_factor``; fit on ``samples_per_level·(l + 1)`` samples.

    Args:
      reference: the textured reference (open or closed, any genus): a :class:`~jmeshtex.Mesh` or
        a ``(vertices [R, 3], faces [G, 3])`` pair.
      template: a coarse mesh of the same topology (icosphere, torus, ...), Mesh or pair.
      key: PRNG key of the surface sampling.
      config: :class:`PrepareConfig` (default: its defaults).
      progress: True: a tqdm bar per level; False: none; a callable: called as
        ``progress(stage, done, total)`` instead (``stage`` is ``"level l"``).
      coarse_reference: optional surface that levels ``0 … coarse_levels − 1`` are fitted to
        instead of ``reference`` (beyond the paper: e.g. the reference without its texture, so the
        coarse levels carry the shape and no aliased trace of the texture, and the first level fitted
        to ``reference`` must lay the texture out from noise). It is placed by ``reference``'s
        normalisation, so it must share its coordinates.
      coarse_levels: how many levels (from the coarsest) fit ``coarse_reference``; 0: none.
      rotation: optional ``[3, 3]`` rotation of the normalised template before the first fit: the
        reference remeshed with its texture elsewhere on the template's triangles (several such
        remeshes train one model, beyond the paper). None: the template as given.
      checkpoint_dir: optional folder that keeps the levels fitted so far (``levels.npz``, written
        atomically after each level): a call with the same inputs resumes after the last finished
        level and returns what an uninterrupted call returns. A file written for other inputs
        (reference, template, config, key, coarse reference, rotation) raises instead of being
        overwritten.

    Returns:
      :class:`TrainingMeshes`.

    Raises:
      InputError: ``reference`` or ``template`` is not a mesh.
      MeshError: (a subclass) an invalid reference or template (:func:`jmeshtex.geometry.validate_mesh`).
      ConfigError: ``coarse_levels`` outside ``[0, config.levels)``, or > 0 without a
        ``coarse_reference``; ``rotation`` not a ``[3, 3]`` rotation matrix; ``checkpoint_dir``
        holds the levels of other inputs.

    Example:
      >>> from jmeshtex.data import icosphere, icosahedron
      >>> tm = training_meshes(icosphere(2), icosahedron(), config=PrepareConfig(levels=2, steps=50,
      ...     samples_per_level=200), key=jax.random.key(0), progress=False)
      >>> [f.shape[0] for f in tm.faces], round(float(tm.scales[1] / tm.scales[0]), 6)
      ([20, 80], 2.0)
    """
    config = PrepareConfig() if config is None else config
    rv, rf = as_mesh(reference, what="training_meshes: reference")
    tv, tf = as_mesh(template, what="training_meshes: template")
    validate_mesh(rv, rf)
    validate_mesh(tv, tf)
    if not (is_int(coarse_levels) and 0 <= coarse_levels < config.levels):
        raise ConfigError(
            f"training_meshes: coarse_levels must be an int in [0, {config.levels}) (the finest "
            f"level always fits the reference), got {coarse_levels!r}"
        )
    if coarse_levels and coarse_reference is None:
        raise ConfigError(
            f"training_meshes: coarse_levels={coarse_levels} needs a coarse_reference to fit"
        )
    rv = np.asarray(rv, np.float64)
    f = np.asarray(tf, np.int64)
    target, v, scale, center = normalize_pair(rv, np.asarray(tv, np.float64), f)
    if rotation is not None:
        v = v @ _rotation_matrix(rotation).T
    coarse = None
    if coarse_levels:
        cv, cf = as_mesh(coarse_reference, what="training_meshes: coarse_reference")
        validate_mesh(cv, cf)
        coarse = ((np.asarray(cv, np.float64) - center) * scale, np.asarray(cf, np.int64))
    report = _progress_bars("prepare") if progress is True else (progress or None)
    surfaces = (coarse, (target, np.asarray(rf, np.int64)))
    resume = None
    if checkpoint_dir is not None:
        inputs = (v, f, *surfaces[1], *(coarse or ()), np.int64(coarse_levels))
        path = pathlib.Path(checkpoint_dir) / LEVELS_FILE
        resume = _LevelCheckpoint(path, _fit_fingerprint(inputs, config, key))
    levels = _fit_levels(
        v, f, surfaces, coarse_levels, scale, config=config, key=key, report=report, resume=resume
    )
    return TrainingMeshes(v.copy(), *levels, center)


def _fit_fingerprint(arrays, config: PrepareConfig, key) -> str:
    """A digest of what a level fit depends on: the normalised meshes, the config and the key."""
    import hashlib
    import json

    h = hashlib.sha256(json.dumps(config.to_dict(), sort_keys=True, default=str).encode())
    for a in (*arrays, jax.random.key_data(key)):
        a = np.ascontiguousarray(np.asarray(a))
        h.update(f"{a.dtype}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


#: the file in ``training_meshes(checkpoint_dir=)`` that keeps the finished levels
LEVELS_FILE = "levels.npz"


class _LevelCheckpoint:
    """The fitted vertices of the finished levels in one ``.npz`` (``training_meshes(checkpoint_dir=)``)."""

    def __init__(self, path: str | os.PathLike, fingerprint: str):
        self.path, self.fingerprint = pathlib.Path(path), fingerprint
        self.levels: list[np.ndarray] = []
        if self.path.is_file():
            data = load_npz(self.path, "training_meshes checkpoint")
            found = str(data.get("fingerprint", ""))
            if found != fingerprint:
                raise ConfigError(
                    f"training_meshes: checkpoint {self.path} holds the levels of other inputs "
                    f"(reference, template, config or key differ); pass another checkpoint_dir "
                    f"or delete that file to start afresh"
                )
            self.levels = [data[f"vertices_{i}"] for i in range(int(data["num_levels"]))]

    def add(self, vertices: np.ndarray) -> None:
        self.levels.append(np.asarray(vertices, np.float64))
        arrays = {f"vertices_{i}": v for i, v in enumerate(self.levels)}
        arrays.update(
            fingerprint=np.asarray(self.fingerprint), num_levels=np.int64(len(self.levels))
        )
        atomic_save_npz(self.path, arrays)


def _fit_levels(
    v, f, surfaces, coarse_levels: int, scale: float, *, config, key, report, resume=None
):
    """Subdivide, rescale and fit level after level (:func:`training_meshes`); ``surfaces``: the
    coarse reference (or None) and the reference, normalised; ``resume``: a
    :class:`_LevelCheckpoint` whose finished levels are taken instead of fitted again. Returns
    ``(vertices, faces, edge_vertices, scales)`` of the levels."""
    coarse, (target, rf) = surfaces
    verts, faces, edges, scales = [], [], [], []
    for level in range(config.levels):
        if level > 0:
            sub = subdivide_midpoint(v, f)
            v, f = sub.vertices * config.scale_factor, sub.faces
            edges.append(sub.edge_vertices)
            target = target * config.scale_factor
            if coarse is not None:
                coarse = (coarse[0] * config.scale_factor, coarse[1])
            scale *= config.scale_factor
        stage = f"level {level}"
        cb = None if report is None else (lambda d, s=stage: report(s, d, config.steps))
        if resume is not None and level < len(resume.levels):
            v = resume.levels[level]
        else:
            v, _ = fit_level(
                (v, f),
                coarse if level < coarse_levels else (target, rf),
                config=config,
                num_samples=config.samples_per_level * (level + 1),
                key=jax.random.fold_in(key, level),
                progress=cb,
            )
            if resume is not None:
                resume.add(v)
        verts.append(v)
        faces.append(f)
        scales.append(scale)
    return tuple(verts), tuple(faces), tuple(edges), np.asarray(scales)


def _rotation_matrix(rotation) -> np.ndarray:
    """``rotation`` as a float64 ``[3, 3]`` proper rotation, or a :class:`ConfigError` naming the fault."""
    r = np.asarray(rotation, np.float64)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise ConfigError(
            f"training_meshes: rotation must be a finite [3, 3] matrix, got shape {r.shape}"
        )
    if not (np.allclose(r @ r.T, np.eye(3), atol=1e-6) and np.linalg.det(r) > 0):
        raise ConfigError(
            "training_meshes: rotation must be a proper rotation (R R^T = I, det R = 1); "
            "e.g. scipy.spatial.transform.Rotation.random().as_matrix()"
        )
    return r


def _progress_bars(what: str) -> Callable[[str, int, int], None]:
    """A ``progress(stage, done, total)`` callback drawing one tqdm bar per stage."""
    from tqdm.auto import tqdm

    bars: dict = {}

    def progress(stage: str, done: int, total: int) -> None:
        bar = bars.get(stage)
        if bar is None:
            bar = bars[stage] = tqdm(total=total, desc=f"{what} {stage}", unit="step")
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return progress

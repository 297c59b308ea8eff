"""The renderer: host visibility (:func:`rasterize`) + pure-JAX shading (:func:`shade`) → uint8 images.

Colour sources (at most one): per-vertex colours (interpolated), per-face colours, scalars through a
matplotlib colormap, or a UV texture (trilinear, mip-mapped per face). A :class:`~jmeshtex.Mesh`
that carries its own UV texture or vertex colours shows them when no source is given; a mesh
without any renders shaded grey.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._triangles import face_normals
from .._types import ArrayLike, Float, Int, Num
from ..geometry import check_mesh_arrays, vertex_normals
from ._camera import Camera, view_camera
from ._shade import camera_lighting, shade
from ._visibility import Visibility, project, rasterize

_log = logging.getLogger("jmeshtex.render")

#: the default view ``(elevation, azimuth)`` in degrees: a 3/4 view from above (matplotlib's default)
DEFAULT_VIEW = (25.0, -60.0)
_SHADINGS = ("smooth", "flat", "unlit")
_BACKGROUNDS = ("white", "transparent")


def check_vertices_faces(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """float64 ``[V, 3]`` / int64 ``[F, 3]`` copies; NaN or infinite vertices raise :class:`InputError`."""
    v = np.asarray(vertices)
    if (
        v.ndim == 2
        and v.shape[1] == 3
        and np.issubdtype(v.dtype, np.number)
        and not np.isfinite(v).all()
    ):
        bad = np.nonzero(~np.isfinite(v).all(axis=1))[0]
        shown = ", ".join(str(int(i)) for i in bad[:10]) + (", ..." if len(bad) > 10 else "")
        raise InputError(
            f"NaN or infinite vertices cannot be rendered: {len(bad)} vertices ({shown})"
        )
    return check_mesh_arrays(vertices, faces)


def texture_lod(
    vertices: Float[np.ndarray, "V 3"],
    faces: Int[np.ndarray, "F 3"],
    uv: Float[np.ndarray, "F 3 2"],
    texture_shape: tuple[int, int],
    camera: Camera,
    *,
    supersample: int = 1,
) -> Float[np.ndarray, " F"]:
    """Mip level per face seen by ``camera``: ``½ log2(texel area / sample area)`` (0 = full resolution).

    The ratio of the face's area in texels (its UV triangle scaled by the texture's ``(height,
    width)``) to its area in screen samples (at ``supersample`` samples per pixel side), i.e.
    texels per sample squared; a face seen edge-on counts as half a sample. Input of
    :func:`shade`'s ``lod``.

    Example:
      >>> import numpy as np
      >>> from jmeshtex.render import look_at
      >>> v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
      >>> cam = look_at((0.5, 0.5, 2), (0.5, 0.5, 0), up="y", half_height=0.5, size=(64, 64))
      >>> texture_lod(v, np.array([[0, 1, 2]]), v[None, :, :2], (256, 256), cam)  # 4 texels a pixel
      array([2.])
    """
    h, w = texture_shape
    s = int(supersample)
    screen, _ = project(
        np.asarray(vertices, np.float64), camera, camera.width * s, camera.height * s
    )
    t = np.asarray(uv, np.float64) * np.array([w, h])
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    tex_area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    p = np.nan_to_num(screen[faces])
    s1, s2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    scr_area = 0.5 * np.abs(s1[:, 0] * s2[:, 1] - s1[:, 1] * s2[:, 0])
    ratio = np.maximum(tex_area, 1e-12) / np.maximum(scr_area, 0.5)
    return np.maximum(0.5 * np.log2(ratio), 0.0)


def colors01(values, rows: int, name: str) -> np.ndarray:
    """``[rows, 3|4]`` colours (uint8 or float) to float64 RGB in [0, 1]."""
    c = np.asarray(values)
    if (
        c.ndim != 2
        or c.shape[0] != rows
        or c.shape[1] not in (3, 4)
        or not np.issubdtype(c.dtype, np.number)
    ):
        raise InputError(
            f"{name} must be numeric [{rows}, 3] or [{rows}, 4] colours, got shape {c.shape}"
        )
    if np.issubdtype(c.dtype, np.integer):
        return c[:, :3] / 255.0
    if not np.isfinite(c).all():
        raise InputError(f"{name} holds NaN or infinite values")
    return np.clip(c[:, :3].astype(np.float64), 0.0, 1.0)


def image01(image, name: str) -> np.ndarray:
    """An image ``[H, W]`` / ``[H, W, 3|4]`` (uint8 or float in [0, 1]) as float64 ``[H, W, 3|4]``
    in [0, 1] (alpha kept); a typed error for any other shape, dtype or non-finite value.

    Example:
      >>> image01(np.array([[0, 255]], np.uint8), "image").shape
      (1, 2, 3)
    """
    img = np.asarray(image)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    if (
        img.ndim != 3
        or img.shape[2] not in (3, 4)
        or min(img.shape[:2]) < 1
        or not np.issubdtype(img.dtype, np.number)
    ):
        raise InputError(
            f"{name} must be an image [H, W], [H, W, 3] or [H, W, 4], got shape {img.shape}"
        )
    if img.dtype == np.uint8:
        return img.astype(np.float64) / 255.0
    if np.issubdtype(img.dtype, np.integer):
        raise InputError(f"{name}: integer images must be uint8, got {img.dtype}")
    if not np.isfinite(img).all():
        raise InputError(f"{name} holds NaN or infinite values")
    return np.clip(img.astype(np.float64), 0.0, 1.0)


def texture01(texture, name: str = "texture") -> np.ndarray:
    """An image ``[H, W]`` / ``[H, W, 3|4]`` (uint8 or float in [0, 1]) as float32 RGB ``[H, W, 3]``
    (alpha ignored)."""
    return image01(texture, name)[..., :3].astype(np.float32)


def scalar_colors(scalars, n_v: int, n_f: int, cmap: str, clim) -> tuple[np.ndarray, bool]:
    """Colours ``[V or F, 3]`` of scalars through a colormap, and whether they are per vertex."""
    import matplotlib

    s = np.asarray(scalars)
    if (
        s.ndim != 1
        or len(s) not in (n_v, n_f)
        or not np.issubdtype(s.dtype, np.number)
        or np.iscomplexobj(s)
    ):
        raise InputError(
            f"scalars must be real [V={n_v}] or [F={n_f}] values, got shape {s.shape} ({s.dtype})"
        )
    s = s.astype(np.float64)
    if not np.isfinite(s).all():
        raise InputError("scalars hold NaN or infinite values")
    vmin, vmax = (
        (float(s.min()), float(s.max())) if clim is None else (float(clim[0]), float(clim[1]))
    )
    if not vmax > vmin:
        vmax = vmin + 1.0  # constant field: one colour
    try:
        colormap = matplotlib.colormaps[cmap]
    except KeyError as err:
        raise InputError(
            f"unknown colormap {cmap!r}: use a matplotlib name such as 'viridis'"
        ) from err
    return colormap(np.clip((s - vmin) / (vmax - vmin), 0.0, 1.0))[:, :3], len(s) == n_v


class _Scene:
    """What every view of one mesh shares: geometry, per-corner normals and the albedo source."""

    def __init__(self, mesh, *, face_colors, scalars, cmap, clim, shading):
        m = as_mesh(mesh)
        v, f = check_vertices_faces(*m)
        self.vertices, self.faces = v, f
        if shading not in _SHADINGS:
            raise InputError(f"shading must be one of {', '.join(_SHADINGS)}, got {shading!r}")
        self.lit = shading != "unlit"
        if face_colors is not None and scalars is not None:
            raise InputError("give at most one of face_colors and scalars")
        vertex_colors = uv = texture = None
        if face_colors is None and scalars is None:  # the mesh's own appearance
            if m.uv is not None or m.texture is not None:
                uv, texture = m.uv, m.texture
            elif m.vertex_colors is not None:
                vertex_colors = m.vertex_colors
        n_v, n_f = len(v), len(f)
        self.corner_colors = self.uv = self.texture = None
        if vertex_colors is not None:
            self.corner_colors = colors01(vertex_colors, n_v, "vertex_colors")[f]
        elif face_colors is not None:
            self.corner_colors = np.repeat(
                colors01(face_colors, n_f, "face_colors")[:, None], 3, axis=1
            )
        elif scalars is not None:
            c, per_vertex = scalar_colors(scalars, n_v, n_f, cmap, clim)
            self.corner_colors = c[f] if per_vertex else np.repeat(c[:, None], 3, axis=1)
        elif uv is not None or texture is not None:
            if uv is None or texture is None:
                raise InputError("a Mesh shows a texture only with both uv and texture")
            self.texture = texture01(texture)
            uv = np.asarray(uv)
            if uv.ndim == 2 and uv.shape == (n_v, 2):
                uv = uv[f]
            if uv.ndim != 3 or uv.shape != (n_f, 3, 2) or not np.issubdtype(uv.dtype, np.number):
                raise InputError(
                    f"uv must be per-corner [F={n_f}, 3, 2] or per-vertex [V={n_v}, 2], got {uv.shape}"
                )
            if not np.isfinite(uv).all():
                raise InputError("uv holds NaN or infinite values")
            self.uv = uv.astype(np.float64)
        else:
            _log.info("the mesh has no colours or texture: rendering it shaded grey")
        fn = face_normals(v, f)
        if shading == "flat":
            self.normals = np.repeat(fn[:, None], 3, axis=1)
        else:
            vn = vertex_normals(v, f)[f]
            # corners of vertices in no proper face (zero normal) fall back to the face normal
            bad = np.linalg.norm(vn, axis=2) < 0.5
            vn[bad] = np.broadcast_to(fn[:, None], vn.shape)[bad]
            self.normals = vn
        dt = np.float32
        self._normals = jnp.asarray(self.normals, dt)
        self._colors = None if self.corner_colors is None else jnp.asarray(self.corner_colors, dt)
        self._uv = None if self.uv is None else jnp.asarray(self.uv, dt)
        self._texture = None if self.texture is None else jnp.asarray(self.texture, dt)

    def visibility(self, camera: Camera, supersample: int) -> Visibility:
        return rasterize(self.vertices, self.faces, camera, supersample=supersample)

    def shade(self, vis: Visibility, background: str) -> np.ndarray:
        """Float ``[H, W, 3|4]`` image of a visibility buffer."""
        cam, s = vis.camera, vis.supersample
        lod = None
        if self._texture is not None:
            lod = jnp.asarray(
                texture_lod(
                    self.vertices, self.faces, self.uv, self.texture.shape[:2], cam, supersample=s
                ),
                jnp.float32,
            )
        lighting = camera_lighting(cam)
        lighting = type(lighting)(*(jnp.asarray(x, jnp.float32) for x in lighting))
        img = shade(
            jnp.asarray(vis.face),
            jnp.asarray(vis.bary, jnp.float32),
            self._normals,
            lighting,
            corner_colors=self._colors,
            uv=self._uv,
            texture=self._texture,
            lod=lod,
            lit=self.lit,
            supersample=s,
            background=background,
        )
        return np.asarray(img)


def to_uint8(image: np.ndarray) -> np.ndarray:
    return np.round(np.clip(image, 0.0, 1.0) * 255.0).astype(np.uint8)


def _check_options(background, supersample) -> int:
    if background not in _BACKGROUNDS:
        raise InputError(f"background must be one of {', '.join(_BACKGROUNDS)}, got {background!r}")
    try:
        s = int(supersample)
    except (TypeError, ValueError) as err:
        raise InputError(f"supersample must be an integer >= 1, got {supersample!r}") from err
    if s < 1 or s != supersample:
        raise InputError(f"supersample must be an integer >= 1, got {supersample!r}")
    return s


def render(
    mesh: Mesh | tuple,
    camera: Camera | None = None,
    *,
    face_colors: Num[ArrayLike, "F C"] | None = None,
    scalars: Float[ArrayLike, " V_or_F"] | None = None,
    cmap: str = "viridis",
    clim: tuple[float, float] | None = None,
    shading: str = "smooth",
    up: str | Sequence[float] = "z",
    size: tuple[int, int] = (512, 512),
    background: str = "white",
    supersample: int = 2,
) -> np.ndarray:
    """Render a triangle mesh to an image: host visibility, then shading in JAX.

    Visibility (:func:`rasterize`) finds the face and perspective-correct barycentrics every one
    of ``supersample²`` samples per pixel sees; :func:`shade` interpolates the albedo (corner
    colours, or a trilinear mip-mapped texture lookup), lights it with a directional light above
    left of the camera (Lambert + Blinn-Phong, two-sided)

    .. math:: c = a\\,(0.3 + 0.7 \\max(0, n\\cdot\\ell)) + 0.12 \\max(0, n\\cdot h)^{32}

    with ``n`` the interpolated vertex normal (``"smooth"``) or the face normal (``"flat"``), and
    averages the samples of each pixel (antialiasing).

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])``; world frame. A
        ``Mesh`` is shown in its own colours: its UV texture (``uv`` ``[F, 3, 2]`` per corner or
        ``[V, 2]`` per vertex, ``texture`` ``[H, W]`` or ``[H, W, 3|4]``, float in [0, 1] or
        uint8), else its ``vertex_colors`` ``[V, 3|4]`` (float in [0, 1], clipped, or uint8; alpha
        ignored), else grey. To show other colours, render ``mesh.replace(vertex_colors=c)``.
      camera: a :class:`Camera`; None: the default 3/4 view (elevation 25°, azimuth -60° about
        ``up``) framed on the bounding sphere. A camera brings its own size and up.
      face_colors: ``[F, 3|4]`` colours, one per face, instead of the mesh's own.
      scalars: ``[V]`` per-vertex or ``[F]`` per-face values mapped through ``cmap`` (per-vertex
        when ``V == F``; vertex colours are interpolated), instead of the mesh's own colours.
      cmap: a matplotlib colormap name.
      clim: ``(vmin, vmax)`` for ``scalars``; default their min and max.
      shading: ``"smooth"`` (interpolated normals), ``"flat"`` (face normals) or ``"unlit"`` (the
        albedo as it is).
      up: the world up axis of the default camera: ``"x"|"y"|"z"|"-x"|"-y"|"-z"`` or a 3-vector
        (``"y"`` for most OBJ files).
      size: ``(width, height)`` in pixels of the default camera.
      background: ``"white"`` (RGB) or ``"transparent"`` (RGBA, coverage alpha).
      supersample: samples per pixel side (antialiasing; 1 = none).

    Returns:
      ``[height, width, 3]`` uint8 RGB image (``[height, width, 4]`` RGBA when transparent).

    Raises:
      InputError: wrong shapes, NaN vertices, both ``face_colors`` and ``scalars``, unknown
        colormap, shading or background, a zero-size image, a camera that sees nothing.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> v, f = icosphere(2)
      >>> img = render((v, f), scalars=v[:, 2], size=(64, 48))
      >>> img.shape, img.dtype, bool(img[0, 0].min() == 255)  # white corner
      ((48, 64, 3), dtype('uint8'), True)
    """
    s = _check_options(background, supersample)
    scene = _Scene(
        mesh, face_colors=face_colors, scalars=scalars, cmap=cmap, clim=clim, shading=shading
    )
    cam = (
        camera
        if camera is not None
        else view_camera(scene.vertices, *DEFAULT_VIEW, up=up, size=size)
    )
    if not isinstance(cam, Camera):
        raise InputError(
            f"camera must be a Camera (see look_at, orbit_cameras), got {type(cam).__name__}"
        )
    return to_uint8(scene.shade(scene.visibility(cam, s), background))


def render_views(
    mesh: Mesh | tuple,
    cameras: Sequence[Camera],
    **options,
) -> np.ndarray:
    """Render one mesh from several cameras (same options as :func:`render`; one compilation).

    Args:
      mesh: as :func:`render`.
      cameras: ``N`` cameras of the same size, e.g. :func:`orbit_cameras`.
      **options: the keyword options of :func:`render` (``size`` and ``up`` are the cameras').

    Returns:
      ``[N, height, width, 3]`` uint8 (``4`` channels when ``background="transparent"``).

    Example:
      >>> from jmeshtex.data import torus
      >>> from jmeshtex.render import orbit_cameras
      >>> mesh = torus(16, 8)
      >>> render_views(mesh, orbit_cameras(mesh, azimuths=3, elevations=(30.0,), size=(32, 32))).shape
      (3, 32, 32, 3)
    """
    unknown = set(options) - {
        "face_colors",
        "scalars",
        "cmap",
        "clim",
        "shading",
        "background",
        "supersample",
        "up",
        "size",
    }
    if unknown:
        raise InputError(f"render_views: unknown options {sorted(unknown)}")
    cams = list(cameras)
    if not cams or not all(isinstance(c, Camera) for c in cams):
        raise InputError(
            "render_views needs a non-empty list of Camera objects (see orbit_cameras)"
        )
    if len({c.size for c in cams}) != 1:
        raise InputError(
            f"render_views: cameras must share one size, got {sorted({c.size for c in cams})}"
        )
    background = options.pop("background", "white")
    s = _check_options(background, options.pop("supersample", 2))
    options.pop("up", None)
    options.pop("size", None)
    scene = _Scene(
        mesh,
        shading=options.pop("shading", "smooth"),
        cmap=options.pop("cmap", "viridis"),
        **{k: options.pop(k, None) for k in ("face_colors", "scalars", "clim")},
    )
    return np.stack([to_uint8(scene.shade(scene.visibility(c, s), background)) for c in cams])

"""Look-at cameras (orthographic and perspective) and the standard orbit rig.

Frames: a camera looks from ``eye`` at ``target``. Its forward axis is
``w = (target - eye) / |target - eye|``, its right axis ``r = w × up / |w × up|`` and its image-up
axis ``u = r × w``. A world point ``p`` has view coordinates ``(x, y, z) = ((p - eye)·r,
(p - eye)·u, (p - eye)·w)``: ``z`` is the depth along the viewing direction. Orthographic cameras map
``(x, y)`` to the image plane directly, the image spanning ``[-half_height, half_height]``
vertically; perspective cameras map ``(x / z, y / z)`` with ``tan(fov_deg / 2)`` as the half height.
Image row 0 is the top of the picture (``y`` largest), column 0 its left edge (``x`` smallest).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from .._config import is_int
from .._errors import InputError
from .._mesh import as_mesh
from ..geometry import up_vector


@dataclasses.dataclass(frozen=True, eq=False)
class Camera:
    """A look-at camera (frozen record; build it with :func:`look_at` or :func:`orbit_cameras`).

    Attributes:
      eye: ``[3]`` float64 camera position (world frame).
      target: ``[3]`` float64 point the camera looks at (lands on the image centre).
      up: ``[3]`` float64 unit world direction that points up in the image.
      fov_deg: vertical field of view in degrees (perspective), or None (orthographic).
      half_height: orthographic half height of the view in world units (the image spans
        ``[-half_height, half_height]`` vertically and ``half_height · width / height`` sideways);
        for perspective cameras the half height at the target's distance.
      size: ``(width, height)`` of the image in pixels.

    Example:
      >>> cam = look_at((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), up="y", half_height=1.5, size=(64, 48))
      >>> cam.size, cam.orthographic
      ((64, 48), True)
      >>> cam.frame()[2]  # forward axis: down -z
      array([ 0.,  0., -1.])
    """

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray
    fov_deg: float | None
    half_height: float
    size: tuple[int, int]

    @property
    def orthographic(self) -> bool:
        return self.fov_deg is None

    @property
    def width(self) -> int:
        return int(self.size[0])

    @property
    def height(self) -> int:
        return int(self.size[1])

    def frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The camera's right, image-up and forward unit axes ``(r, u, w)`` in the world frame."""
        w = self.target - self.eye
        w = w / np.linalg.norm(w)
        r = np.cross(w, self.up)
        r = r / np.linalg.norm(r)
        return r, np.cross(r, w), w

    def replace(self, **changes) -> Camera:
        """A copy with some fields replaced (checked again, like :func:`look_at`)."""
        fields = {
            k: getattr(self, k) for k in ("eye", "target", "up", "fov_deg", "half_height", "size")
        }
        fields.update(changes)
        return look_at(fields.pop("eye"), fields.pop("target"), **fields)


def ground_frame(up: str | Sequence[float] | np.ndarray) -> np.ndarray:
    """``[3, 3]`` rows ``(a, b, up)``: a right-handed world frame whose third axis is ``up``.

    Azimuth 0 looks from ``+a``, azimuth 90° from ``+b``. For ``up="z"`` it is ``(x, y, z)``
    (matplotlib's ``view_init`` convention), for ``up="y"`` ``(z, x, y)``: azimuth 0 then looks at a
    Y-up model from the front (``+z``), as OBJ files are usually authored.
    """
    u = up_vector(up)
    if isinstance(up, str):
        i = int(np.argmax(np.abs(u)))  # the named axis (up_vector parsed the name)
        a = np.zeros(3)
        a[(i + 1) % 3] = 1.0
    else:
        a = np.eye(3)[int(np.argmin(np.abs(u)))]
        a = a - (a @ u) * u
        a = a / np.linalg.norm(a)
    return np.stack([a, np.cross(u, a), u])


def direction(
    elev_deg: float, azim_deg: float, up: str | Sequence[float] | np.ndarray = "z"
) -> np.ndarray:
    """Unit vector from the target towards a camera at ``(elevation, azimuth)`` degrees about ``up``."""
    e, a = np.radians(elev_deg), np.radians(azim_deg)
    frame = ground_frame(up)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)]) @ frame


def _check_size(size) -> tuple[int, int]:
    try:
        width, height = (int(s) for s in size)
    except (TypeError, ValueError) as err:
        raise InputError(f"size must be (width, height) in pixels, got {size!r}") from err
    if width < 1 or height < 1:
        raise InputError(f"zero-size image: size must be at least 1 pixel each way, got {size!r}")
    if not (16 <= width <= 8192 and 16 <= height <= 8192):
        raise InputError(f"size must be between 16 and 8192 pixels each way, got {size!r}")
    return width, height


def _point(x, name: str) -> np.ndarray:
    p = np.asarray(x, dtype=np.float64) if np.ndim(x) == 1 else np.full(0, np.nan)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise InputError(f"{name} must be a finite 3-vector, got {x!r}")
    return p


def look_at(
    eye: Sequence[float] | np.ndarray,
    target: Sequence[float] | np.ndarray,
    *,
    up: str | Sequence[float] | np.ndarray = "z",
    fov_deg: float | None = None,
    half_height: float | None = None,
    size: tuple[int, int] = (512, 512),
) -> Camera:
    """A camera at ``eye`` looking at ``target``, ``up`` pointing up in the image.

    Args:
      eye: ``[3]`` camera position (world frame).
      target: ``[3]`` point on the image centre.
      up: world up axis, ``"x"|"y"|"z"|"-x"|"-y"|"-z"`` or a 3-vector (need not be orthogonal to the
        viewing direction, only not parallel to it).
      fov_deg: vertical field of view in degrees (perspective, ``0 < fov_deg < 180``); None:
        orthographic.
      half_height: orthographic half height of the view in world units; default
        ``|eye - target| · tan(15°)`` (what a 30° perspective camera sees at the target). For
        perspective cameras it is derived from ``fov_deg`` and must not be given.
      size: ``(width, height)`` in pixels.

    Returns:
      A :class:`Camera`.

    Raises:
      InputError: non-finite points, ``eye == target``, ``up`` parallel to the viewing direction,
        a bad field of view, half height or size.

    Example:
      >>> cam = look_at((3.0, 0.0, 0.0), (0.0, 0.0, 0.0), fov_deg=40.0)
      >>> [float(round(x, 3)) for x in cam.frame()[0]]  # right axis: +y seen from +x with z up
      [0.0, 1.0, 0.0]
    """
    eye_, target_ = _point(eye, "eye"), _point(target, "target")
    u = up_vector(up)
    dist = float(np.linalg.norm(target_ - eye_))
    # relative to the positions' magnitude, so a camera framing a mesh of any scale is accepted
    if dist <= 1e-12 * max(float(np.abs(eye_).max()), float(np.abs(target_).max())) or dist == 0:
        raise InputError(
            f"eye and target coincide at {eye_.tolist()}: the camera has no viewing direction"
        )
    w = (target_ - eye_) / dist
    if np.linalg.norm(np.cross(w, u)) < 1e-9:
        raise InputError(
            f"up {u.tolist()} is parallel to the viewing direction {w.tolist()}: pick another up"
        )
    width, height = _check_size(size)
    if fov_deg is not None:
        fov = float(fov_deg)
        if not (np.isfinite(fov) and 0.0 < fov < 180.0):
            raise InputError(
                f"fov_deg must be in (0, 180) degrees or None (orthographic), got {fov_deg!r}"
            )
        if half_height is not None:
            raise InputError(
                "half_height is for orthographic cameras; a perspective camera's view is set by fov_deg"
            )
        hh = dist * np.tan(np.radians(fov) / 2.0)
    else:
        fov = None
        hh = dist * np.tan(np.radians(15.0)) if half_height is None else float(half_height)
        if not (np.isfinite(hh) and hh > 0.0):
            raise InputError(
                f"half_height must be a positive number of world units, got {half_height!r}"
            )
    return Camera(
        eye=eye_, target=target_, up=u, fov_deg=fov, half_height=float(hh), size=(width, height)
    )


def bounding_sphere(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre (of the bounding box) and radius (farthest vertex from it) of ``[V, 3]`` points."""
    center = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    radius = float(np.linalg.norm(vertices - center, axis=1).max())
    return center, (radius if radius > 0.0 else 1.0)


#: fraction of the shorter image side the bounding sphere's diameter spans in framed views
FILL = 0.92


def view_camera(
    vertices: np.ndarray,
    elev_deg: float,
    azim_deg: float,
    *,
    up: str | Sequence[float] | np.ndarray = "z",
    size: tuple[int, int] = (512, 512),
    fov_deg: float | None = None,
) -> Camera:
    """A camera at ``(elevation, azimuth)`` about ``up``, framed on the points' bounding sphere.

    The sphere's silhouette spans :data:`FILL` (92 %) of the shorter image side, whatever the
    view direction, so every view of a rig has the same scale.
    """
    center, radius = bounding_sphere(vertices)
    width, height = _check_size(size)
    aspect = min(1.0, width / height)  # the sphere must also fit sideways in a portrait image
    d = direction(elev_deg, azim_deg, up)
    # image up: the direction of increasing elevation (the world up projected into the image, and
    # well defined looking straight down or up the up axis)
    e, a = np.radians(elev_deg), np.radians(azim_deg)
    up_ = np.array([-np.sin(e) * np.cos(a), -np.sin(e) * np.sin(a), np.cos(e)]) @ ground_frame(up)
    if fov_deg is None:
        dist = 3.0 * radius
        hh = radius / (FILL * aspect)
        return look_at(center + dist * d, center, up=up_, half_height=hh, size=size)
    # perspective: the silhouette of a sphere at distance D spans the half angle asin(r / D)
    half = np.arctan(FILL * aspect * np.tan(np.radians(float(fov_deg)) / 2.0))
    dist = radius / np.sin(half)
    return look_at(center + dist * d, center, up=up_, fov_deg=fov_deg, size=size)


def orbit_cameras(
    mesh,
    *,
    azimuths: int | Sequence[float] = 8,
    elevations: Sequence[float] = (20.0, -10.0),
    up: str | Sequence[float] | np.ndarray = "z",
    size: tuple[int, int] = (512, 512),
    fov_deg: float | None = None,
) -> list[Camera]:
    """The standard rig: cameras on a sphere around the mesh, framed on its bounding sphere.

    Every method's renders and evaluations use this rig, so views are comparable. Camera
    ``(i, j)`` sits at elevation ``elevations[i]`` and azimuth ``azimuths[j]`` (degrees, about
    ``up``; azimuth 0 looks from +x for ``up="z"``, from +z for ``up="y"``), at the same distance, so
    the bounding sphere spans 92 % of the shorter image side.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])``.
      azimuths: a count ``N`` (evenly spaced ``0, 360/N, ...``) or a list of azimuths in degrees.
      elevations: elevations in degrees (positive: above the target).
      up: world up axis, ``"x"|"y"|"z"|"-x"|"-y"|"-z"`` or a 3-vector (``"y"`` for most OBJ files).
      size: ``(width, height)`` per view.
      fov_deg: None (orthographic) or a vertical field of view for perspective cameras.

    Returns:
      ``len(elevations) · len(azimuths)`` cameras, elevation-major.

    Raises:
      InputError: an empty rig, non-finite vertices or angles, a bad ``up`` or size.

    Example:
      >>> from jmeshtex.data import icosphere
      >>> cams = orbit_cameras(icosphere(1), azimuths=4, size=(64, 64))
      >>> len(cams), [round(float(c.eye[2]), 3) for c in cams[:1]]
      (8, [1.026])
    """
    v = np.asarray(as_mesh(mesh).vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise InputError(f"vertices must be [V, 3] with V >= 1, got shape {v.shape}")
    if not np.isfinite(v).all():
        raise InputError("vertices hold NaN or infinite values: cannot frame the camera rig")
    if np.ndim(azimuths) == 0:
        if not is_int(azimuths, 1):
            raise InputError(
                f"azimuths must be an integer >= 1 (a count) or a list of degrees, got {azimuths!r}"
            )
        az = [360.0 * k / int(azimuths) for k in range(int(azimuths))]
    else:
        az = [float(a) for a in azimuths]
    el = [float(e) for e in elevations]
    if not az or not el:
        raise InputError("orbit_cameras needs at least one azimuth and one elevation")
    if not np.isfinite(az + el).all():
        raise InputError(f"azimuths and elevations must be finite, got {az} and {el}")
    return [view_camera(v, e, a, up=up, size=size, fov_deg=fov_deg) for e in el for a in az]

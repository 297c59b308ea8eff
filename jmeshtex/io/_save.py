"""Write meshes (OBJ/PLY/OFF/GLB) and PNG images atomically.

Every file is encoded in memory first, written to a temporary file in the destination folder and
moved over the destination with :func:`os.replace`, so an interrupted or failed save never leaves a
partial file and never clobbers the previous one.

What each format keeps (``Mesh`` fields):

=======  ========================  ==  =========================  ===========================
format   positions                 UV  texture                    vertex colours
=======  ========================  ==  =========================  ===========================
.obj     float64, exact            yes ``<stem>.png``             RGB, 8 bit
.ply     float64, exact            yes ``<stem>_texture.png``     RGB(A), 8 bit
.off     float64, exact            no  no                         no
.glb     float32 (glTF has no      yes embedded PNG               RGB(A), 8 bit, only without
         double positions)                                        UVs
=======  ========================  ==  =========================  ===========================

A field the format cannot hold is dropped with a ``UserWarning`` that names the format to use
instead. Textures are 8-bit PNGs (values rounded to multiples of 1/255). A textured OBJ writes
``<stem>.obj``, ``<stem>.mtl`` and ``<stem>.png``, a textured PLY ``<stem>.ply`` and
``<stem>_texture.png``: named after the mesh file, so several meshes (and an OBJ and a PLY of the
same stem) can share a folder. OBJ writes positions (``v``) and UVs (``vt``) separately; PLY and
GLB write one vertex per (vertex, UV) pair (split along seams), sorted by vertex. Either way
:func:`~jmeshtex.io.load_mesh` merges them back to the same vertex order. Unreferenced vertices survive
only where no UV split is written (OFF, and PLY/GLB without UVs; trimesh drops them from OBJ
files): run :func:`~jmeshtex.geometry.prepare_mesh` first to remove them.
"""

from __future__ import annotations

import io
import os
import pathlib
import warnings
from typing import Any

import numpy as np

from .._errors import EmptyMeshError, InputError, MeshIOError, NonFiniteVertexError
from .._mesh import Mesh
from .._mesh_arrays import check_indices, coerce_faces, coerce_vertices
from .._types import ArrayLike, Float
from ._atomic import atomic_write

MESH_SUFFIXES = (".obj", ".ply", ".off", ".glb")


# ----------------------------------------------------------------------------------------------
# atomic writes
# ----------------------------------------------------------------------------------------------


def _atomic_write(path: str | os.PathLike, data: bytes) -> None:
    """Mesh files and their textures go into an existing folder only (see :func:`atomic_write`)."""
    atomic_write(path, data, parents=False)


# ----------------------------------------------------------------------------------------------
# images
# ----------------------------------------------------------------------------------------------


def _image_to_uint8(image: Any, what: str = "image") -> np.ndarray:
    img = np.asarray(image)
    if img.ndim == 2:
        img = img[:, :, None]
    if img.ndim != 3 or img.shape[2] not in (1, 2, 3, 4) or img.shape[0] == 0 or img.shape[1] == 0:
        raise InputError(
            f"{what} must have shape [H, W] or [H, W, C] with C in 1..4, got {img.shape}"
        )
    if img.dtype == np.uint8:
        return img
    if img.dtype == bool or not (
        np.issubdtype(img.dtype, np.floating) or np.issubdtype(img.dtype, np.integer)
    ):
        raise InputError(f"{what} must be uint8 or real numbers in [0, 1], got dtype {img.dtype}")
    img = img.astype(np.float64)
    if not np.isfinite(img).all():
        raise InputError(f"{what} has NaN or infinite values. Fix: np.nan_to_num(image) first")
    return np.round(np.clip(img, 0.0, 1.0) * 255.0).astype(np.uint8)


def _png_bytes(pixels: np.ndarray) -> bytes:
    from PIL import Image

    data = pixels[:, :, 0] if pixels.shape[2] == 1 else pixels  # L, LA, RGB or RGBA
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(data)).save(buf, format="PNG")
    return buf.getvalue()


def save_png(
    image: Float[ArrayLike, "H W C"], path: str | os.PathLike, *, parents: bool = False
) -> None:
    """Write an image as an 8-bit PNG, atomically.

    Row 0 is the top of the image (for textures: v = 1). Floats are clipped to [0, 1] and rounded to
    multiples of 1/255; ``uint8`` is written as is. C = 1 (grey), 2 (grey + alpha), 3 (RGB) or
    4 (RGBA). The PNG is encoded in memory, written to a temporary file in the destination folder
    and moved over ``path``, so a reader never sees a half-written file.

    Args:
      image: ``[H, W]`` or ``[H, W, C]`` floats in [0, 1], or ``uint8``.
      path: destination ``.png``.
      parents: create missing parent folders (default: the folder must exist).

    Raises:
      InputError: wrong shape or dtype, NaN/inf values, a suffix other than ``.png``.
      MeshIOError: the file cannot be written (the previous file, if any, is left intact).

    Example:
      >>> import numpy as np, pathlib, tempfile
      >>> from jmeshtex.io import load_texture
      >>> path = pathlib.Path(tempfile.mkdtemp()) / "ramp.png"
      >>> save_png(np.linspace(0, 1, 12).reshape(2, 2, 3), path)
      >>> load_texture(path).shape
      (2, 2, 3)
    """
    pixels = _image_to_uint8(image)
    path = pathlib.Path(path)
    if path.suffix.lower() != ".png":
        raise InputError(f"save_png writes PNG files; {path} does not end in .png")
    atomic_write(path, _png_bytes(pixels), parents=parents)


# ----------------------------------------------------------------------------------------------
# meshes
# ----------------------------------------------------------------------------------------------


def _checked_mesh(mesh: Mesh | tuple) -> Mesh:
    if not isinstance(mesh, Mesh):
        try:
            vertices, faces = mesh
        except (TypeError, ValueError):
            raise InputError(
                f"save_mesh expects a jmeshtex.Mesh or a (vertices, faces) pair, got {type(mesh).__name__}"
            ) from None
        mesh = Mesh(vertices, faces)
    v = coerce_vertices(mesh.vertices)
    f = coerce_faces(mesh.faces)
    check_indices(f, len(v))
    bad = np.nonzero(~np.isfinite(v).all(axis=1))[0]
    if bad.size:
        raise NonFiniteVertexError(indices=bad)
    if len(f) == 0:
        raise EmptyMeshError("nothing to save: the mesh has no faces")
    uv = colors = None
    if mesh.uv is not None:
        uv = np.asarray(mesh.uv, dtype=np.float64)
        if uv.shape != (len(f), 3, 2):
            raise InputError(
                f"Mesh.uv must have shape [F, 3, 2] = {(len(f), 3, 2)}, got {uv.shape}"
            )
        if not np.isfinite(uv).all():
            raise InputError("Mesh.uv has NaN or infinite values")
    if mesh.vertex_colors is not None:
        colors = np.asarray(mesh.vertex_colors, dtype=np.float64)
        if colors.ndim != 2 or colors.shape[0] != len(v) or colors.shape[1] not in (3, 4):
            raise InputError(
                f"Mesh.vertex_colors must have shape [V, 3] or [V, 4] with V={len(v)}, got {colors.shape}"
            )
    return mesh.replace(vertices=v, faces=f, uv=uv, vertex_colors=colors)


def _colors_uint8(colors: np.ndarray) -> np.ndarray:
    if not np.isfinite(colors).all():
        raise InputError("Mesh.vertex_colors has NaN or infinite values")
    return np.round(np.clip(colors, 0.0, 1.0) * 255.0).astype(np.uint8)


def _split_by_uv(faces: np.ndarray, uv: np.ndarray | None):
    """Stored vertices = distinct (vertex, uv) pairs, sorted by vertex then (u, v).

    Returns ``(stored_faces [F, 3], stored_to_vertex [S], stored_uv [S, 2] or None)``.
    """
    if uv is None:
        return faces, np.arange(faces.max() + 1), None
    m = faces.ravel()
    u = uv.reshape(-1, 2) + 0.0
    order = np.lexsort((u[:, 1], u[:, 0], m))
    new = np.ones(len(m), bool)
    new[1:] = (m[order][1:] != m[order][:-1]) | np.any(u[order][1:] != u[order][:-1], axis=1)
    ids = np.empty(len(m), np.int64)
    ids[order] = np.cumsum(new) - 1
    first = order[new]
    return ids.reshape(faces.shape), m[first], u[first]


def _unique_rows(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct rows (exact, ``-0.0 == 0.0``) in lexicographic order and the inverse map.

    A lexsort over the columns: ``np.unique(axis=0)`` sorts a void view and is ~15x slower.
    """
    x = x + 0.0
    order = np.lexsort(x.T[::-1])
    xs = x[order]
    new = np.ones(len(x), bool)
    new[1:] = np.any(xs[1:] != xs[:-1], axis=1)
    inverse = np.empty(len(x), np.int64)
    inverse[order] = np.cumsum(new) - 1
    return xs[new], inverse


def _format_rows(prefix: str, values: np.ndarray, fmt: str = "{!r}") -> str:
    """``prefix a b c\\n`` for each row, in one ``str.format`` call (no per-row Python loop)."""
    if values.size == 0:
        return ""
    row = (f"{prefix} " if prefix else "") + " ".join([fmt] * values.shape[1]) + "\n"
    return (row * values.shape[0]).format(*values.ravel().tolist())


def _encode_obj(mesh: Mesh, stem: str) -> dict[str, bytes]:
    files: dict[str, bytes] = {}
    head = ["# written by jmeshtex\n"]
    if mesh.texture is not None and mesh.uv is not None:
        files[f"{stem}.png"] = _png_bytes(_image_to_uint8(mesh.texture, "Mesh.texture"))
        files[f"{stem}.mtl"] = (
            f"# written by jmeshtex\nnewmtl {stem}\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nd 1\nillum 1\n"
            f"map_Kd {stem}.png\n"
        ).encode()
        head.append(f"mtllib {stem}.mtl\n")
    v = mesh.vertices
    if mesh.vertex_colors is not None:
        if mesh.vertex_colors.shape[1] == 4 and np.any(mesh.vertex_colors[:, 3] < 1):
            warnings.warn(
                "OBJ stores RGB vertex colours only: alpha is dropped (save as .ply or .glb to keep it)",
                UserWarning,
                stacklevel=3,
            )
        rgb = _colors_uint8(mesh.vertex_colors)[:, :3] / 255.0
        body = [_format_rows("v", np.concatenate([v, rgb], axis=1))]
    else:
        body = [_format_rows("v", v)]
    f = mesh.faces + 1
    if mesh.uv is not None:
        uv_values, uv_index = _unique_rows(mesh.uv.reshape(-1, 2))
        body.append(_format_rows("vt", uv_values))
        if len(head) > 1:
            body.append(f"usemtl {stem}\n")
        pairs = np.stack([f.ravel(), uv_index.reshape(-1) + 1], axis=1).reshape(-1, 6)
        body.append(("f {}/{} {}/{} {}/{}\n" * len(pairs)).format(*pairs.ravel().tolist()))
    else:
        body.append(_format_rows("f", f, "{}"))
    files[f"{stem}.obj"] = "".join(head + body).encode()
    return files


def _encode_ply(mesh: Mesh, stem: str) -> dict[str, bytes]:
    files: dict[str, bytes] = {}
    stored_faces, to_vertex, stored_uv = _split_by_uv(mesh.faces, mesh.uv)
    if mesh.uv is None:  # keep every vertex, referenced or not
        to_vertex = np.arange(len(mesh.vertices))
    fields = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
    columns = [mesh.vertices[to_vertex, k] for k in range(3)]
    header = ["ply", "format binary_little_endian 1.0", "comment written by jmeshtex"]
    if mesh.texture is not None and mesh.uv is not None:
        files[f"{stem}_texture.png"] = _png_bytes(_image_to_uint8(mesh.texture, "Mesh.texture"))
        header.append(f"comment TextureFile {stem}_texture.png")
    if stored_uv is not None:
        fields += [("texture_u", "<f8"), ("texture_v", "<f8")]
        columns += [stored_uv[:, 0], stored_uv[:, 1]]
    if mesh.vertex_colors is not None:
        rgba = _colors_uint8(mesh.vertex_colors)[to_vertex]
        names = ["red", "green", "blue", "alpha"][: rgba.shape[1]]
        fields += [(n, "u1") for n in names]
        columns += [rgba[:, k] for k in range(rgba.shape[1])]
    header.append(f"element vertex {len(to_vertex)}")
    header += [f"property {'double' if t == '<f8' else 'uchar'} {n}" for n, t in fields]
    header += [
        f"element face {len(stored_faces)}",
        "property list uchar int vertex_indices",
        "end_header",
    ]
    vert = np.empty(len(to_vertex), dtype=fields)
    for (name, _), col in zip(fields, columns, strict=True):
        vert[name] = col
    face = np.empty(len(stored_faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    face["n"] = 3
    face["i"] = stored_faces
    files[f"{stem}.ply"] = ("\n".join(header) + "\n").encode() + vert.tobytes() + face.tobytes()
    return files


def _encode_off(mesh: Mesh, stem: str) -> dict[str, bytes]:
    v, f = mesh.vertices, mesh.faces
    text = (
        f"OFF\n# written by jmeshtex\n{len(v)} {len(f)} 0\n"
        + _format_rows("", v)
        + _format_rows("3", f, "{}")
    )
    return {f"{stem}.off": text.encode()}


def _encode_glb(mesh: Mesh, stem: str) -> dict[str, bytes]:
    import trimesh
    from PIL import Image

    stored_faces, to_vertex, stored_uv = _split_by_uv(mesh.faces, mesh.uv)
    if mesh.uv is None:
        to_vertex = np.arange(len(mesh.vertices))
    if stored_uv is not None:
        image = None
        if mesh.texture is not None:
            pixels = _image_to_uint8(mesh.texture, "Mesh.texture")
            image = Image.fromarray(pixels[:, :, 0] if pixels.shape[2] == 1 else pixels)
        if mesh.vertex_colors is not None:
            warnings.warn(
                "GLB (through trimesh) stores either UVs or vertex colours: the colours are dropped (save as .ply to keep both)",
                UserWarning,
                stacklevel=3,
            )
        if image is None:  # an explicit empty material, or trimesh would embed a grey placeholder
            visual = trimesh.visual.TextureVisuals(
                uv=stored_uv, material=trimesh.visual.material.PBRMaterial()
            )
        else:
            visual = trimesh.visual.TextureVisuals(uv=stored_uv, image=image)
    elif mesh.vertex_colors is not None:
        visual = trimesh.visual.ColorVisuals(
            vertex_colors=_colors_uint8(mesh.vertex_colors)[to_vertex]
        )
    else:
        visual = None
    tm = trimesh.Trimesh(
        mesh.vertices[to_vertex], stored_faces, visual=visual, process=False, validate=False
    )
    with warnings.catch_warnings():
        warnings.simplefilter(
            "ignore"
        )  # trimesh's own deprecation noise is not the caller's concern
        data = tm.export(file_type="glb")
    return {f"{stem}.glb": data}


def mesh_suffix(path: pathlib.Path, action: str, *, fix: str) -> str:
    """``path``'s suffix, lower case, or :class:`~jmeshtex.MeshIOError` unless it names a mesh
    format jmeshtex reads and writes (:data:`MESH_SUFFIXES`); the message says ``action`` failed
    and ends with ``fix``."""
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise MeshIOError(
            f"cannot {action} {path}: unsupported mesh format {suffix or '(no suffix)'!r}; "
            f"supported: {', '.join(MESH_SUFFIXES)}. Fix: {fix}"
        )
    return suffix


_ENCODERS = {".obj": _encode_obj, ".ply": _encode_ply, ".off": _encode_off, ".glb": _encode_glb}


def save_mesh(mesh: Mesh | tuple, path: str | os.PathLike) -> None:
    """Write a mesh as OBJ, PLY, OFF or GLB (chosen by the suffix), atomically.

    UVs, the texture and vertex colours are written where the format holds them (see the module
    table); a textured OBJ also writes ``<stem>.mtl`` and ``<stem>.png`` next to it (a PLY
    ``<stem>_texture.png``), each atomically, the mesh file last. Positions are exact (shortest round-trip
    decimal / float64) except in GLB (float32). Invalid-but-indexable meshes (non-manifold, ...)
    can be written; only broken arrays are refused.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` or ``(vertices [V, 3], faces [F, 3])``.
      path: destination ``.obj`` / ``.ply`` / ``.off`` / ``.glb``; its folder must exist.

    Raises:
      MeshIOError: unsupported suffix, missing folder, or the write failed (the previous files
        are left intact).
      InputError, FaceIndexError, NonFiniteVertexError, EmptyMeshError: broken arrays.

    Example:
      >>> import pathlib, tempfile
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import icosahedron
      >>> from jmeshtex.io import load_mesh
      >>> path = pathlib.Path(tempfile.mkdtemp()) / "ico.off"
      >>> save_mesh(Mesh(*icosahedron()), path)
      >>> m = load_mesh(path)
      >>> m.num_vertices, m.num_faces, bool((m.vertices == icosahedron().vertices).all())
      (12, 20, True)
    """
    path = pathlib.Path(path)
    suffix = mesh_suffix(path, "save", fix="give the file one of those suffixes")
    mesh = _checked_mesh(mesh)
    if suffix == ".off" and (
        mesh.uv is not None or mesh.texture is not None or mesh.vertex_colors is not None
    ):
        warnings.warn(
            "OFF stores geometry only: UVs, texture and vertex colours are dropped (save as .obj, .ply or .glb to keep them)",
            UserWarning,
            stacklevel=2,
        )
    elif mesh.texture is not None and mesh.uv is None:
        warnings.warn(
            "the mesh has a texture but no UVs: the texture is not written",
            UserWarning,
            stacklevel=2,
        )
    files = _ENCODERS[suffix](mesh, path.stem)
    main = path.name
    for name, data in files.items():  # dependencies (texture, material) first, the mesh file last
        if not name.endswith(suffix):
            _atomic_write(path.with_name(name), data)
    _atomic_write(path.with_name(main), files[f"{path.stem}{suffix}"])
